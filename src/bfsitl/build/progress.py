"""Progress of a build on stderr: a live counter on a terminal, plain lines otherwise.

The total number of files is an estimate that may arrive late (a ``make -n`` dry run runs
beside the build), so until it does the count is shown alone.  Not a terminal (CI logs, a
pipe): one line per 10 % (or per 50 files without a total), never a carriage return.
"""

from __future__ import annotations

import sys
import threading
import time
from typing import TextIO

PREFIX = "bfsitl: "
_LIVE_INTERVAL_S = 0.1
_PLAIN_STEP_PERCENT = 10
_PLAIN_STEP_FILES = 50


STDERR = "stderr"
"""The default stream: ``sys.stderr`` as it is when the progress is created (not as it was
when this module was imported, so redirections and test captures are honoured)."""


class BuildProgress:
    """Where a build reports to.  ``stream=None`` is silent (library use)."""

    def __init__(self, stream: TextIO | str | None = STDERR, *, live: bool | None = None) -> None:
        if isinstance(stream, str):
            stream = sys.stderr
        self.stream: TextIO | None = stream
        if live is None:
            isatty = getattr(stream, "isatty", None)
            live = bool(isatty and isatty())
        self.live = live
        self._lock = threading.Lock()
        self._total: int | None = None
        self._count = 0
        self._last_step = 0
        self._last_printed = 0
        self._last_draw_s = 0.0
        self._line_open = False

    def note(self, message: str) -> None:
        """One line of its own (a live counter line is finished first)."""
        with self._lock:
            self._end_live_line()
            self._write(f"{PREFIX}{message}\n")

    def set_total(self, total: int) -> None:
        """The estimated number of files to compile (may be called from another thread)."""
        with self._lock:
            self._total = max(total, self._count) if total > 0 else None

    def compiled(self, count: int) -> None:
        """``count`` files compiled so far."""
        with self._lock:
            self._count = count
            if self.live:
                now = time.monotonic()
                if now - self._last_draw_s >= _LIVE_INTERVAL_S:
                    self._last_draw_s = now
                    self._write(f"\r{PREFIX}compiling {self._counter()}")
                    self._line_open = True
                return
            if self._total:
                step = min(100, count * 100 // self._total) // _PLAIN_STEP_PERCENT
                if step > self._last_step:
                    self._last_step = step
                    self._plain_line()
            elif count % _PLAIN_STEP_FILES == 0:
                self._plain_line()

    def finish(self) -> None:
        """The compile phase is over: the final count (a live line is closed)."""
        with self._lock:
            if self.live and self._count:
                self._write(f"\r{PREFIX}compiled {self._counter()}")
                self._line_open = True
            elif self._count and self._count != self._last_printed:
                self._plain_line()
            self._end_live_line()

    def _plain_line(self) -> None:
        self._last_printed = self._count
        self._write(f"{PREFIX}compiled {self._counter()}\n")

    def _counter(self) -> str:
        if self._total:
            total = max(self._total, self._count)
            return f"{self._count}/{total} files ({self._count * 100 // total} %)"
        return f"{self._count} files"

    def _end_live_line(self) -> None:
        if self._line_open:
            self._write("\n")
            self._line_open = False

    def _write(self, text: str) -> None:
        if self.stream is None:
            return
        self.stream.write(text)
        self.stream.flush()
