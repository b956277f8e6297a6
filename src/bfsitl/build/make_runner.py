"""Run Betaflight's ``make`` for a SITL: progress, a clean environment, and a clean stop.

* make and everything it starts run in a process group of their own; on Ctrl-C, any other
  exception or a failure the whole group is terminated (then killed), so no compiler keeps
  writing into a directory that is being deleted.
* Progress comes from Betaflight's own compile lines (``%% (optimised) src/...c``), one per
  source file; the total is estimated by a ``make -n`` dry run started beside the build.
* Variables that make would take from the environment as defaults (``OPTIONS``, ``CFLAGS``,
  ``MAKEFLAGS`` from an outer make, ...) are removed, so a build depends only on its plan.
* On failure the error names its cause (the first compiler ``error:`` line, or make's
  ``***`` line) with the last lines of output; a missing gcc or make names the package.
"""

from __future__ import annotations

import collections
import os
import re
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from bfsitl.build.progress import BuildProgress
from bfsitl.errors import BuildToolMissingError, FirmwareBuildError

COMPILE_LINE_PREFIX = "%% "
"""How Betaflight's ``compile_file`` announces each source file."""

REQUIRED_TOOLS = ("make", "gcc")
INSTALL_TOOLS_HINT = "sudo apt-get install gcc make  (Debian/Ubuntu; packages gcc and make)"
TAIL_LINES = 20

CLEARED_ENV_VARS = (
    "MAKEFLAGS",
    "MFLAGS",
    "MAKELEVEL",
    "MAKEFILES",
    "GNUMAKEFLAGS",
    "TARGET",
    "OPTIONS",
    "EXTRA_FLAGS",
    "DEBUG",
    "DEBUG_FLAGS",
    "CONFIG",
    "REV",
    "REVISION",
    "CFLAGS",
    "CPPFLAGS",
    "LDFLAGS",
    "CCACHE",
    "ARM_SDK_PREFIX",
    "ARM_SDK_DIR",
    "V",
    "OBJECT_DIR",
    "BIN_DIR",
)
"""Environment variables make reads as variable defaults; none of them may shape a build."""

_TERM_GRACE_S = 2.0
_ERROR_RE = re.compile(r"(\berror\b:|\*\*\*|undefined reference)", re.IGNORECASE)
_MISSING_TOOL_RE = re.compile(
    r"(?:^|[\s:/])(?P<tool>gcc|cc|cc1|make|ld|as)(?:-\d+)?: (?:command )?not found"
    r"|(?:^|[\s:/])(?P<tool2>gcc|cc|make)(?:-\d+)?: No such file or directory",
)


@dataclass(frozen=True)
class MakeResult:
    duration_s: float
    compiled_files: int


def check_build_tools(environ: Mapping[str, str]) -> None:
    """Raise :class:`BuildToolMissingError` before anything is copied if gcc or make is absent."""
    path = environ.get("PATH", os.defpath)
    missing = [tool for tool in REQUIRED_TOOLS if shutil.which(tool, path=path) is None]
    if missing:
        raise BuildToolMissingError(
            f"cannot build the SITL: {' and '.join(missing)} not found on PATH. "
            f"Install: {INSTALL_TOOLS_HINT}"
        )


def build_environment(environ: Mapping[str, str], work_dir: Path) -> dict[str, str]:
    """The environment make runs in (see the module docstring)."""
    env = {k: v for k, v in environ.items() if k not in CLEARED_ENV_VARS}
    # The copy has no .git: without a ceiling, 4.6.0's `git rev-parse HEAD` would find a
    # repository around the cache directory and stamp its revision into the firmware.
    env["GIT_CEILING_DIRECTORIES"] = str(work_dir)
    # Compiler messages in English: the cause of a failure is found by its words.
    env["LC_ALL"] = "C"
    return env


