"""However a bfsitl process is stopped, it stops cleanly and nothing it started outlives it.

* Ctrl-C (SIGINT), SIGTERM (``kill``, ``timeout``, CI runners, systemd) and SIGHUP (a closed
  terminal) all take one path: :class:`Interrupted`, a :class:`KeyboardInterrupt`, raised
  in the main thread, so every ``finally`` and context manager runs (sessions disarm, SITLs
  stop, reports get written).  :func:`stop_signals_interrupt` installs that for a command.
* A process bfsitl starts for its own work (a scenario suite's worker) asks the kernel to
  signal it when its parent ends (:func:`die_with_parent`): a SIGKILL of the parent runs no
  Python at all, so only the kernel can tell the children.
* A worker takes the first stop signal as :class:`Interrupted` and ignores the rest
  (:class:`WorkerStop`): a second Ctrl-C, or the parent passing the signal on, must not cut
  short the cleanup the first one started; once its job has cleaned up, the worker ends.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from types import FrameType
from typing import NoReturn

from bfsitl.errors import Interrupted

_PR_SET_PDEATHSIG = 1

#: The signals that mean "stop now, cleanly".
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


def how_stopped(exc: BaseException) -> str:
    """``Ctrl-C`` for SIGINT (what a user pressed), else the signal's name."""
    name = exc.signal_name if isinstance(exc, Interrupted) else "SIGINT"
    return "Ctrl-C" if name == "SIGINT" else name


def _raise_interrupted(signum: int, _frame: FrameType | None) -> None:
    raise Interrupted(signal.Signals(signum).name)


@contextmanager
def _handling(
    signums: tuple[int, ...], handler: signal.Handlers | Callable[..., None]
) -> Iterator[None]:
    """While inside: ``signums`` go to ``handler``; the previous handlers come back on the way
    out.  Outside the main thread (where Python cannot take signals) it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {signum: signal.signal(signum, handler) for signum in signums}
    try:
        yield
    finally:
        for signum, before in previous.items():
            signal.signal(signum, before)


def stop_signals_interrupt() -> AbstractContextManager[None]:
    """While inside: SIGTERM and SIGHUP raise :class:`Interrupted` like Ctrl-C does."""
    return _handling((signal.SIGTERM, signal.SIGHUP), _raise_interrupted)


def stop_signals_ignored() -> AbstractContextManager[None]:
    """While inside: stop signals are ignored, so a bounded cleanup runs to its end."""
    return _handling(STOP_SIGNALS, signal.SIG_IGN)


def die_with_parent(parent_pid: int, signum: int = signal.SIGTERM) -> None:
    """Ask the kernel to send ``signum`` to this process when its parent ends, however it
    ends.  If the parent is already gone (it ended before this call), exit at once.  Linux
    only; elsewhere it does nothing."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, int(signum), 0, 0, 0)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:
        os._exit(1)


class WorkerStop:
    """A pool worker's stop signals: the first raises :class:`Interrupted` in the job under
    way, whose cleanup then runs, and the worker ends when the job does; an idle worker
    ends at once.  Later signals are ignored.

    A worker must end by itself: a pool hands a live worker the next job, and when the
    parent was killed, the worker would wait for work forever on a queue whose other end
    it holds itself (so it never sees the end of it).

    Use :meth:`install` once in the worker, and :meth:`job` around each job."""

    def __init__(self) -> None:
        self.stopping = False
        self.signal_name = "SIGINT"
        self._busy = False

    def install(self) -> None:
        for signum in STOP_SIGNALS:
            signal.signal(signum, self._on_signal)

    @contextmanager
    def job(self) -> Iterator[None]:
        """Around one job.  A job that starts after a stop signal ends the worker at once."""
        if self.stopping:
            self._end()
        self._busy = True
        try:
            yield
        finally:
            self._busy = False
            if self.stopping:
                # The job has cleaned up; its result has nowhere to go (the parent is gone
                # or stopping and counts it as not run).
                self._end()

    def _on_signal(self, signum: int, _frame: FrameType | None) -> None:
        if self.stopping:
            return
        self.stopping = True
        self.signal_name = signal.Signals(signum).name
        if not self._busy:
            self._end()  # idle: nothing to clean up, wherever the worker waits
        raise Interrupted(self.signal_name)

    @staticmethod
    def _end() -> NoReturn:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)
