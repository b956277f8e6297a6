"""The sample outputs the docs' pages show, each made by running the command the page quotes,
so that they cannot go stale.

A page marks a code block as a made output with an HTML comment on the line before its fence::

    <!-- output: NAME -->
    ```
    ...what the command printed...
    ```

tools/regenerate_docs.py runs NAME's command and puts what it printed (cut to what the page
shows: a command's table, its verdict lines) between the fences; the rest of the page is left
alone.  Paths of the machine that made it are written relative to the folder the command ran
in.  A block without a marker is written by hand (a synopsis, a file's layout, a sketch)."""

from __future__ import annotations

import os
import re
import shlex
import shutil
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from docs_running import (
    FIT_ARGS,
    LOCKSTEP_46,
    LOCKSTEP_MASTER,
    REPO,
    ROMA_LOG,
    STOCK,
    Context,
    MakeFailed,
    Need,
    benchmark,
    bfsitl,
    compare_argv,
    compare_run,
    demo_run,
    excite_fit_run,
    real_log,
    roma_replay_run,
    run,
    square_run,
)

#: ``<!-- output: NAME -->``: the next line opens the block NAME fills.
MARKER = re.compile(r"^<!-- output: ([a-z0-9-]+) -->$")
FENCE = "```"
#: The pages that may hold made outputs (README.md and docs/*.md, but docs/index.md, which is
#: the README made again).
PAGES = ("README.md", "docs/*.md")
ELIDED = "..."


@dataclass(frozen=True)
class Output:
    """A code block (or several: the same output on two pages) the command ``how`` fills."""

    name: str
    how: str
    needs: tuple[Need, ...]
    make: Callable[[Context, Path], str]

    def regenerate(self, ctx: Context, work: Path, out: Path) -> str:
        """Make the text in ``work`` and write it into every block marked with this output's
        name in the pages under ``out`` (copied there from the repository first when ``out`` is
        elsewhere); which pages changed."""
        text = self.make(ctx, work).rstrip("\n")
        changes = []
        for page in pages_with(self.name):
            target = out / page
            if not target.exists():
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(REPO / page, target)
            before = target.read_text()
            after = fill(before, self.name, text)
            if after != before:
                write_whole(target, after)
            changes.append(f"{page} ({'changed' if after != before else 'unchanged'})")
        if not changes:
            raise MakeFailed(f"no page has a block marked <!-- output: {self.name} -->")
        return ", ".join(changes)


# -- the pages' blocks -----------------------------------------------------------------------


def page_paths() -> list[str]:
    """Every page that may hold a made output, relative to the repository."""
    found = {p.relative_to(REPO).as_posix() for pattern in PAGES for p in REPO.glob(pattern)}
    found.discard("docs/index.md")
    return sorted(found)


def markers(text: str) -> list[str]:
    """The output names marked in a page's text, in order."""
    return [m.group(1) for line in text.splitlines() if (m := MARKER.match(line))]


def pages_with(name: str) -> list[str]:
    return [page for page in page_paths() if name in markers((REPO / page).read_text())]


def block_span(lines: Sequence[str], name: str) -> list[tuple[int, int]]:
    """(first, end) line indexes of the content of each block marked ``name``; ValueError when
    a marker is not followed by a fenced block."""
    spans = []
    for index, line in enumerate(lines):
        match = MARKER.match(line)
        if not match or match.group(1) != name:
            continue
        if index + 1 >= len(lines) or not lines[index + 1].startswith(FENCE):
            raise ValueError(f"<!-- output: {name} --> is not followed by a ``` block")
        end = index + 2
        while end < len(lines) and lines[end].rstrip() != FENCE:
            end += 1
        if end >= len(lines):
            raise ValueError(f"the block marked <!-- output: {name} --> is not closed")
        spans.append((index + 2, end))
    return spans


def block_text(text: str, name: str) -> list[str]:
    """The content of each block marked ``name`` in a page's text."""
    lines = text.splitlines()
    return ["\n".join(lines[first:end]) for first, end in block_span(lines, name)]


def fill(text: str, name: str, content: str) -> str:
    """The page's text with every block marked ``name`` holding ``content``."""
    lines = text.splitlines()
    for first, end in reversed(block_span(lines, name)):
        lines[first:end] = content.splitlines()
    return "\n".join(lines) + ("\n" if text.endswith("\n") else "")


