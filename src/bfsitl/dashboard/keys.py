"""Single key presses from the terminal, without Enter, for the dashboard's ``q``.

The terminal is put in cbreak mode (no line buffering, no echo) for as long as the dashboard
runs and restored on the way out, whatever happens.  cbreak keeps ``ISIG``, so Ctrl-C still
raises KeyboardInterrupt and the dashboard can quit cleanly on it too.  Waiting for a key is
also how the loop paces itself: ``wait_key(timeout_s)`` returns early only when a key arrives.
"""

from __future__ import annotations

import os
import select
import time
from typing import Protocol


class KeySource(Protocol):
    """Where the dashboard's key presses come from."""

    def wait_key(self, timeout_s: float) -> str | None:
        """The keys pressed within ``timeout_s`` (as soon as one is), or None after it."""
        ...


class NoKeys:
    """No keyboard (stdin is not a terminal): only waits.  Ctrl-C still quits."""

    def wait_key(self, timeout_s: float) -> str | None:
        if timeout_s > 0:
            time.sleep(timeout_s)
        return None


class TerminalKeys:
    """Keys from a terminal file descriptor in cbreak mode; use as a context manager."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._saved: list | None = None

    def __enter__(self) -> TerminalKeys:
        import termios
        import tty

        self._saved = termios.tcgetattr(self.fd)
        tty.setcbreak(self.fd)
        return self

    def __exit__(self, *exc_info: object) -> None:
        if self._saved is not None:
            import termios

            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
            self._saved = None

    def wait_key(self, timeout_s: float) -> str | None:
        readable, _, _ = select.select([self.fd], [], [], max(0.0, timeout_s))
        if not readable:
            return None
        data = os.read(self.fd, 64)
        return data.decode("utf-8", "replace") if data else None


def is_quit(keys: str) -> bool:
    """q, Q, or Ctrl-D (EOF typed at the terminal) quit."""
    return any(key in ("q", "Q", "\x04") for key in keys)
