"""What the bridge must do for the Configurator, checked with a client that speaks like the app
(``tests/support/configurator_client.py``, frames from ``tests/data/configurator/``) against a
fake SITL port: the app's subprotocol offer is served, its pages are served and foreign ones refused
before a byte reaches the FC, its frames pass byte for byte, and its way of reconnecting
(close the old socket, open the next at once) is served, not refused as busy."""

from __future__ import annotations

import socket
import threading

import pytest
from support.configurator_client import APP_ORIGIN, ConfiguratorLikeClient, frames
from support.fake_sitl_port import FakeSitl, wait_until
from websockets.exceptions import ConnectionClosed

from bfsitl.bridges import Upstream
from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION
from bfsitl.bridges.websocket_relay import WebSocketRelay
from bfsitl.protocol.msp_codes import MspCommand

API = next(step for step in frames()["connect"] if step["command"] == MspCommand.API_VERSION)


@pytest.fixture
def fake_sitl():
    sitl = FakeSitl()
    yield sitl
    sitl.close()


def test_the_apps_offer_is_served_with_binary_frames(fake_sitl) -> None:
    assert frames()["websocket"]["subprotocols"] == ["binary"]
    with WebSocketRelay(fake_sitl.upstream, port=0).running() as url:
        with ConfiguratorLikeClient(url) as app:
            assert app.subprotocol == "binary"
            reply = app.request(API["hex"], API["command"])
            assert reply.command == MspCommand.API_VERSION and not reply.error


@pytest.mark.parametrize("origin", [APP_ORIGIN, "http://localhost:8000", "http://127.0.0.1:5173"])
def test_the_apps_pages_are_served(fake_sitl, origin: str) -> None:
    with WebSocketRelay(fake_sitl.upstream, port=0).running() as url:
        with ConfiguratorLikeClient(url, origin=origin) as app:
            assert app.request(API["hex"], API["command"]).payload


def test_a_foreign_page_speaking_like_the_app_is_refused_before_the_fc_hears_it(fake_sitl) -> None:
    with WebSocketRelay(fake_sitl.upstream, port=0).running() as url:
        with ConfiguratorLikeClient(url, origin="https://evil.example") as page:
            assert page.ws is not None
            with pytest.raises(ConnectionClosed):
                page.ws.send(bytes.fromhex(API["hex"]))
                page.ws.recv(timeout=3.0)
            assert page.ws.close_code == CLOSE_POLICY_VIOLATION
    assert fake_sitl.received == b"" and fake_sitl.connections == 0


class _Sink:
    """A TCP port that keeps what it receives and answers nothing (v1 and v2 alike)."""

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.received = bytearray()
        threading.Thread(target=self._serve, daemon=True).start()

    @property
    def upstream(self) -> Upstream:
        return Upstream("127.0.0.1", self._server.getsockname()[1], busy_wait_s=0.3)

    def _serve(self) -> None:
        conn, _addr = self._server.accept()
        with conn:
            while chunk := conn.recv(4096):
                self.received += chunk

    def close(self) -> None:
        self._server.close()


def test_the_apps_frames_reach_the_fc_byte_for_byte() -> None:
    sink = _Sink()
    sent = b"".join(
        bytes.fromhex(step["hex"]) for step in frames()["connect"] + frames()["setup_tab_poll"]
    )
    try:
        with WebSocketRelay(sink.upstream, port=0).running() as url:
            with ConfiguratorLikeClient(url) as app:
                assert app.ws is not None
                for step in frames()["connect"] + frames()["setup_tab_poll"]:
                    app.ws.send(bytes.fromhex(step["hex"]))
                wait_until(lambda: len(sink.received) >= len(sent))
    finally:
        sink.close()
    assert bytes(sink.received) == sent
    assert sent.count(b"$X<") == 3  # the MSP v2 requests (MSP2_GET_TEXT) pass as they are


def test_reconnecting_as_the_app_does_is_served_not_refused(fake_sitl) -> None:
    """The app closes its old socket and opens the next without waiting: the bridge must let
    the new one wait for the old one's end instead of closing it as busy."""
    with WebSocketRelay(fake_sitl.upstream, port=0).running() as url:
        first = ConfiguratorLikeClient(url).open()
        assert first.request(API["hex"], API["command"]).payload
        closing = first.abandon()
        with ConfiguratorLikeClient(url) as second:
            assert second.request(API["hex"], API["command"], timeout_s=5.0).payload
        closing.join(timeout=5.0)
    assert fake_sitl.connections == 2
