"""TCP transport: the SITL exposes UART1 on TCP 5761 (UART2 on 5762, ...)."""

from __future__ import annotations

import errno
import select
import socket
from collections.abc import Callable

from bfsitl.errors import LinkError, LinkTimeoutError
from bfsitl.link.base import DEFAULT_TIMEOUT_S, Link

#: Makes an unconnected socket; an isolated SITL's namespace hands out sockets this way.
SocketFactory = Callable[[int, int], socket.socket]


def _default_socket_factory(family: int, kind: int) -> socket.socket:
    return socket.socket(family, kind)


def connect_tcp(
    host: str,
    port: int,
    *,
    connect_timeout_s: float,
    socket_factory: SocketFactory | None = None,
    hint: str = "Start one with `bfsitl status --start`.",
) -> socket.socket:
    """A connected TCP socket with Nagle off, or a :class:`LinkError` that says why.

    ``socket_factory`` makes the socket (an isolated SITL's namespace provides one); ``hint``
    ends the "connection refused" message with what the caller's user can do about it.  The
    socket is left with the connect timeout set: the caller chooses its blocking mode.
    """
    uri = f"tcp://{host}:{port}"
    factory = socket_factory or _default_socket_factory
    sock = factory(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.settimeout(connect_timeout_s)
        sock.connect((host, port))
        # MSP frames are tiny; Nagle would hold a request back for an ACK.
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    except TimeoutError as exc:
        sock.close()
        raise LinkTimeoutError(f"{uri}: no answer to connect within {connect_timeout_s} s") from exc
    except OSError as exc:
        sock.close()
        if exc.errno == errno.ECONNREFUSED:
            raise LinkError(
                f"{uri}: connection refused: nothing listens there. Is the SITL running (in "
                f"this network namespace)? {hint}"
            ) from exc
        raise LinkError(f"{uri}: cannot connect: {exc}") from exc
    return sock


class TcpLink(Link):
    """A TCP connection to a SITL UART (or any MSP-over-TCP bridge)."""

    #: The SITL's TCP thread flushes replies when it reads (see ``bfsitl.fc.msp_client``).
    wants_wake_bytes = True

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 5761,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        connect_timeout_s: float = 2.0,
        socket_factory: SocketFactory | None = None,
    ) -> None:
        super().__init__(f"tcp://{host}:{port}", timeout_s)
        self.host = host
        self.port = port
        sock = connect_tcp(
            host, port, connect_timeout_s=connect_timeout_s, socket_factory=socket_factory
        )
        sock.setblocking(False)
        self._sock = sock

    def _write_bytes(self, data: bytes) -> None:
        view = memoryview(data)
        while view:
            try:
                sent = self._sock.send(view)
            except BlockingIOError:
                _, writable, _ = select.select([], [self._sock], [], self.timeout_s)
                if not writable:
                    raise TimeoutError from None
                continue
            view = view[sent:]

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        # A zero timeout is a poll (a lockstep link makes one per simulation step): the
        # socket is non-blocking, so recv alone answers it, without a select() call.
        if timeout_s > 0:
            readable, _, _ = select.select([self._sock], [], [], timeout_s)
            if not readable:
                return b""
        try:
            data = self._sock.recv(max_bytes)
        except BlockingIOError:
            return b""
        return data if data else None

    @property
    def readable_fd(self) -> int:
        return self._sock.fileno()

    def _close(self) -> None:
        try:
            self._sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass
        self._sock.close()