def write_whole(target: Path, text: str) -> None:
    """Replace ``target`` whole (a stop half-way leaves the old page)."""
    partial = target.with_name(f".{target.name}.partial")
    try:
        partial.write_text(text)
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


def readme_as_home_page(readme: str) -> str:
    """docs/index.md: the README with its links made relative to docs/."""
    return readme.replace("](docs/", "](").replace(
        "The docs site builds from `docs/` with `mkdocs build --strict` "
        "(`pip install -e '.[docs]'`):",
        "Pages of this site:",
    )


# -- cutting what a command printed ----------------------------------------------------------


def shown(argv: Sequence[str], width: int = 96) -> str:
    """A command as the page quotes it: ``$ bfsitl ...``, each argument quoted as a shell
    would need it, continued with ``\\`` on the next line where it would pass ``width``."""
    words = list(argv)
    if words[:3] == [words[0], "-m", "bfsitl.cli.main"]:
        words = ["bfsitl", *words[3:]]
    elif len(words) > 1 and words[1].startswith(str(REPO)):
        words = ["python", os.path.relpath(words[1], REPO), *words[2:]]
    lines = ["$"]
    for word in map(shlex.quote, words):
        # A line holds at least one word besides the prompt or the continuation's indent.
        if len(lines[-1]) + 1 + len(word) > width - 2 and lines[-1].strip() not in ("$", ""):
            lines[-1] += " \\"
            lines.append("     ")
        lines[-1] += " " + word
    return "\n".join(lines)


def relative(text: str, *folders: Path) -> str:
    """``text`` with the paths of this machine's folders made relative (the repository's,
    and the folder the command ran in)."""
    for folder in (*folders, REPO):
        text = text.replace(f"{folder}/", "").replace(str(folder), ".")
    return text


def keep(text: str, *starts: str) -> str:
    """The lines of ``text`` that start with one of ``starts``."""
    return "\n".join(line for line in text.splitlines() if line.startswith(starts))


def elide(lines: Iterable[str], drop: Callable[[str], bool]) -> str:
    """``lines`` with each run of dropped lines written as one ``...``."""
    kept: list[str] = []
    for line in lines:
        if not drop(line):
            kept.append(line)
        elif not kept or kept[-1] != ELIDED:
            kept.append(ELIDED)
    return "\n".join(kept)


def from_line(text: str, start: str) -> list[str]:
    """The lines of ``text`` from the first that starts with ``start``."""
    lines = text.splitlines()
    for index, line in enumerate(lines):
        if line.startswith(start):
            return lines[index:]
    raise MakeFailed(f"no line starts with {start!r}")


def table(text: str, header: str, last: str) -> str:
    """The lines from the one that starts with ``header`` to the one that starts with
    ``last``."""
    lines = from_line(text, header)
    for index, line in enumerate(lines):
        if line.startswith(last):
            return "\n".join(lines[: index + 1])
    raise MakeFailed(f"no line starts with {last!r} after {header!r}")


#: The SITL's start-up as `bfsitl` narrates it: elided where a page shows a command's result.
_START_UP = re.compile(
    r"^bfsitl: (starting betaflight|SITL ready|lockstep:|switching the GPS|the configuration "
    r"needs a reboot|SITL exited with code 0 \(reboot\)|provisioned|waiting for the FC)"
)


def verdicts(printed: Sequence[str]) -> list[str]:
    """A compare's verdict lines and its tally, without its progress (``bfsitl: ...`` and
    each run's ``  ran ...``)."""
    return [line for line in printed if not line.startswith(("bfsitl: ", "  ran "))]


# -- the outputs -----------------------------------------------------------------------------


def make_demo(ctx: Context, work: Path) -> str:
    """How the flight ends: from arming (the SITL's start-up before it is elided)."""
    text = (demo_run(ctx) / "fly.log").read_text()
    return "\n".join([ELIDED, *from_line(text, "bfsitl: arming")])


def make_demo_end(ctx: Context, work: Path) -> str:
    text = (demo_run(ctx) / "fly.log").read_text()
    return keep(text, "bfsitl: outcome", "hold ", "RC link ", "bfsitl: wrote")


def make_square(ctx: Context, work: Path) -> str:
    return keep((square_run(ctx) / "fly.log").read_text(), "waypoint ", "cross-track", "landed ")


