"""A namespaced SITL's liveness from /proc: running, ended (a zombie), gone."""

from __future__ import annotations

import os
import subprocess
import sys
import time

from bfsitl.sitl.network import _running


def test_a_running_process_is_running() -> None:
    assert _running(os.getpid())


def test_an_ended_process_not_yet_collected_is_not_running() -> None:
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    deadline = time.monotonic() + 10
    while _running(child.pid) and time.monotonic() < deadline:
        time.sleep(0.01)  # it exits at once; until wait() it is a zombie
    assert not _running(child.pid)
    assert child.wait() == 0
    assert not _running(child.pid)  # collected: gone from /proc
