"""The Configurator bridge against a fake SITL TCP port: relay, one client at a time, errors."""

from __future__ import annotations

import contextlib
import socket
import urllib.error
import urllib.request

import pytest
from support.fake_sitl_port import API_VERSION_REPLY, FakeSitl, wait_until
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import connect

from bfsitl.bridges import Upstream
from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION, OriginPolicy
from bfsitl.bridges.websocket_relay import (
    CLOSE_BUSY,
    CLOSE_UPSTREAM_ERROR,
    CLOSE_UPSTREAM_GONE,
    WebSocketRelay,
    pick_subprotocol,
)
from bfsitl.errors import ListenAddressInUseError
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import encode_request

REQUEST = encode_request(MspCommand.API_VERSION)


@pytest.fixture
def fake_sitl():
    sitl = FakeSitl()
    yield sitl
    sitl.close()


def relay_for(sitl: FakeSitl, events: list[str] | None = None) -> WebSocketRelay:
    return WebSocketRelay(
        sitl.upstream, port=0, on_event=events.append if events is not None else None
    )


def closed_code(ws) -> tuple[int | None, str]:
    with pytest.raises(ConnectionClosed):
        ws.recv(timeout=3.0)
    return ws.close_code, ws.close_reason


@pytest.mark.parametrize("subprotocol", ["wsSerial", "binary"])
def test_msp_round_trip_with_each_subprotocol(fake_sitl, subprotocol):
    relay = relay_for(fake_sitl)
    with relay.running() as url, connect(url, subprotocols=[subprotocol]) as ws:
        assert url.startswith("ws://127.0.0.1:")
        assert ws.subprotocol == subprotocol
        ws.send(REQUEST)
        reply = b""
        while len(reply) < len(API_VERSION_REPLY):
            message = ws.recv(timeout=3.0)
            assert isinstance(message, bytes)  # always binary frames back
            reply += message
        assert reply == API_VERSION_REPLY


def test_text_frames_are_relayed_as_utf8_bytes(fake_sitl):
    relay = relay_for(fake_sitl)
    with relay.running() as url, connect(url, subprotocols=["binary"]) as ws:
        ws.send("#")
        wait_until(lambda: fake_sitl.received == b"#")


def test_second_client_is_refused_while_one_is_connected(fake_sitl):
    events: list[str] = []
    relay = relay_for(fake_sitl, events)
    with relay.running() as url:
        with connect(url, subprotocols=["binary"]) as first:
            first.send(REQUEST)
            first.recv(timeout=3.0)
            with connect(url, subprotocols=["binary"]) as second:
                code, reason = closed_code(second)
            assert code == CLOSE_BUSY and "another client" in reason
            first.send(REQUEST)  # the first client is not disturbed
            assert first.recv(timeout=3.0)
        wait_until(lambda: fake_sitl.closed_connections == 1)  # the SITL's slot is free again
        with connect(url, subprotocols=["binary"]) as third:
            third.send(REQUEST)
            assert third.recv(timeout=3.0)
    assert relay.refused_clients == 1
    assert fake_sitl.connections == 2
    assert any("refused" in e for e in events)


def test_client_without_subprotocol_is_served_and_foreign_one_refused(fake_sitl):
    relay = relay_for(fake_sitl)
    with relay.running() as url:
        with connect(url) as ws:
            ws.send(REQUEST)
            assert ws.recv(timeout=3.0)
        with pytest.raises(InvalidStatus) as refused:
            connect(url, subprotocols=["mqtt"])
        assert refused.value.response.status_code == 400


def test_pick_subprotocol_prefers_the_current_configurators_binary():
    assert pick_subprotocol(["binary"]) == "binary"  # Configurator 2026.6.1 and later
    assert pick_subprotocol(["wsSerial", "binary"]) == "binary"
    assert pick_subprotocol(["chat", "wsSerial"]) == "wsSerial"  # older builds
    assert pick_subprotocol([]) is None
    with pytest.raises(ValueError, match="binary or wsSerial"):
        pick_subprotocol(["chat"])


@pytest.mark.parametrize(
    "origin",
    [
        "https://evil.example",
        "http://127.0.0.1.evil.example",
        "https://app.betaflight.com.evil.example",
        "null",
    ],
)
def test_a_foreign_page_is_refused_before_a_byte_reaches_the_fc(fake_sitl, origin):
    """Cross-site WebSocket hijacking: a page in another tab must not drive the FC."""
    events: list[str] = []
    relay = relay_for(fake_sitl, events)
    with relay.running() as url, connect(url, subprotocols=["binary"], origin=origin) as ws:
        with contextlib.suppress(ConnectionClosed):
            ws.send(REQUEST)
        code, reason = closed_code(ws)
    assert code == CLOSE_POLICY_VIOLATION and "--allow-origin" in reason
    assert fake_sitl.connections == 0 and fake_sitl.received == b""
    assert relay.refused_origins == 1
    assert any(origin in e and "--allow-origin" in e for e in events)


