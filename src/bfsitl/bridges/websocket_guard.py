"""An Origin check in front of a WebSocket server that cannot check Origin itself.

The Foxglove SDK's WebSocket server (``foxglove.start_server``) accepts every ``Origin``: any
web page open in the user's browser could read the flight from it.  bfsitl's rule for every
WebSocket server it runs (:mod:`bfsitl.bridges.origin_policy`) is enforced here instead: the
SDK server listens on an ephemeral port of 127.0.0.1, and this guard listens on the port the
user is told about.  A client from an accepted origin gets a WebSocket to the server with the
subprotocol it asked for, and every message is passed on unchanged both ways; any other page is
closed with 1008 before a byte reaches the server.

What it does not close: the ephemeral port itself is reachable by anything on this machine
that finds it.  The server behind it is given no capabilities (clients cannot publish, set
parameters or call services), so what such a page could do is read flight telemetry.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Sequence
from typing import Any

from bfsitl.bridges.background import StoppableServer
from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION, OriginPolicy

LISTEN_HOST = "127.0.0.1"
#: What a closing handshake may take before the connection is dropped.
CLOSE_TIMEOUT_S = 2.0
#: Close code when the server behind the guard cannot be reached (RFC 6455: internal error).
CLOSE_UPSTREAM_ERROR = 1011


class OriginGuard(StoppableServer):
    """A WebSocket server on ``LISTEN_HOST:port`` passing accepted clients to ``upstream_url``.

    ``subprotocols`` are the ones the server behind speaks, in order of preference; a client
    must offer one of them.  ``port_option`` names the command-line option that changes the
    port, for the error when it is taken.
    """

    thread_name = "bfsitl-origin-guard"

    def __init__(
        self,
        upstream_url: str,
        *,
        port: int,
        subprotocols: Sequence[str],
        origins: OriginPolicy | None = None,
        on_event: Callable[[str], None] | None = None,
        port_option: str = "--port",
    ) -> None:
        super().__init__()
        self.upstream_url = upstream_url
        self.host = LISTEN_HOST
        self.port = port
        self.subprotocols = tuple(subprotocols)
        self.origins = origins or OriginPolicy()
        self.port_option = port_option
        self.refused_origins = 0
        self.clients_served = 0
        self._on_event = on_event or (lambda _line: None)

    async def serve(self, started: Callable[[str], None] | None = None) -> None:
        from websockets.asyncio.server import serve
        from websockets.typing import Subprotocol

        await self._serve_until_stopped(
            lambda: serve(
                self._handle,
                LISTEN_HOST,
                self.port,
                subprotocols=[Subprotocol(name) for name in self.subprotocols],
                compression=None,
                max_size=None,
                close_timeout=CLOSE_TIMEOUT_S,
            ),
            started,
        )

    async def _handle(self, connection: Any) -> None:
        from websockets.asyncio.client import connect

        request = connection.request
        origin = request.headers.get("Origin") if request is not None else None
        refusal = self.origins.refusal(origin)
        if refusal is not None:
            self.refused_origins += 1
            self._on_event(
                f"refused a client from {origin}: not an allowed page; if it is "
                f"yours, restart with --allow-origin {origin}"
            )
            await connection.close(CLOSE_POLICY_VIOLATION, refusal)
            return
        protocols = [connection.subprotocol] if connection.subprotocol else None
        try:
            upstream = await connect(
                self.upstream_url,
                subprotocols=protocols,
                compression=None,
                max_size=None,
                close_timeout=CLOSE_TIMEOUT_S,
            )
        except (OSError, Exception) as exc:  # noqa: BLE001 - any failure closes the client
            self._on_event(f"the server behind the guard is not reachable: {exc}")
            await connection.close(CLOSE_UPSTREAM_ERROR, "server not reachable")
            return
        self.clients_served += 1
        self._on_event(f"client {origin or 'without Origin'} connected")
        async with upstream:
            await _pass_both_ways(connection, upstream)


async def _pass_both_ways(client: Any, server: Any) -> None:
    """Copy messages each way until one side closes; then close the other with its code."""
    from websockets.exceptions import ConnectionClosed

    async def copy(source: Any, target: Any) -> None:
        with contextlib.suppress(ConnectionClosed):
            async for message in source:
                await target.send(message)

    to_server = asyncio.create_task(copy(client, server))
    to_client = asyncio.create_task(copy(server, client))
    done, pending = await asyncio.wait({to_server, to_client}, return_when=asyncio.FIRST_COMPLETED)
    for task in pending:
        task.cancel()
    await asyncio.gather(*pending, return_exceptions=True)
    ended, other = (client, server) if to_server in done else (server, client)
    code = ended.close_code if ended.close_code not in (None, 1005, 1006) else 1000
    with contextlib.suppress(Exception):
        await other.close(code, ended.close_reason or "")
