"""WebSocket to SITL TCP relay, for the web Betaflight Configurator's manual connection.

The web Configurator cannot open TCP sockets.  Since its 2026.6.1 release the browser opens the
WebSocket with the single subprotocol ``binary`` (as the websockify family does); older builds
offered ``wsSerial``, which is still accepted.  This server carries the bytes of binary (or
text) messages unchanged to a SITL UART serving MSP (UART1 on TCP 5761, or the second MSP port
on 5762 during a flight) and sends what the SITL answers back as binary messages.

Why it is built this way:

* The SITL serves one TCP client per UART, so the bridge serves one WebSocket client at a
  time: a second one is accepted and closed at once with code 1013 ("try again later") and a
  reason a browser can read, instead of silently losing the FC to the first one.
* The TCP connection is opened per WebSocket client and closed when it leaves: the SITL closes
  connections idle for 120 s and exits on every reboot, so a connection held across clients
  would go stale.  Closing it also frees the SITL's slot for any other tool.
* The WebSocket server listens on the host while the TCP connection may be made inside an
  isolated SITL's network namespace (:attr:`Upstream.socket_factory`), so a browser on the
  host reaches a SITL that nothing else on the host can see.
* Any web page can open a WebSocket to 127.0.0.1, so without a check a page in another tab
  could send CLI commands and ``save`` them (cross-site WebSocket hijacking).  Browsers always
  send the page's ``Origin``: clients from an origin :class:`OriginPolicy` does not accept are
  closed at once with code 1008, before a byte reaches the FC.
* asyncio from the maintained ``websockets`` library: one thread, no hand-written handshake,
  and Ctrl-C (cancellation) closes every connection with a proper close frame.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from bfsitl.bridges import RequestWatch, SessionStats, Upstream, connect_upstream
from bfsitl.bridges.background import StoppableServer
from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION, OriginPolicy
from bfsitl.errors import BfsitlError, ExtraMissingError, UpstreamBusyError

if TYPE_CHECKING:
    from websockets.asyncio.server import ServerConnection

#: The port the Configurator examples use; any free port works.
DEFAULT_PORT = 6761
LISTEN_HOST = "127.0.0.1"
#: Subprotocols accepted, in the order of preference when a client offers several: the
#: Configurator's current one first, then what builds before 2026.6.1 offered.
SUBPROTOCOLS: tuple[str, ...] = ("binary", "wsSerial")
#: No FC exchange comes near this; a larger message is a client bug, not MSP.
MAX_MESSAGE_BYTES = 64 * 1024
_READ_CHUNK_BYTES = 4096
#: How long a closing handshake may take; a local client answers at once, and Ctrl-C should
#: not wait the library's default 10 s for one that does not.
CLOSE_TIMEOUT_S = 2.0

# Close codes (RFC 6455 section 7.4.1); reasons must fit 123 bytes.
CLOSE_BUSY = 1013  # try again later: another client holds the bridge
#: How long a new client waits for the previous one's connection to finish closing before it
#: is refused as a second client.
_HANDOVER_WAIT_S = 1.0
_HANDOVER_POLL_S = 0.02
CLOSE_UPSTREAM_GONE = 1001  # going away: the SITL closed the TCP connection
CLOSE_UPSTREAM_ERROR = 1011  # the SITL could not be reached

_BUSY_REASON = "busy: another client is connected to this bridge (the SITL serves one)"
_SITL_CLOSED_REASON = "the SITL closed the connection (reboot, exit, or 120 s idle)"


def _import_websockets():  # type: ignore[no-untyped-def]
    try:
        from websockets.asyncio import server
        from websockets.exceptions import ConnectionClosed, NegotiationError
    except ImportError as exc:
        raise ExtraMissingError(
            "the Configurator bridge needs websockets: pip install 'bfsitl[bridge]'"
        ) from exc
    return server, ConnectionClosed, NegotiationError


def connect_hint(url: str) -> str:
    """What to do in the Configurator (2026.12) to reach ``url``: its manual entries, the
    built-in "Betaflight SITL" one included, appear only with Expert Mode on."""
    if url == f"ws://{LISTEN_HOST}:{DEFAULT_PORT}":
        return (
            'in the Configurator: Options > Expert Mode on; Connect menu > "Betaflight '
            'SITL" (this URL; it connects at once)'
        )
    return (
        'in the Configurator: Options > Expert Mode on; Connect menu > "Manual '
        'Selection", this URL in the Port field, then Connect'
    )


def pick_subprotocol(offered: Sequence[str]) -> str | None:
    """The subprotocol to answer: the first one we accept in the client's order of preference.

    A client that offers none (``websocat``, a quick script) is served without one; a client
    that offers only others is refused, since it expects a protocol we do not speak.
    """
    for name in SUBPROTOCOLS:
        if name in offered:
            return name
    if offered:
        raise ValueError(
            f"client offered subprotocols {', '.join(offered)}; this bridge speaks "
            f"{' or '.join(SUBPROTOCOLS)} (raw serial bytes)"
        )
    return None


class WebSocketRelay(StoppableServer):
    """A WebSocket server on ``LISTEN_HOST:port`` relaying each client to the SITL's UART.

    ``port=0`` picks a free port (tests); :attr:`url` is known once the server listens.
    ``origins`` decides which web pages may connect (default: the Configurator's own).
    ``on_event`` receives one line per noteworthy event (client in and out, refusals,
    warnings); :attr:`sessions` keeps the statistics of every finished client.
    """

    thread_name = "bfsitl-ws-relay"

    def __init__(
        self,
        upstream: Upstream,
        *,
        port: int = DEFAULT_PORT,
        host: str = LISTEN_HOST,
        origins: OriginPolicy | None = None,
        on_event: Callable[[str], None] | None = None,
        port_option: str = "--port",
    ) -> None:
        _import_websockets()  # fail now, with the install hint, not at the first client
        super().__init__()
        self.upstream = upstream
        self.origins = origins or OriginPolicy()
        self.port_option = port_option
        self.host = host
        self.port = port
        self.sessions: list[SessionStats] = []
        self.refused_clients = 0
        self.refused_origins = 0
        self._on_event = on_event or (lambda _line: None)
        self._active: SessionStats | None = None

    # -- serving ---------------------------------------------------------------------------
    async def serve(self, started: Callable[[str], None] | None = None) -> None:
        """Serve until :meth:`stop` or cancellation (Ctrl-C); closes every client on the way out.

        Raises :class:`ListenAddressInUseError` when the port is taken.
        """
        server_module, _closed, negotiation_error = _import_websockets()

        def select_subprotocol(_connection: object, offered: Sequence[str]) -> str | None:
            try:
                return pick_subprotocol(offered)
            except ValueError as exc:
                self._on_event(f"refused a client: {exc}")
                raise negotiation_error(str(exc)) from None

        def note_plain_http(_connection: object, request) -> None:  # type: ignore[no-untyped-def]
            # websockets answers 426 by itself; say why, since it is usually a browser tab.
            if request.headers.get("Upgrade", "").lower() != "websocket":
                self._on_event(
                    f"a plain HTTP request for {request.path} was refused: this is a "
                    f"WebSocket server; enter {self.url} in the Configurator's "
                    f"manual connection, not in the address bar"
                )

        await self._serve_until_stopped(
            lambda: server_module.serve(
                self._handle,
                self.host,
                self.port,
                subprotocols=list(SUBPROTOCOLS),
                select_subprotocol=select_subprotocol,
                compression=None,
                max_size=MAX_MESSAGE_BYTES,
                process_request=note_plain_http,
                close_timeout=CLOSE_TIMEOUT_S,
            ),
            started,
        )

    # -- one client ------------------------------------------------------------------------
    async def _handle(self, connection: ServerConnection) -> None:
        host, port = connection.remote_address[:2]
        request = connection.request  # set once the handshake is done, as it is here
        origin_header = request.headers.get("Origin") if request is not None else None
        origin = origin_header or "no Origin header"
        client = f"{host}:{port}"
        refusal = self.origins.refusal(origin_header)
        if refusal is not None:
            # Checked before the one-client rule: a foreign page must not even learn whether
            # the FC is busy, nor take the slot from the Configurator.
            self.refused_origins += 1
            self._on_event(
                f"refused {client}: the page at {origin} is not allowed to drive "
                f"the FC (cross-site WebSocket); if it is yours, restart with "
                f"--allow-origin {origin}"
            )
            await connection.close(CLOSE_POLICY_VIOLATION, refusal)
            return
        # A client that reconnects at once (a page reload) can arrive before the relay has
        # finished with its previous connection: give that one a moment to end.
        waited_s = 0.0
        while self._active is not None and waited_s < _HANDOVER_WAIT_S:
            await asyncio.sleep(_HANDOVER_POLL_S)
            waited_s += _HANDOVER_POLL_S
        if self._active is not None:
            self.refused_clients += 1
            self._on_event(
                f"refused {client} ({origin}): {self._active.client} is connected, "
                f"and the SITL serves one client at a time"
            )
            await connection.close(CLOSE_BUSY, _BUSY_REASON)
            return
        session = SessionStats(client, time.monotonic())
        self._active = session  # set before any await: a second client sees it
        self._on_event(
            f"client {client} connected ({origin}, subprotocol {connection.subprotocol or 'none'})"
        )
        try:
            await self._relay(connection, session)
        finally:
            session.ended_s = time.monotonic()
            self.sessions.append(session)
            self._active = None
            self._on_event(session.summary())

    async def _relay(self, connection: ServerConnection, session: SessionStats) -> None:
        try:
            sock = await asyncio.to_thread(connect_upstream, self.upstream)
        except (BfsitlError, OSError) as exc:  # also a SITL that failed to restart
            busy = isinstance(exc, UpstreamBusyError)
            session.end_reason = "SITL busy" if busy else "SITL not reachable"
            self._on_event(str(exc))
            await connection.close(CLOSE_UPSTREAM_ERROR, _short_reason(exc))
            return
        sock.setblocking(False)
        reader, writer = await asyncio.open_connection(sock=sock)
        watch = RequestWatch()
        to_fc = asyncio.create_task(self._client_to_fc(connection, writer, watch, session))
        to_client = asyncio.create_task(self._fc_to_client(connection, reader, session))
        try:
            done, _pending = await asyncio.wait(
                {to_fc, to_client}, return_when=asyncio.FIRST_COMPLETED
            )
            first = done.pop()
            ended = first.result() if not first.cancelled() else _Ended("bridge stopping")
        finally:
            for task in (to_fc, to_client):
                task.cancel()
            await asyncio.gather(to_fc, to_client, return_exceptions=True)
            writer.close()  # frees the SITL's only client slot for the next one
            with contextlib.suppress(OSError):
                await writer.wait_closed()
        session.end_reason = ended.reason
        session.torn_frame_bytes = watch.torn_frame_bytes
        if ended.by_sitl:
            await connection.close(CLOSE_UPSTREAM_GONE, _SITL_CLOSED_REASON)

    async def _client_to_fc(
        self,
        connection: ServerConnection,
        writer: asyncio.StreamWriter,
        watch: RequestWatch,
        session: SessionStats,
    ) -> _Ended:
        _server, connection_closed, _negotiation = _import_websockets()
        try:
            async for message in connection:
                data = message.encode("utf-8") if isinstance(message, str) else bytes(message)
                for warning in watch.feed(data):
                    self._on_event(f"{session.client}: {warning}")
                writer.write(data)
                await writer.drain()
                session.bytes_to_fc += len(data)
        except connection_closed as exc:
            return _Ended(f"client connection lost: {exc}")
        except OSError as exc:
            return _Ended(f"writing to the SITL failed: {exc}", by_sitl=True)
        return _Ended("client closed")

    async def _fc_to_client(
        self,
        connection: ServerConnection,
        reader: asyncio.StreamReader,
        session: SessionStats,
    ) -> _Ended:
        _server, connection_closed, _negotiation = _import_websockets()
        try:
            while chunk := await reader.read(_READ_CHUNK_BYTES):
                await connection.send(chunk)
                session.bytes_to_client += len(chunk)
        except connection_closed as exc:
            return _Ended(f"client connection lost: {exc}")
        except OSError as exc:
            return _Ended(f"the SITL connection failed: {exc}", by_sitl=True)
        return _Ended("the SITL closed the connection", by_sitl=True)


@dataclass(frozen=True, slots=True)
class _Ended:
    """Why one direction of a relay stopped, and whether the SITL's side ended it."""

    reason: str
    by_sitl: bool = False


def _short_reason(exc: BaseException) -> str:
    """A close reason (at most 123 UTF-8 bytes): the first sentence of the error."""
    text = str(exc).split(". ")[0]
    encoded = text.encode("utf-8")
    if len(encoded) <= 123:
        return text
    return encoded[:120].decode("utf-8", "ignore") + "..."
