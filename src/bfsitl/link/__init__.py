"""Transports picked by URI: ``tcp://HOST:PORT`` and ``serial:///dev/DEVICE?baud=N``.

The lockstep builds' shared-memory exchange (:mod:`bfsitl.link.shm_exchange`) is a transport
too, though for the fdm datagram rather than MSP: no URI picks it, the lockstep bridge does."""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

from bfsitl.errors import LinkError
from bfsitl.link.base import DEFAULT_TIMEOUT_S, Link
from bfsitl.link.serial_link import DEFAULT_BAUD, SerialLink
from bfsitl.link.tcp_link import SocketFactory, TcpLink

#: UART1 of a SITL on this machine.
DEFAULT_SITL_URI = "tcp://127.0.0.1:5761"

__all__ = [
    "DEFAULT_SITL_URI",
    "Link",
    "SerialLink",
    "SocketFactory",
    "TcpLink",
    "open_link",
]


def open_link(
    uri: str = DEFAULT_SITL_URI,
    *,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    socket_factory: SocketFactory | None = None,
) -> Link:
    """Open the transport a URI names.

    ``tcp://127.0.0.1:5761`` is the SITL's UART1; ``serial:///dev/ttyACM0?baud=115200`` a real
    board (``baud`` defaults to 115200).  ``socket_factory`` makes the TCP socket, which lets a
    caller connect inside an isolated SITL's network namespace.

    Args:
        uri: ``tcp://HOST:PORT`` or ``serial:///dev/DEVICE?baud=N``; the SITL's UART1 on this
            machine by default.
        timeout_s: Seconds a read waits for bytes (a TCP connection has 2 s to connect).
        socket_factory: Makes the TCP socket; None makes an ordinary one.

    Returns:
        The open link.

    Raises:
        LinkError: An unknown scheme or a malformed URI, or the connection or port cannot
            be opened (``LinkTimeoutError`` when nothing answers in time).
        ExtraMissingError: A serial URI without pyserial (``pip install 'bfsitl[serial]'``).
    """
    parts = urlsplit(uri)
    if parts.scheme == "tcp":
        if not parts.hostname or parts.port is None:
            raise LinkError(f"{uri!r}: a tcp URI needs a host and a port, e.g. {DEFAULT_SITL_URI}")
        return TcpLink(parts.hostname, parts.port, timeout_s, socket_factory=socket_factory)
    if parts.scheme == "serial":
        device = parts.path or parts.netloc
        if not device:
            raise LinkError(f"{uri!r}: a serial URI needs a device, e.g. serial:///dev/ttyACM0")
        query = parse_qs(parts.query)
        try:
            baud = int(query.get("baud", [DEFAULT_BAUD])[0])
        except ValueError as exc:
            raise LinkError(f"{uri!r}: baud must be an integer") from exc
        return SerialLink(device, baud, timeout_s)
    raise LinkError(
        f"{uri!r}: unknown link; use tcp://HOST:PORT (SITL, e.g. {DEFAULT_SITL_URI}) or "
        f"serial:///dev/ttyACM0?baud=115200 (real board)"
    )
