"""A virtual serial port: a pseudo-terminal whose bytes are relayed to a SITL's UART over TCP.

Tools that only open serial devices (pyserial, terminal monitors, our own ``serial://`` link)
then reach a SITL exactly as they would reach a board on ``/dev/ttyACM0``.  A symlink gives
the port a stable name, since the pty's own name (``/dev/pts/N``) changes on every run.

Why it is built this way:

* The pty is put in raw mode: MSP is binary, and a line discipline would echo bytes, turn CR
  into LF and swallow ``0x03`` as an interrupt.
* The bridge holds no descriptor of the pty's terminal side.  Linux then reports a hang-up on
  our side whenever no program has the port open, which is how a client's arrival and
  departure are seen: a departure closes the SITL connection (the SITL serves one TCP client
  and would otherwise stay taken) and throws away bytes queued for the client that left.
* The SITL connection is opened on the client's first byte, and again after the SITL ended it
  (idle for 120 s, or the process exited on a reboot): a serial port has no "connect", so the
  bridge reconnects by itself, like a USB port coming back after a board rebooted.
* One thread and ``poll``: there are only two byte streams, and the order of bytes must be kept.
"""

from __future__ import annotations

import contextlib
import errno
import os
import select
import socket
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from bfsitl.bridges import (
    RequestWatch,
    SessionStats,
    Upstream,
    connect_upstream,
)
from bfsitl.errors import (
    BfsitlError,
    LinkPathError,
)

#: How often a bridge with no client looks whether one has opened the port.
IDLE_POLL_S = 0.05
#: After a failed SITL connection, client bytes are dropped (like a dead line) for this long
#: before the next attempt, so a client sending continuously does not hammer the SITL.
RECONNECT_BACKOFF_S = 1.0
#: Bytes held for a client that does not read; beyond this the oldest are dropped, as a UART
#: receiver overruns.
MAX_PENDING_TO_CLIENT_BYTES = 64 * 1024
_CHUNK_BYTES = 4096
_UPSTREAM_SEND_TIMEOUT_S = 2.0


@dataclass(frozen=True, slots=True)
class PtyEndpoint:
    """Where clients open the virtual port: the pty itself, and the stable symlink if any."""

    device: str
    link: Path | None = None

    @property
    def path(self) -> str:
        """The name to give a client: the symlink when there is one."""
        return str(self.link) if self.link is not None else self.device

    @property
    def uri(self) -> str:
        """The same port as a bfsitl link URI."""
        return f"serial://{self.path}"