def make_log_check(ctx: Context, work: Path) -> str:
    argv = bfsitl("log", "check", str(REPO / "tests/data/blackbox/switch-landing-master.BFL"))
    return relative(shown(argv) + "\n" + run(argv, work, ok=(0, 1)), work)


def make_compare(ctx: Context, work: Path) -> str:
    printed = (compare_run(ctx) / "compare.log").read_text()
    return "\n".join([shown(compare_argv(ctx)), ELIDED, *verdicts(printed.splitlines())])


def make_roma_compare(ctx: Context, work: Path) -> str:
    (work / ROMA_LOG).symlink_to(ctx.real_logs / ROMA_LOG)
    scenario = work / "roma.toml"
    scenario.write_text(
        'description = "ROMA F5 freestyle flight (4.2.9), replayed"\n'
        f'[replay]\nlog = "{ROMA_LOG}"\n[expect]\nmin_setpoint_correlation = 0.99\n'
    )
    argv = bfsitl(
        *("scenario", "compare", "--firmware", ctx.firmware_46),
        *("--firmware", ctx.firmware_master, "roma.toml"),
    )
    printed = run(argv, work, ok=(0, 1)).splitlines()
    first, last = printed[0], printed[-1]
    return "\n".join(
        ["$ cat roma.toml", scenario.read_text().rstrip(), "", shown(argv), first, ELIDED]
        + verdicts(printed)
        + [last]
    )


def make_log_fit(ctx: Context, work: Path) -> str:
    printed = (excite_fit_run(ctx) / "fit.log").read_text()
    return shown(bfsitl(*FIT_ARGS)) + "\n" + printed


def make_log_replay(ctx: Context, work: Path) -> str:
    folder = roma_replay_run(ctx)
    argv = bfsitl(
        *("log", "replay", ROMA_LOG, "--vehicle", "5inch-freestyle"),
        *("--firmware", ctx.firmware_46),
    )
    printed = relative((folder / "replay.log").read_text(), folder).splitlines()
    return shown(argv) + "\n" + elide(printed, lambda line: bool(_START_UP.match(line)))


def make_log_replay_b(ctx: Context, work: Path) -> str:
    (work / ROMA_LOG).symlink_to(ctx.real_logs / ROMA_LOG)
    argv = bfsitl(
        *("log", "replay", ROMA_LOG, "--vehicle", "5inch-freestyle"),
        *("--firmware", ctx.firmware_46),
        *("--b-cli", "set f_roll = 0", "--b-cli", "set f_pitch = 0"),
    )
    printed = relative(run(argv, work, ok=(0, 1)), work)
    return "\n".join([shown(argv), ELIDED, *from_line(printed, "B (")])


def make_timings(ctx: Context, work: Path) -> str:
    argv = bfsitl(
        *("scenario", "run", "--timings", "--firmware", ctx.firmware_46, "--out", "runs"),
        *("rc-loss-hover-drop", "rescue-far", "motor-weak"),
    )
    printed = run(argv, work)
    return shown(argv) + "\n" + ELIDED + "\n" + table(printed, "run ", "share ")


def make_known_failure(ctx: Context, work: Path) -> str:
    """rescue-far on master (the defect happens), then the same scenario declaring the
    defect on every build, on 4.6.0 (where it does not happen)."""
    from bfsitl.library import scenarios_dir

    known = bfsitl("scenario", "run", "rescue-far", "--firmware", ctx.firmware_master)
    lines = [shown(known), keep(run(known, work), "KNOWN ", "PASS ", "FAIL ")]
    declared = (scenarios_dir() / "rescue-far.toml").read_text()
    everywhere = declared.replace('generation = "master"\n', "")
    everywhere = re.sub(r'\[expect\."4\.6"\]\nno_finding = \[[^]]*\]\n', "", everywhere)
    (work / "rescue-far-everywhere.toml").write_text(everywhere)
    fixed = bfsitl(
        *("scenario", "run", "rescue-far-everywhere.toml", "--firmware", ctx.firmware_46),
    )
    lines += [shown(fixed), keep(run(fixed, work, ok=(1,)), "KNOWN ", "PASS ", "FAIL ")]
    return "\n".join(lines)


def make_vehicle_list(ctx: Context, work: Path) -> str:
    return run(bfsitl("vehicle", "list"), work)


