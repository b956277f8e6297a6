"""However a scenario suite is stopped, nothing it started outlives it.

``bfsitl scenario run --jobs 2`` on the real firmware, stopped while both workers fly: by
Ctrl-C (SIGINT to its process group, as a terminal sends it), by SIGTERM (what ``timeout``,
CI runners and systemd send first) and by SIGKILL.  The first two must write the JUnit file
and the report with the unfinished runs marked not run, and say which signal it was; all
three must leave no process (workers, their resource tracker, SITLs, namespace agents) and
no multiprocessing semaphore in /dev/shm.  The suite runs under ``subreaper.py``, which
inherits every orphan, so a leftover cannot hide by being re-parented to init.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from junitparser import JUnitXml, Skipped

from bfsitl.build import FirmwareCache
from bfsitl.cli.doctor import stale_sitl_processes

pytestmark = pytest.mark.sitl

SUBREAPER = Path(__file__).with_name("subreaper.py")
BUILD = "4.6.0-gps-lockstep"
#: Four runs for two workers: two fly when the signal comes, two wait their turn.
SCENARIOS = ("gps-rescue-home", "rc-loss-hover-autoland", "gusts", "motor-weak")
#: How long the leftovers get to end by themselves once the suite's process is gone (a
#: worker told by the kernel closes its session: disarm, stop the SITL).
GRACE_S = 30.0


def _sitl_pids() -> set[int]:
    return {pid for pid, _name in stale_sitl_processes()}


def _semaphores() -> set[str]:
    return {path.name for path in Path("/dev/shm").glob("sem.mp-*")}


@pytest.mark.timeout(300)
@pytest.mark.parametrize(
    "signum", [signal.SIGINT, signal.SIGTERM, signal.SIGKILL], ids=["ctrl-c", "sigterm", "sigkill"]
)
def test_a_stopped_suite_leaves_nothing_running_and_says_what_it_did_not_run(
    signum: signal.Signals,
    lockstep_gps_46_firmware: Path,
    firmware_build_cache: FirmwareCache,
    tmp_path: Path,
) -> None:
    sitls_before, semaphores_before = _sitl_pids(), _semaphores()
    junit, report_dir, out = tmp_path / "results.xml", tmp_path / "report", tmp_path / "runs"
    env = {**os.environ, "BFSITL_CACHE_DIR": str(firmware_build_cache.root)}
    env.pop("BFSITL_FIRMWARE", None)
    watcher = subprocess.Popen(
        [
            sys.executable,
            str(SUBREAPER),
            str(tmp_path / "left.json"),
            str(GRACE_S),
            str(tmp_path / "stdout"),
            str(tmp_path / "stderr"),
            "--",
            sys.executable,
            "-m",
            "bfsitl.cli.main",
            "scenario",
            "run",
            *SCENARIOS,
            "--firmware",
            BUILD,
            "--jobs",
            "2",
            "--junit",
            str(junit),
            "--report",
            str(report_dir),
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=env,
    )
    try:
        assert watcher.stdout is not None
        suite_pid = int(watcher.stdout.readline())
        deadline = time.monotonic() + 120
        while len(_sitl_pids() - sitls_before) < 2:  # both workers are flying
            assert watcher.poll() is None, (tmp_path / "stderr").read_text()[-3000:]
            assert time.monotonic() < deadline, "the two runs never started"
            time.sleep(0.05)
        time.sleep(0.5)
        if signum == signal.SIGINT:
            os.killpg(suite_pid, signum)  # a terminal's Ctrl-C: the whole group
        else:
            os.kill(suite_pid, signum)  # kill, timeout, a CI runner: the process
        watcher.wait(timeout=GRACE_S + 120)
    finally:
        if watcher.poll() is None:
            watcher.kill()
    stderr = (tmp_path / "stderr").read_text()
    left = json.loads((tmp_path / "left.json").read_text())
    assert left["left"] == [], f"left running: {left['left']}\n{stderr[-3000:]}"
    assert not _sitl_pids() - sitls_before, "a SITL outlived the suite"
    assert not _semaphores() - semaphores_before, "semaphores left in /dev/shm"
    if signum == signal.SIGKILL:
        return
    how = "Ctrl-C" if signum == signal.SIGINT else "SIGTERM"
    assert left["returncode"] == 130, stderr[-3000:]
    assert f"interrupted ({how})" in stderr, stderr[-3000:]
    cases = [case for suite in JUnitXml.fromfile(str(junit)) for case in suite]
    assert len(cases) == len(SCENARIOS), [case.name for case in cases]
    not_run = [
        case
        for case in cases
        for result in case.result
        if isinstance(result, Skipped) and f"interrupted ({how})" in (result.message or "")
    ]
    assert not_run, [(case.name, [r.message for r in case.result]) for case in cases]
    assert (report_dir / "index.html").is_file()