class PtyRelay:
    """A pty relayed to the SITL's UART; :meth:`open`, then :meth:`serve` until :meth:`stop`.

    ``on_event`` receives one line per noteworthy event (client in and out, SITL connection
    problems, warnings); :attr:`sessions` keeps the statistics of every client that left.
    """

    def __init__(
        self,
        upstream: Upstream,
        *,
        link_path: str | Path | None = None,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        self.upstream = upstream
        self.link_path = Path(link_path) if link_path is not None else None
        self.sessions: list[SessionStats] = []
        self.endpoint: PtyEndpoint | None = None
        self._on_event = on_event or (lambda _line: None)
        self._master: int | None = None
        self._wake_r = self._wake_w = -1  # a pipe from open(): stop() wakes the loop with it
        self._stopping = threading.Event()
        self._upstream: socket.socket | None = None
        self._session: SessionStats | None = None
        self._watch = RequestWatch()
        self._to_client = bytearray()
        self._retry_after_s = 0.0
        self._dropped_to_client = 0

    # -- lifecycle -------------------------------------------------------------------------
    def open(self) -> PtyEndpoint:
        """Create the pty (raw mode) and the symlink; clients may open it from now on."""
        if self.endpoint is not None:
            return self.endpoint
        self._wake_r, self._wake_w = os.pipe()
        master, slave = os.openpty()
        try:
            tty.setraw(slave)
            device = os.ttyname(slave)
        finally:
            os.close(slave)  # see the module docstring: hang-ups tell when clients come and go
        os.set_blocking(master, False)
        self._master = master
        try:
            if self.link_path is not None:
                _make_symlink(self.link_path, device, self._on_event)
        except BaseException:
            self._close_master()
            self._close_wake_pipe()
            raise
        self.endpoint = PtyEndpoint(device, self.link_path)
        return self.endpoint

    def serve(self) -> None:
        """Relay until :meth:`stop` is called (from any thread or a signal handler)."""
        if self._master is None:
            self.open()
        while not self._stopping.is_set():
            hung_up, readable = self._master_state()
            if hung_up:
                if readable:  # bytes the client wrote just before it closed the port
                    if self._session is None:
                        self._begin_session()
                    self._read_client(drain=True)
                self._end_session("client closed the port")
                self._wait_for_wake(IDLE_POLL_S)
                continue
            if self._session is None:
                self._begin_session()
            self._relay_once(IDLE_POLL_S)
        self._end_session("bridge stopped")

    def stop(self) -> None:
        """Make :meth:`serve` return soon; safe from another thread or a signal handler."""
        self._stopping.set()
        if self._wake_w >= 0:
            with contextlib.suppress(OSError):
                os.write(self._wake_w, b"x")

    def close(self) -> None:
        """Close the SITL connection and the pty, and remove our symlink.  Idempotent."""
        self._end_session("bridge stopped")  # no-op unless serve() was interrupted
        self._close_upstream()
        self._close_master()
        endpoint, self.endpoint = self.endpoint, None
        if endpoint is not None and endpoint.link is not None:
            _remove_symlink(endpoint.link, endpoint.device)
        self._close_wake_pipe()

    def _close_wake_pipe(self) -> None:
        for fd in (self._wake_r, self._wake_w):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._wake_r = self._wake_w = -1

    def __enter__(self) -> PtyEndpoint:
        return self.open()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    @contextlib.contextmanager
    def running(self) -> Iterator[PtyEndpoint]:
        """Open and serve from a background thread while the block runs; always cleans up."""
        endpoint = self.open()
        thread = threading.Thread(target=self.serve, name="bfsitl-pty-relay", daemon=True)
        thread.start()
        try:
            yield endpoint
        finally:
            self.stop()
            thread.join(timeout=10.0)
            self.close()

    # -- the loop --------------------------------------------------------------------------
    def _master_state(self) -> tuple[bool, bool]:
        """(no client has the port open, bytes from a client wait to be read)."""
        assert self._master is not None
        poller = select.poll()
        poller.register(self._master, select.POLLIN)
        events = 0
        for _fd, event in poller.poll(0):
            events |= event
        return bool(events & select.POLLHUP), bool(events & select.POLLIN)

    def _wait_for_wake(self, timeout_s: float) -> None:
        readable, _, _ = select.select([self._wake_r], [], [], timeout_s)
        if readable:
            with contextlib.suppress(OSError):
                os.read(self._wake_r, 64)

    def _relay_once(self, timeout_s: float) -> None:
        assert self._master is not None
        poller = select.poll()
        master_events = select.POLLIN | (select.POLLOUT if self._to_client else 0)
        poller.register(self._master, master_events)
        poller.register(self._wake_r, select.POLLIN)
        if self._upstream is not None:
            poller.register(self._upstream.fileno(), select.POLLIN)
        for fd, event in poller.poll(timeout_s * 1000):
            if fd == self._wake_r:
                self._wait_for_wake(0)
            elif fd == self._master:
                if event & select.POLLOUT:
                    self._flush_to_client()
                if event & select.POLLIN:
                    self._read_client()
            elif self._upstream is not None and fd == self._upstream.fileno():
                self._read_upstream()

    def _read_client(self, drain: bool = False) -> None:
        assert self._master is not None
        data = bytearray()
        while True:
            try:
                chunk = os.read(self._master, _CHUNK_BYTES)
            except BlockingIOError:
                break
            except OSError as exc:
                if exc.errno == errno.EIO:  # the client has closed the port, all read
                    break
                raise
            data += chunk
            if not chunk or not drain or len(data) >= MAX_PENDING_TO_CLIENT_BYTES:
                break
        if not data or self._session is None:
            return
        for warning in self._watch.feed(bytes(data)):
            self._on_event(f"{self._session.client}: {warning}")
        if self._upstream is None and not self._connect():
            return  # dropped, as bytes sent down a dead serial line
        assert self._upstream is not None
        try:
            self._upstream.sendall(data)
        except OSError as exc:
            self._on_event(f"writing to the SITL failed ({exc}); reconnecting on the next bytes")
            self._close_upstream()
            return
        self._session.bytes_to_fc += len(data)

    def _read_upstream(self) -> None:
        assert self._upstream is not None
        try:
            data = self._upstream.recv(_CHUNK_BYTES)
        except (BlockingIOError, TimeoutError):
            return
        except OSError as exc:
            data = b""
            self._on_event(f"SITL connection lost: {exc}")
        if not data:
            self._on_event(
                "the SITL closed the connection (it rebooted or exited, or the port "
                "sat idle for 120 s); reconnecting on the client's next bytes"
            )
            self._close_upstream()
            return
        if self._session is not None:
            self._session.bytes_to_client += len(data)
        self._to_client += data
        overflow = len(self._to_client) - MAX_PENDING_TO_CLIENT_BYTES
        if overflow > 0:
            del self._to_client[:overflow]
            if not self._dropped_to_client:
                self._on_event(
                    f"the client does not read: dropping the oldest bytes beyond "
                    f"{MAX_PENDING_TO_CLIENT_BYTES} B, as a UART overruns"
                )
            self._dropped_to_client += overflow
        self._flush_to_client()

    def _flush_to_client(self) -> None:
        assert self._master is not None
        try:
            written = os.write(self._master, self._to_client)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:  # no client any more; the hang-up check ends it
                return
            raise
        del self._to_client[:written]

    def _connect(self) -> bool:
        if time.monotonic() < self._retry_after_s:
            return False
        try:
            sock = connect_upstream(self.upstream)
        except (BfsitlError, OSError) as exc:  # also a SITL that failed to restart
            self._retry_after_s = time.monotonic() + RECONNECT_BACKOFF_S
            self._on_event(
                f"{exc} (client bytes are dropped; trying again in {RECONNECT_BACKOFF_S:.0f} s)"
            )
            return False
        sock.settimeout(_UPSTREAM_SEND_TIMEOUT_S)
        self._upstream = sock
        self._on_event(f"connected to the SITL at {self.upstream.uri}")
        return True

    # -- sessions --------------------------------------------------------------------------
    def _begin_session(self) -> None:
        self._session = SessionStats("serial client", time.monotonic())
        self._watch = RequestWatch()
        self._retry_after_s = 0.0
        self._dropped_to_client = 0
        self._on_event(f"a client opened {self.endpoint.path if self.endpoint else 'the pty'}")

    def _end_session(self, reason: str) -> None:
        session, self._session = self._session, None
        if session is None:
            return
        self._close_upstream()
        self._discard_queued_bytes()
        session.ended_s = time.monotonic()
        session.end_reason = reason
        session.torn_frame_bytes = self._watch.torn_frame_bytes
        self.sessions.append(session)
        self._on_event(session.summary())

    def _discard_queued_bytes(self) -> None:
        """Replies meant for the client that left must not greet the next one."""
        self._to_client.clear()
        if self.endpoint is None:
            return
        # Queued bytes sit in the terminal side's input queue, which only a descriptor of
        # that side can flush (tcflush on our side does not reach it).
        with contextlib.suppress(termios.error, OSError):
            fd = os.open(self.endpoint.device, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
            try:
                termios.tcflush(fd, termios.TCIFLUSH)
            finally:
                os.close(fd)

    def _close_upstream(self) -> None:
        sock, self._upstream = self._upstream, None
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            sock.close()

    def _close_master(self) -> None:
        master, self._master = self._master, None
        if master is not None:
            with contextlib.suppress(OSError):
                os.close(master)


def _make_symlink(path: Path, device: str, on_event: Callable[[str], None]) -> None:
    """Point ``path`` at ``device``, replacing only a symlink (a stale one from a crash)."""
    if path.is_symlink():
        on_event(f"replacing the existing symlink {path} -> {os.readlink(path)}")
    elif path.exists():
        kind = "directory" if path.is_dir() else "file"
        raise LinkPathError(
            f"{path} exists and is a {kind}, not a symlink: refusing to overwrite it. Give "
            f"another --link path, or remove it yourself if it is not needed."
        )
    if not path.parent.is_dir():
        raise LinkPathError(f"cannot create {path}: directory {path.parent} does not exist")
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with contextlib.suppress(FileNotFoundError):
            temporary.unlink()
        os.symlink(device, temporary)
        os.replace(temporary, path)  # atomic: a client never sees a missing or half link
    except OSError as exc:
        with contextlib.suppress(OSError):
            temporary.unlink()
        raise LinkPathError(f"cannot create the symlink {path}: {exc}") from exc


def _remove_symlink(path: Path, device: str) -> None:
    """Remove ``path`` if it is still our symlink (another bridge may have taken the name)."""
    with contextlib.suppress(OSError):
        if path.is_symlink() and os.readlink(path) == device:
            path.unlink()