def make_vehicle_bad_file(ctx: Context, work: Path) -> str:
    profile = run(bfsitl("vehicle", "show", "5inch-freestyle"), work, log_name="show.log")
    bad = profile.replace("max_rpm =", "max_rmp =").replace("mass_g = 650.0", "mass_g = -650.0")
    (work / "my-quad.toml").write_text(bad)
    argv = bfsitl("fly", "--vehicle", "my-quad.toml")
    printed = run(argv, work, ok=(2,))  # argparse's usage first, then the error
    return "\n".join([shown(argv), ELIDED, *from_line(printed, "bfsitl fly: error")])


def make_vehicles_benchmark(ctx: Context, work: Path) -> str:
    printed = run(benchmark("vehicles.py"), work)
    return table(printed, "firmware ", "medians of")


OUTPUTS = (
    Output(
        "demo-output",
        "make demo: bfsitl fly --log flight.csv --plot flight.png --summary flight.json",
        (STOCK,),
        make_demo,
    ),
    Output(
        "demo-output-end",
        "the same flight: its outcome, hold, RC link and files",
        (STOCK,),
        make_demo_end,
    ),
    Output(
        "square-waypoints",
        "bfsitl fly --firmware MASTER --mission square --wind 3 ... (its waypoints)",
        (LOCKSTEP_MASTER,),
        make_square,
    ),
    Output(
        "log-check",
        "bfsitl log check tests/data/blackbox/switch-landing-master.BFL",
        (),
        make_log_check,
    ),
    Output(
        "compare-hover-throttle",
        "the compare figures' run: its verdicts",
        (LOCKSTEP_46,),
        make_compare,
    ),
    Output(
        "compare-roma",
        "bfsitl scenario compare --firmware 4.6 --firmware MASTER roma.toml (a [replay])",
        (real_log(ROMA_LOG), LOCKSTEP_46, LOCKSTEP_MASTER),
        make_roma_compare,
    ),
    Output(
        "log-fit-5inch",
        "bfsitl log fit LOG00001.BF --mass-g 650 (the log-fit-sitl figure's run)",
        (LOCKSTEP_46,),
        make_log_fit,
    ),
    Output(
        "log-replay-roma-output",
        "bfsitl log replay roma-f5-4.2.9.bbl --vehicle 5inch-freestyle --firmware 4.6",
        (real_log(ROMA_LOG), LOCKSTEP_46),
        make_log_replay,
    ),
    Output(
        "log-replay-b",
        "the same replay with --b-cli 'set f_roll = 0' --b-cli 'set f_pitch = 0'",
        (real_log(ROMA_LOG), LOCKSTEP_46),
        make_log_replay_b,
    ),
    Output(
        "scenario-timings",
        "bfsitl scenario run --timings rc-loss-hover-drop rescue-far motor-weak (4.6)",
        (LOCKSTEP_46,),
        make_timings,
    ),
    Output(
        "known-failure",
        "bfsitl scenario run rescue-far on MASTER, then declared on every build on 4.6",
        (LOCKSTEP_46, LOCKSTEP_MASTER),
        make_known_failure,
    ),
    Output("vehicle-list", "bfsitl vehicle list", (), make_vehicle_list),
    Output(
        "vehicle-bad-file",
        "bfsitl fly --vehicle my-quad.toml (a mistyped field and a negative mass)",
        (),
        make_vehicle_bad_file,
    ),
    Output(
        "vehicles-benchmark",
        "python benchmarks/vehicles.py (16 flights through both lockstep builds)",
        (LOCKSTEP_46, LOCKSTEP_MASTER),
        make_vehicles_benchmark,
    ),
)


def marker_problems() -> list[str]:
    """What is wrong between the pages' markers and the outputs: a marker no output fills, an
    output no page shows, a marker not followed by a block."""
    names = {output.name for output in OUTPUTS}
    problems = []
    marked: set[str] = set()
    for page in page_paths():
        text = (REPO / page).read_text()
        for name in markers(text):
            marked.add(name)
            if name not in names:
                problems.append(f"{page}: <!-- output: {name} --> names no output")
            try:
                block_span(text.splitlines(), name)
            except ValueError as exc:
                problems.append(f"{page}: {exc}")
    problems += [f"no page shows the output {name}" for name in sorted(names - marked)]
    return problems
