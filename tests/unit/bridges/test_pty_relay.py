"""The virtual serial port against a fake SITL TCP port: relay, clients coming and going, errors.

The fake does what the bridge depends on (``drivers/serial_tcp.c``): one client at a time, a
second one accepted and closed at once, MSP_API_VERSION answered.  The real SITL runs the same
paths in tests/integration/test_serial_parity.py.
"""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path

import pytest
import serial  # type: ignore[import-untyped]
from support.fake_sitl_port import API_VERSION_REPLY, FakeSitl, wait_until

from bfsitl.bridges import Upstream
from bfsitl.bridges.pty_relay import PtyRelay
from bfsitl.errors import LinkPathError, MspErrorReply
from bfsitl.fc.msp_client import MspClient
from bfsitl.link import open_link
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import encode_request


@pytest.fixture
def fake_sitl():
    sitl = FakeSitl()
    yield sitl
    sitl.close()


def read_available(fd: int) -> bytes:
    """What a non-blocking read finds (raw mode with VMIN=0 answers b"" when empty)."""
    try:
        return os.read(fd, 4096)
    except BlockingIOError:
        return b""


def api_version_over_pyserial(path: str) -> bytes:
    with serial.Serial(path, 115200, timeout=2.0) as port:
        port.write(encode_request(MspCommand.API_VERSION))
        return port.read(len(API_VERSION_REPLY))


def test_msp_through_symlink_and_symlink_removed_on_close(fake_sitl, tmp_path):
    link = tmp_path / "ttyBF"
    events: list[str] = []
    relay = PtyRelay(fake_sitl.upstream, link_path=link, on_event=events.append)
    with relay.running() as endpoint:
        assert link.is_symlink() and os.readlink(link) == endpoint.device
        assert endpoint.uri == f"serial://{link}"
        assert api_version_over_pyserial(str(link)) == API_VERSION_REPLY
    assert not link.exists() and not link.is_symlink()
    wait_until(lambda: fake_sitl.closed_connections == 1)
    assert [s.bytes_to_client for s in relay.sessions] == [len(API_VERSION_REPLY)]


def test_our_serial_link_and_msp_client_run_through_the_pty(fake_sitl, tmp_path):
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc")
    with relay.running() as endpoint:
        with MspClient(open_link(endpoint.uri, timeout_s=2.0), timeout_s=2.0) as client:
            assert client.api_version().api == (1, 47)
            # An error frame ('!') comes back through the relay as well.
            with pytest.raises(MspErrorReply):
                client.request(MspCommand.STATUS)


