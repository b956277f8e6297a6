"""The transport base: a byte stream with deadlines and the project's own errors.

A subclass fills in three hooks (``_write_bytes``, ``_read_bytes``, ``_close``); the base owns
timeouts, byte counters, and the mapping of ``OSError`` to :class:`~bfsitl.errors.LinkError`
so that no caller above this layer ever sees a bare socket or serial exception.
"""

from __future__ import annotations

import abc
import errno
import threading
import time
from types import TracebackType

from bfsitl.errors import LinkClosedError, LinkError, LinkTimeoutError

DEFAULT_TIMEOUT_S = 1.0


class Link(abc.ABC):
    """A bidirectional byte stream to a flight controller.

    A link also says what the peer on its far side needs of an MSP client, so that nobody
    guesses it from the link's type (a wrapped link would defeat the guess).
    """

    #: The peer flushes its replies only when more bytes arrive (a SITL's TCP thread): the
    #: client sends wake bytes while it waits.
    wants_wake_bytes: bool = False
    #: What the peer's receive buffer takes at once: the client keeps less in flight.  The
    #: default is below a SITL's 1400-byte TCP receive ring, with room for an RC frame.
    max_in_flight_bytes: int = 1024

    def __init__(self, uri: str, timeout_s: float = DEFAULT_TIMEOUT_S) -> None:
        self.uri = uri
        self.timeout_s = timeout_s
        self.bytes_written = 0
        self.bytes_read = 0
        self._closed = False
        # Writers from several threads (an RC stream beside telemetry) must not interleave
        # the bytes of two frames.
        self._write_lock = threading.Lock()

    # -- hooks -----------------------------------------------------------------------------
    @abc.abstractmethod
    def _write_bytes(self, data: bytes) -> None:
        """Write all of ``data`` or raise OSError."""

    @abc.abstractmethod
    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        """Up to ``max_bytes``; ``b""`` when nothing came in ``timeout_s``; None on EOF."""

    @abc.abstractmethod
    def _close(self) -> None:
        """Release the OS resource."""

    @property
    def readable_fd(self) -> int:
        """A descriptor that polls readable when bytes have come (-1: none to poll); a
        lockstep MSP wait lets the compiled loop watch it between steps."""
        return -1

    # -- public API ------------------------------------------------------------------------
    @property
    def closed(self) -> bool:
        return self._closed

    def write(self, data: bytes) -> None:
        if self._closed:
            raise LinkClosedError(f"{self.uri}: link is closed")
        try:
            with self._write_lock:
                self._write_bytes(bytes(data))
        except OSError as exc:
            raise self._map_error(exc, "write") from exc
        self.bytes_written += len(data)

    def read_some(self, timeout_s: float | None = None, max_bytes: int = 65536) -> bytes:
        """Whatever arrives first, up to ``max_bytes``; ``b""`` if nothing in ``timeout_s``.

        Raises :class:`LinkClosedError` when the peer has closed the stream.
        """
        if self._closed:
            raise LinkClosedError(f"{self.uri}: link is closed")
        wait_s = self.timeout_s if timeout_s is None else max(0.0, timeout_s)
        try:
            data = self._read_bytes(max_bytes, wait_s)
        except OSError as exc:
            raise self._map_error(exc, "read") from exc
        if data is None:
            raise LinkClosedError(
                f"{self.uri}: the other end closed the connection "
                f"(a SITL closes it when it reboots or exits, or when another client holds "
                f"its port)"
            )
        self.bytes_read += len(data)
        return data

    def pause(self, seconds: float) -> None:
        """Let ``seconds`` pass on the FC's side of the link (a guard time it needs).

        Wall time here; a lockstep link lets simulation time pass instead (the FC's clock
        moves only when the simulation steps).
        """
        if seconds > 0:
            time.sleep(seconds)

    def drain_input(self, quiet_s: float = 0.05) -> bytes:
        """Read and return everything until the line has been quiet for ``quiet_s``."""
        drained = bytearray()
        while True:
            chunk = self.read_some(quiet_s)
            if not chunk:
                return bytes(drained)
            drained += chunk

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._close()
        except OSError:
            pass  # closing is best effort: the resource is gone either way

    def __enter__(self) -> Link:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        state = "closed" if self._closed else "open"
        return f"<{type(self).__name__} {self.uri} {state}>"

    def _map_error(self, exc: OSError, action: str) -> LinkError:
        if isinstance(exc, TimeoutError):
            return LinkTimeoutError(f"{self.uri}: {action} timed out")
        if exc.errno in (errno.ECONNRESET, errno.EPIPE, errno.ENOTCONN, errno.EBADF):
            return LinkClosedError(f"{self.uri}: connection lost during {action} ({exc})")
        return LinkError(f"{self.uri}: {action} failed: {exc}")