def run_make(
    args: Sequence[str],
    *,
    cwd: Path,
    env: Mapping[str, str],
    progress: BuildProgress,
    dry_run_args: Sequence[str] | None = None,
) -> MakeResult:
    """Run make in ``cwd``; returns its duration and the files compiled, or raises."""
    started_s = time.monotonic()
    tail: collections.deque[str] = collections.deque(maxlen=TAIL_LINES)
    first_error: str | None = None
    missing_tool: str | None = None
    compiled = 0
    estimator: _DryRun | None = None
    try:
        process = subprocess.Popen(
            list(args),
            cwd=cwd,
            env=dict(env),
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            errors="replace",
            start_new_session=True,
        )
    except FileNotFoundError:
        raise BuildToolMissingError(
            f"cannot run {args[0]}: not installed. Install: {INSTALL_TOOLS_HINT}"
        ) from None
    try:
        if dry_run_args is not None:
            estimator = _DryRun(dry_run_args, cwd, env, progress)
        assert process.stdout is not None
        for raw in process.stdout:
            line = raw.rstrip("\n")
            tail.append(line)
            if line.startswith(COMPILE_LINE_PREFIX):
                compiled += 1
                progress.compiled(compiled)
                continue
            if missing_tool is None:
                found = _MISSING_TOOL_RE.search(line)
                if found:
                    missing_tool = found.group("tool") or found.group("tool2")
            if first_error is None and _ERROR_RE.search(line):
                first_error = line.strip()
        code = process.wait()
    except BaseException:
        _stop_group(process)
        raise
    finally:
        if estimator is not None:
            estimator.stop()
        progress.finish()
    duration_s = time.monotonic() - started_s
    if code != 0:
        output = "\n".join(tail)
        if missing_tool is not None:
            raise BuildToolMissingError(
                f"make failed: the build needs {missing_tool}, which is not installed. Install: "
                f"{INSTALL_TOOLS_HINT}\nlast lines of make's output:\n{output}",
                output,
            )
        cause = first_error or (tail[-1].strip() if tail else "no output")
        raise FirmwareBuildError(
            f"make failed (exit code {code}) after {duration_s:.1f} s: {cause}\n"
            f"last {len(tail)} lines of make's output:\n{output}",
            output,
        )
    return MakeResult(duration_s, compiled)


def _stop_group(process: subprocess.Popen[str], *, close_output: bool = True) -> None:
    """TERM make's whole process group, KILL it after a grace period, reap make."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(process.pid, sig)
        except (ProcessLookupError, PermissionError):
            break
        try:
            process.wait(_TERM_GRACE_S)
            # make is gone; its compilers may linger a moment in the group: KILL them too.
            if sig == signal.SIGTERM:
                try:
                    os.killpg(process.pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass
            break
        except subprocess.TimeoutExpired:
            continue
    if close_output and process.stdout is not None:
        process.stdout.close()


class _DryRun:
    """``make -n`` beside the build: counts the compile lines it would run, sets the total."""

    def __init__(
        self, args: Sequence[str], cwd: Path, env: Mapping[str, str], progress: BuildProgress
    ) -> None:
        self._progress = progress
        try:
            self._process: subprocess.Popen[str] | None = subprocess.Popen(
                list(args),
                cwd=cwd,
                env=dict(env),
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                text=True,
                errors="replace",
                start_new_session=True,
            )
        except OSError:
            self._process = None
            return
        self._thread = threading.Thread(target=self._count, name="make-dry-run", daemon=True)
        self._thread.start()

    def _count(self) -> None:
        # A dry run prints the commands, so each file shows as `echo "%% (...) file.c" && gcc
        # ...`.  It may end in an error at the link step (master's Makefile reads a file the
        # compile step would have written): the count of compile commands stands anyway.
        assert self._process is not None and self._process.stdout is not None
        total = sum(1 for line in self._process.stdout if COMPILE_LINE_PREFIX in line)
        self._process.wait()
        if total:
            self._progress.set_total(total)

    def stop(self) -> None:
        if self._process is None:
            return
        if self._process.poll() is None:
            # Its reader thread sees the pipe end once the group is gone; closing the pipe
            # under that thread instead would make it fail.
            _stop_group(self._process, close_output=False)
        self._thread.join(timeout=_TERM_GRACE_S)
        if self._process.stdout is not None and not self._thread.is_alive():
            self._process.stdout.close()
