"""Run a command and report what it left running: ``python subreaper.py REPORT GRACE_S OUT ERR
-- COMMAND...``.

This process becomes the command's *subreaper* (``PR_SET_CHILD_SUBREAPER``): whatever the
command starts and leaves behind when it ends (its workers, their resource tracker, a SITL,
a namespace agent) is handed to this process instead of to init, so it can be seen.  It
prints the command's pid on its first line (the command runs in a session of its own, so its
pid is also its process group: a test can send it "Ctrl-C"), waits for it, then gives what is
left up to ``GRACE_S`` to end by itself, and writes ``{"returncode": ..., "left": [...]}`` to
REPORT.  Whatever is still left then is killed, so a failing test leaves nothing either.
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

_PR_SET_CHILD_SUBREAPER = 36


def _children() -> list[int]:
    """This process's living children (its own, and the orphans it inherited)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == os.getpid() and fields[0] != "Z":
            found.append(int(entry.name))
    return found


def _reap() -> None:
    while True:
        try:
            pid, _status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return


def _describe(pid: int) -> str:
    try:
        argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
    except OSError:
        return f"{pid} (gone)"
    return f"{pid} {' '.join(part.decode(errors='replace') for part in argv if part)}"


def main() -> int:
    report_path, grace_s, out_path, err_path, dashes, *command = sys.argv[1:]
    assert dashes == "--", "usage: subreaper.py REPORT GRACE_S OUT ERR -- COMMAND..."
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(_PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_CHILD_SUBREAPER)")
    with open(out_path, "w") as out, open(err_path, "w") as err:
        child = subprocess.Popen(
            command, stdout=out, stderr=err, stdin=subprocess.DEVNULL, start_new_session=True
        )
    print(child.pid, flush=True)
    returncode = child.wait()
    deadline = time.monotonic() + float(grace_s)
    _reap()
    left = _children()
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        _reap()
        left = _children()
    Path(report_path).write_text(
        json.dumps({"returncode": returncode, "left": [_describe(pid) for pid in left]})
    )
    # The test fails; still leave nothing behind.  A resource tracker is given a moment to
    # go by itself once the others are gone: killed, it would leave its semaphores behind.
    for round_number in range(50):
        for pid in _children():
            if round_number < 20 and "resource_tracker" in _describe(pid):
                continue
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        time.sleep(0.1)
        _reap()
        if not _children():
            break
    return 0


if __name__ == "__main__":
    sys.exit(main())
