"""Stop signals: SIGTERM and SIGHUP stop like Ctrl-C, a worker stops once and cleans up, and
a child asked to die with its parent does, even when the parent is killed outright."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from bfsitl.stop_signals import (
    Interrupted,
    how_stopped,
    stop_signals_ignored,
    stop_signals_interrupt,
)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_raise_an_interrupt_that_names_them(signum: int) -> None:
    before = signal.getsignal(signum)
    with pytest.raises(KeyboardInterrupt) as caught, stop_signals_interrupt():
        os.kill(os.getpid(), signum)
        time.sleep(1.0)  # the handler runs at the next bytecode
    assert isinstance(caught.value, Interrupted)
    assert how_stopped(caught.value) == signal.Signals(signum).name
    assert signal.getsignal(signum) is before  # put back on the way out


def test_ctrl_c_is_said_as_ctrl_c() -> None:
    assert how_stopped(KeyboardInterrupt()) == "Ctrl-C"
    assert how_stopped(Interrupted("SIGINT")) == "Ctrl-C"


def test_signals_are_ignored_while_a_cleanup_must_finish() -> None:
    with stop_signals_interrupt(), stop_signals_ignored():
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(0.05)  # nothing raised: the cleanup went on


def _python(code: str, **kwargs) -> subprocess.Popen[str]:  # type: ignore[no-untyped-def]
    return subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(code)], text=True, stdout=subprocess.PIPE, **kwargs
    )


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def test_a_child_dies_with_its_parent_even_when_the_parent_is_killed(tmp_path: Path) -> None:
    # parent -> child; the child asks to die with the parent and says its pid; SIGKILL the
    # parent (it runs no Python at all then), and the kernel ends the child.
    parent = _python(f"""
        import subprocess, sys, time
        child = subprocess.Popen([sys.executable, "-c", '''
        import os, time
        from bfsitl.stop_signals import die_with_parent
        die_with_parent({{parent}})
        open({str(tmp_path / "child.pid")!r}, "w").write(str(os.getpid()))
        time.sleep(60)
        '''.replace("{{parent}}", str(__import__("os").getpid()))])
        print(child.pid, flush=True)
        time.sleep(60)
        """)
    try:
        assert parent.stdout is not None
        child_pid = int(parent.stdout.readline())
        deadline = time.monotonic() + 20
        while not (tmp_path / "child.pid").exists():
            assert time.monotonic() < deadline, "the child never started"
            time.sleep(0.05)
        assert _alive(child_pid)
        parent.kill()
        parent.wait()
        deadline = time.monotonic() + 5
        while _alive(child_pid) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert not _alive(child_pid), "the child outlived its killed parent"
    finally:
        parent.kill()


def test_a_worker_stops_once_cleans_up_and_ends_with_its_job() -> None:
    worker = _python(
        """
        import os, signal, sys, time
        from bfsitl.stop_signals import Interrupted, WorkerStop
        stop = WorkerStop()
        stop.install()
        with stop.job():
            try:
                print("busy", flush=True)
                time.sleep(30)
            except Interrupted as exc:
                print("interrupted", exc.signal_name, flush=True)
                os.kill(os.getpid(), signal.SIGINT)    # a second signal: ignored
                time.sleep(0.2)
                print("cleaned up", flush=True)
        print("still here after the job", flush=True)
        """,
        stderr=subprocess.PIPE,
    )
    assert worker.stdout is not None
    assert worker.stdout.readline().strip() == "busy"
    worker.send_signal(signal.SIGTERM)
    out, err = worker.communicate(timeout=20)
    assert out.splitlines() == ["interrupted SIGTERM", "cleaned up"]
    assert worker.returncode == 0, err


def test_an_idle_worker_ends_quietly() -> None:
    idle = _python(
        """
        import time
        from bfsitl.stop_signals import WorkerStop
        WorkerStop().install()
        print("idle", flush=True)
        time.sleep(30)
        """,
        stderr=subprocess.PIPE,
    )
    assert idle.stdout is not None and idle.stdout.readline().strip() == "idle"
    idle.send_signal(signal.SIGINT)
    _out, err = idle.communicate(timeout=20)
    assert idle.returncode == 0 and "Traceback" not in err, err