@pytest.mark.parametrize(
    "origin",
    [
        None,
        "http://127.0.0.1:8000",
        "http://localhost:5173",
        "https://app.betaflight.com",
        "tauri://localhost",
    ],
)
def test_the_configurators_own_origins_and_scripts_are_served(fake_sitl, origin):
    relay = relay_for(fake_sitl)
    with relay.running() as url, connect(url, subprotocols=["binary"], origin=origin) as ws:
        ws.send(REQUEST)
        assert ws.recv(timeout=3.0)
    assert relay.refused_origins == 0


def test_allow_origin_adds_a_page(fake_sitl):
    relay = WebSocketRelay(
        fake_sitl.upstream, port=0, origins=OriginPolicy.with_extra(["https://My.Example:8443/"])
    )
    with relay.running() as url:
        with connect(url, subprotocols=["binary"], origin="https://my.example:8443") as ws:
            ws.send(REQUEST)
            assert ws.recv(timeout=3.0)
        with connect(url, subprotocols=["binary"], origin="https://my.example:9000") as ws:
            assert closed_code(ws)[0] == CLOSE_POLICY_VIOLATION


def test_taken_port_names_its_holder(fake_sitl):
    with socket.create_server(("127.0.0.1", 0)) as holder:
        port = holder.getsockname()[1]
        relay = WebSocketRelay(fake_sitl.upstream, port=port)
        with pytest.raises(ListenAddressInUseError, match=rf"tcp {port} held by pid \d+"):
            with relay.running():
                pass


def test_unreachable_sitl_closes_the_client_with_the_reason():
    with socket.create_server(("127.0.0.1", 0)) as placeholder:
        port = placeholder.getsockname()[1]
    events: list[str] = []
    relay = WebSocketRelay(Upstream("127.0.0.1", port), port=0, on_event=events.append)
    with relay.running() as url, connect(url, subprotocols=["binary"]) as ws:
        code, reason = closed_code(ws)
    assert code == CLOSE_UPSTREAM_ERROR and "connection refused" in reason
    assert any("Is the SITL running" in e for e in events)


def test_busy_sitl_closes_the_client_with_the_reason(fake_sitl):
    fake_sitl.other_client_present = True
    relay = relay_for(fake_sitl)
    with relay.running() as url, connect(url, subprotocols=["binary"]) as ws:
        code, reason = closed_code(ws)
    assert code == CLOSE_UPSTREAM_ERROR and "closed our connection" in reason


def test_sitl_closing_ends_the_client_and_the_next_one_reconnects(fake_sitl):
    relay = relay_for(fake_sitl)
    with relay.running() as url:
        with connect(url, subprotocols=["binary"]) as ws:
            ws.send(REQUEST)
            ws.recv(timeout=3.0)
            fake_sitl.drop_client()  # as when the SITL reboots
            code, reason = closed_code(ws)
        assert code == CLOSE_UPSTREAM_GONE and "reboot" in reason
        with connect(url, subprotocols=["binary"]) as ws:
            ws.send(REQUEST)
            assert ws.recv(timeout=3.0)
    assert relay.sessions[0].end_reason == "the SITL closed the connection"


def test_client_leaving_mid_frame_is_reported(fake_sitl):
    events: list[str] = []
    relay = relay_for(fake_sitl, events)
    with relay.running() as url:
        with connect(url, subprotocols=["binary"]) as ws:
            ws.send(b"$M<\x0a\x65\x01")
            wait_until(lambda: fake_sitl.received == b"$M<\x0a\x65\x01")
        wait_until(lambda: len(relay.sessions) == 1)
    assert relay.sessions[0].torn_frame_bytes == 6
    assert relay.sessions[0].bytes_to_fc == 6
    assert any("middle of an MSP frame" in e for e in events)


def test_stop_closes_connected_clients_cleanly(fake_sitl):
    relay = relay_for(fake_sitl)
    with contextlib.ExitStack() as stack:
        with relay.running() as url:
            ws = stack.enter_context(connect(url, subprotocols=["binary"]))
            ws.send(REQUEST)
            ws.recv(timeout=3.0)
        code, _reason = closed_code(ws)  # the client outlives the server
    assert code == 1001  # going away: the server shut down
    wait_until(lambda: fake_sitl.closed_connections == 1)


def test_plain_http_request_is_explained(fake_sitl):
    events: list[str] = []
    relay = relay_for(fake_sitl, events)
    with relay.running() as url:
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(url.replace("ws://", "http://"), timeout=3.0)
        refused.value.close()
    assert refused.value.code == 426
    assert any("not in the address bar" in e for e in events)


def test_a_taken_port_is_found_before_anything_starts_and_names_the_option():
    from bfsitl.bridges import check_listen_port

    with socket.create_server(("127.0.0.1", 0)) as holder:
        port = holder.getsockname()[1]
        with pytest.raises(ListenAddressInUseError, match="--configurator-port"):
            check_listen_port("127.0.0.1", port, "--configurator-port")
    check_listen_port("127.0.0.1", port, "--configurator-port")  # free again: no error
