"""Timer slack for the SITL process.

The SITL's main loop sleeps 50 us of real time per scheduler pass (``main.c``:
``delayMicroseconds_real(50)``).  Linux adds the process's timer slack to every such sleep,
50 us by default, so each pass takes 100 us or more and the 8 kHz gyro/PID loop and the 100 Hz
serial (MSP) task run slow: on a 2-core VM the firmware's own ``tasks`` showed GYRO at 2462 Hz
and SERIAL at 74 Hz with the default slack, 8244 Hz and 89 Hz with 1 ns.  Timer slack is
inherited across fork and exec, so the launcher sets it just before starting the SITL.
Figures: ``benchmarks/telemetry.py``.
"""

from __future__ import annotations

import contextlib
import ctypes
from collections.abc import Iterator

#: What bfsitl gives the SITL by default.
SITL_TIMER_SLACK_NS = 1
_PR_SET_TIMERSLACK = 29
_PR_GET_TIMERSLACK = 30


def set_timer_slack(slack_ns: int) -> bool:
    """Set this process's timer slack (children inherit it); False where not possible."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_TIMERSLACK, ctypes.c_ulong(slack_ns), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


@contextlib.contextmanager
def timer_slack(slack_ns: int | None) -> Iterator[None]:
    """Use ``slack_ns`` on this thread for the block (a fork inside inherits it), then restore.

    Timer slack belongs to the thread, and a child starts with the slack of the thread that
    forked it, so this touches neither the other threads nor the rest of the program.
    """
    if slack_ns is None:
        yield
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        previous_ns = int(libc.prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0))
    except (OSError, AttributeError):
        yield
        return
    set_timer_slack(slack_ns)
    try:
        yield
    finally:
        if previous_ns > 0:
            set_timer_slack(previous_ns)