def test_each_client_gets_its_own_connection_and_no_stale_bytes(fake_sitl, tmp_path):
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc")
    with relay.running() as endpoint:
        # The first client asks and leaves without reading its answer.
        with serial.Serial(endpoint.path, timeout=1.0) as port:
            port.write(encode_request(MspCommand.API_VERSION))
            wait_until(lambda: len(relay.sessions) == 0 and fake_sitl.connections == 1)
            time.sleep(0.2)  # the reply is queued in the pty by now
        wait_until(lambda: fake_sitl.closed_connections == 1)  # the SITL slot was freed
        # A raw open, since pyserial empties the input queue itself when it opens a port.
        fd = os.open(endpoint.path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            time.sleep(0.1)
            assert read_available(fd) == b""  # the first client's reply was thrown away
        finally:
            os.close(fd)
        with serial.Serial(endpoint.path, timeout=2.0) as port:
            port.write(encode_request(MspCommand.API_VERSION))
            assert port.read(len(API_VERSION_REPLY)) == API_VERSION_REPLY
    assert fake_sitl.connections == 2
    assert relay.sessions[0].bytes_to_client == len(API_VERSION_REPLY)


def test_reconnects_after_the_sitl_closed_the_connection(fake_sitl, tmp_path):
    events: list[str] = []
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc", on_event=events.append)
    with relay.running() as endpoint, serial.Serial(endpoint.path, timeout=2.0) as port:
        port.write(encode_request(MspCommand.API_VERSION))
        assert port.read(len(API_VERSION_REPLY)) == API_VERSION_REPLY
        fake_sitl.drop_client()  # as when the SITL reboots
        wait_until(lambda: any("closed the connection" in e for e in events))
        port.write(encode_request(MspCommand.API_VERSION))
        assert port.read(len(API_VERSION_REPLY)) == API_VERSION_REPLY
    assert fake_sitl.connections == 2


def test_busy_sitl_is_reported_and_bytes_dropped(fake_sitl, tmp_path):
    fake_sitl.other_client_present = True
    events: list[str] = []
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc", on_event=events.append)
    with relay.running() as endpoint, serial.Serial(endpoint.path, timeout=0.2) as port:
        port.write(encode_request(MspCommand.API_VERSION))
        wait_until(lambda: any("another client holds its UART" in e for e in events))
        assert port.read(16) == b""
    assert fake_sitl.received == b""


def test_unreachable_sitl_is_reported(tmp_path):
    with socket.create_server(("127.0.0.1", 0)) as placeholder:
        port = placeholder.getsockname()[1]
    events: list[str] = []
    relay = PtyRelay(Upstream("127.0.0.1", port), link_path=tmp_path / "fc", on_event=events.append)
    with relay.running() as endpoint, serial.Serial(endpoint.path, timeout=0.2) as port_:
        port_.write(b"$M<\x00\x01\x01")
        wait_until(lambda: any("connection refused" in e for e in events))


def test_client_leaving_mid_frame_is_reported(fake_sitl, tmp_path):
    events: list[str] = []
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc", on_event=events.append)
    with relay.running() as endpoint:
        with serial.Serial(endpoint.path, timeout=0.5) as port:
            port.write(encode_request(MspCommand.API_VERSION))
            port.read(len(API_VERSION_REPLY))
            port.write(b"$M<\x0a\x65\x01\x02")  # a 10-byte payload announced, 2 sent
            wait_until(lambda: fake_sitl.received.endswith(b"\x01\x02"))
        wait_until(lambda: len(relay.sessions) == 1)
    assert relay.sessions[0].torn_frame_bytes == 7
    assert any("middle of an MSP frame" in e for e in events)


def test_refuses_to_overwrite_a_regular_file(fake_sitl, tmp_path):
    target = tmp_path / "precious"
    target.write_text("keep me")
    with pytest.raises(LinkPathError, match="not a symlink: refusing to overwrite"):
        PtyRelay(fake_sitl.upstream, link_path=target).open()
    assert target.read_text() == "keep me"


def test_missing_directory_is_a_clear_error(fake_sitl, tmp_path):
    with pytest.raises(LinkPathError, match="does not exist"):
        PtyRelay(fake_sitl.upstream, link_path=tmp_path / "nope" / "fc").open()


def test_replaces_a_stale_symlink_and_leaves_a_foreign_one(fake_sitl, tmp_path):
    link = tmp_path / "fc"
    link.symlink_to("/dev/pts/does-not-exist")
    events: list[str] = []
    relay = PtyRelay(fake_sitl.upstream, link_path=link, on_event=events.append)
    endpoint = relay.open()
    try:
        assert os.readlink(link) == endpoint.device
        assert any("replacing the existing symlink" in e for e in events)
        # Someone else re-points the name while we run: closing must not delete theirs.
        link.unlink()
        link.symlink_to("/dev/null")
    finally:
        relay.close()
    assert os.readlink(link) == "/dev/null"


def test_pty_is_raw(fake_sitl, tmp_path):
    """Binary bytes pass unchanged both ways: no echo, no CR/LF mapping, no ^C signal."""
    relay = PtyRelay(fake_sitl.upstream, link_path=tmp_path / "fc")
    awkward = bytes(range(256))
    with relay.running() as endpoint:
        fd = os.open(endpoint.path, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, awkward)
            wait_until(lambda: fake_sitl.received == awkward)
        finally:
            os.close(fd)
    assert Path(endpoint.device).name.isdigit()
