"""Regenerate the docs' figures (docs/NAME.png) and sample outputs (the code blocks marked
``<!-- output: NAME -->``), each by the command its page quotes, so that they cannot go stale.

Each is made in a temporary folder of its own (a run that a figure and an output both show is
flown once); the PNG is copied over ``docs/NAME.png`` and the text written into its blocks,
then docs/index.md is made again from the README.  One line per figure or output says whether
it was made (and in how many seconds) or skipped, and why (a firmware build or the real
blackbox logs missing, a 45-minute training run, the real Configurator's web build).  One
whose command fails leaves its file as it was.  Ctrl-C (or SIGTERM) stops the command that is
running, lets it stop its SITLs, and removes the temporary folders.

Run: ``python tools/regenerate_docs.py [--only NAME ...] [--firmware-46 NAME]
[--firmware-master NAME] [--real-logs DIR] [--hover-run DIR] [--recover-run DIR]
[--waypoints-run DIR] [--out DIR] [--list] [--check]``.
The firmware names are cached builds (``bfsitl firmware list``; ``BFSITL_CACHE_DIR`` says
which cache) or SITL binaries; the stock 4.6.0 is the one ``bfsitl fly`` finds by default.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Protocol

from docs_figures import FIGURES
from docs_outputs import OUTPUTS, marker_problems, readme_as_home_page, write_whole
from docs_running import (
    FIRMWARE_46,
    FIRMWARE_MASTER,
    REAL_LOGS,
    REPO,
    Context,
    MakeFailed,
    Need,
    report,
    stop_signals_as_ctrl_c,
)


class Made(Protocol):
    """A figure or an output."""

    @property
    def name(self) -> str: ...
    @property
    def how(self) -> str: ...
    @property
    def needs(self) -> tuple[Need, ...]: ...
    def regenerate(self, ctx: Context, work: Path, out: Path) -> str: ...


ALL: tuple[Made, ...] = (*FIGURES, *OUTPUTS)


def why_skipped(item: Made, ctx: Context) -> str | None:
    for need in item.needs:
        reason = need.unmet(ctx)
        if reason is not None:
            return reason
    return None


def make_one(item: Made, ctx: Context, out: Path) -> str:
    """Make ``item`` in a temporary folder and install it under ``out``; what changed."""
    with tempfile.TemporaryDirectory(
        prefix=f"docs-{item.name}-", ignore_cleanup_errors=True
    ) as folder:
        return item.regenerate(ctx, Path(folder), out)


def make_all(items: Sequence[Made], ctx: Context, out: Path) -> int:
    """Make each item that can be made, then docs/index.md from the README; 1 when one
    failed, 0 otherwise."""
    failed = False
    for item in items:
        reason = why_skipped(item, ctx)
        if reason is not None:
            report("skipped", item.name, reason)
            continue
        started = time.monotonic()
        try:
            change = make_one(item, ctx, out)
        except MakeFailed as exc:
            failed = True
            seconds = time.monotonic() - started
            report("FAILED", item.name, f"{exc}; left as it was", seconds)
            continue
        report("made", item.name, change, time.monotonic() - started)
    readme = out / "README.md"
    if readme.exists():
        home = out / "docs" / "index.md"
        home.parent.mkdir(parents=True, exist_ok=True)
        write_whole(home, readme_as_home_page(readme.read_text()))
    return 1 if failed else 0


def list_items(items: Sequence[Made], ctx: Context) -> None:
    for item in items:
        reason = why_skipped(item, ctx)
        kind = "figure" if item in FIGURES else "output"
        print(f"{item.name} ({kind})\n    made by: {item.how}")
        print(f"    needs:   {', '.join(n.label for n in item.needs) or 'nothing'}")
        print(f"    here:    {'would be made' if reason is None else 'skipped: ' + reason}")


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    names = [item.name for item in ALL]
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="NAME", help=f"of: {', '.join(names)}")
    parser.add_argument(
        "--firmware-46",
        default=FIRMWARE_46,
        metavar="NAME",
        help="the 4.6.0 lockstep build with GPS (default %(default)s)",
    )
    parser.add_argument(
        "--firmware-master",
        default=FIRMWARE_MASTER,
        metavar="NAME",
        help="the master lockstep build (default %(default)s)",
    )
    parser.add_argument(
        "--real-logs",
        type=Path,
        default=REAL_LOGS,
        metavar="DIR",
        help="the real blackbox logs (default: shared/blackbox/real beside the repository)",
    )
    parser.add_argument(
        "--hover-run",
        type=Path,
        metavar="DIR",
        help="the folder of a training run of examples/train_hover.py (the gym figures)",
    )
    parser.add_argument(
        "--recover-run",
        type=Path,
        metavar="DIR",
        help="the folder of a training run of examples/train_recover.py (its curve)",
    )
    parser.add_argument(
        "--waypoints-run",
        type=Path,
        metavar="DIR",
        help="the folder of a training run of examples/train_waypoints.py (its curve)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=REPO,
        metavar="DIR",
        help="where docs/NAME.png and the pages go (default: the repository; elsewhere, the "
        "pages a made output is in are copied there first)",
    )
    parser.add_argument("--list", action="store_true", help="list what can be made and stop")
    parser.add_argument(
        "--check",
        action="store_true",
        help="check that every marked block names an output and every output has a block",
    )
    args = parser.parse_args(argv)
    only = [name.removesuffix(".png") for name in args.only or []]
    unknown = sorted(set(only) - set(names))
    if unknown:
        parser.error(f"nothing called {', '.join(unknown)}; of: {', '.join(names)}")
    args.items = [item for item in ALL if not only or item.name in only]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    if args.check:
        problems = marker_problems()
        for problem in problems:
            print(f"regenerate_docs: {problem}")
        return 1 if problems else 0
    with contextlib.ExitStack() as stack:
        ctx = Context(
            args.firmware_46,
            args.firmware_master,
            args.real_logs,
            args.hover_run,
            stack,
            recover_run=args.recover_run,
            waypoints_run=args.waypoints_run,
        )
        if args.list:
            list_items(args.items, ctx)
            return 0
        args.out.mkdir(parents=True, exist_ok=True)
        with stop_signals_as_ctrl_c():
            try:
                return make_all(args.items, ctx, args.out.resolve())
            except KeyboardInterrupt:
                print("regenerate_docs: stopped; what was being made was left as it was")
                return 130


if __name__ == "__main__":
    sys.exit(main())
