"""The Origin rule every bfsitl WebSocket server follows, and the guard that adds it to one
that cannot check Origin itself (the Foxglove SDK's)."""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections.abc import Iterator

import pytest
from websockets.asyncio.server import serve
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION, OriginPolicy, normalise_origin
from bfsitl.bridges.websocket_guard import CLOSE_UPSTREAM_ERROR, OriginGuard
from bfsitl.errors import BridgeError


@pytest.mark.parametrize(
    "origin",
    [
        None,  # not a browser
        "http://127.0.0.1:8000",
        "http://localhost:5173",
        "https://localhost",
        "http://[::1]:80",
        "https://app.betaflight.com",
        "https://master.app.betaflight.com",
        "tauri://localhost",
        "http://tauri.localhost",
        "capacitor://localhost",
        "chrome-extension://abcdefghijklmnop",
        "https://app.foxglove.dev",
        "HTTP://LOCALHOST:9",
    ],
)
def test_the_configurators_and_foxgloves_pages_are_accepted(origin):
    assert OriginPolicy().refusal(origin) is None


@pytest.mark.parametrize(
    "origin",
    [
        "https://evil.example",
        "null",
        "file://",
        "http://127.0.0.1.nip.io",
        "https://app.betaflight.com.evil.example",
        "https://evilapp.betaflight.com",
        "ftp://localhost",
        "https://foxglove.dev.evil.example",
        "",
    ],
)
def test_other_pages_are_refused_with_a_reason_that_fits_a_close_frame(origin):
    reason = OriginPolicy().refusal(origin)
    assert reason is not None and "--allow-origin" in reason
    assert len(reason.encode()) <= 123


def test_allow_origin_adds_exact_origins_or_everything():
    policy = OriginPolicy.with_extra(["https://Viewer.Example:8443/"])
    assert policy.accepts("https://viewer.example:8443")
    assert not policy.accepts("https://viewer.example:8444")
    assert not policy.accepts("http://viewer.example:8443")
    assert OriginPolicy.with_extra(["*"]).accepts("https://anything.example")


@pytest.mark.parametrize(
    "bad", ["viewer.example", "https://viewer.example/path", "https://", "https://x.example/?q=1"]
)
def test_a_mistyped_allow_origin_is_an_error_at_start(bad):
    with pytest.raises(BridgeError, match="--allow-origin"):
        normalise_origin(bad)


@contextlib.contextmanager
def echo_server(subprotocol: str = "demo.v1") -> Iterator[str]:
    """An upstream that echoes every message and closes with 4000 on the text "bye"."""
    ready = threading.Event()
    stop: list[asyncio.Event] = []
    url: list[str] = []

    async def handler(connection) -> None:  # type: ignore[no-untyped-def]
        async for message in connection:
            if message == "bye":
                await connection.close(4000, "upstream says bye")
                return
            await connection.send(message)

    async def main() -> None:
        stop.append(asyncio.Event())
        async with serve(handler, "127.0.0.1", 0, subprotocols=[subprotocol]) as server:  # type: ignore[list-item]
            url.append(f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}")
            ready.set()
            await stop[0].wait()

    loop = asyncio.new_event_loop()
    thread = threading.Thread(target=loop.run_until_complete, args=(main(),), daemon=True)
    thread.start()
    assert ready.wait(5)
    try:
        yield url[0]
    finally:
        loop.call_soon_threadsafe(stop[0].set)
        thread.join(5)


def test_an_allowed_client_talks_to_the_server_behind_in_both_directions():
    with echo_server() as upstream:
        guard = OriginGuard(upstream, port=0, subprotocols=["demo.v1"])
        with (
            guard.running() as url,
            connect(url, subprotocols=["demo.v1"], origin="http://localhost:3000") as ws,
        ):
            assert ws.subprotocol == "demo.v1"
            ws.send(b"\x01\x02binary")
            assert ws.recv(timeout=3) == b"\x01\x02binary"
            ws.send("text")
            assert ws.recv(timeout=3) == "text"
            ws.send("bye")  # the server's close reaches the client with its code
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=3)
            assert ws.close_code == 4000
    assert guard.clients_served == 1


def test_a_foreign_page_never_reaches_the_server_behind():
    events: list[str] = []
    with echo_server() as upstream:
        guard = OriginGuard(upstream, port=0, subprotocols=["demo.v1"], on_event=events.append)
        with (
            guard.running() as url,
            connect(url, subprotocols=["demo.v1"], origin="https://evil.example") as ws,
        ):
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=3)
            assert ws.close_code == CLOSE_POLICY_VIOLATION
    assert guard.clients_served == 0 and guard.refused_origins == 1
    assert any("https://evil.example" in line for line in events)


def test_a_server_behind_that_is_gone_closes_the_client_with_a_reason():
    with echo_server() as upstream:
        pass  # stopped: nothing listens there any more
    guard = OriginGuard(upstream, port=0, subprotocols=["demo.v1"])
    with guard.running() as url, connect(url, subprotocols=["demo.v1"]) as ws:
        with pytest.raises(ConnectionClosed):
            ws.recv(timeout=5)
        assert ws.close_code == CLOSE_UPSTREAM_ERROR
