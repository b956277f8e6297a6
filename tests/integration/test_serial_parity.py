"""Real-board parity: the real SITL behind ``bfsitl serial-bridge``'s pty, as a board on a UART.

What a real board offers is a serial device.  These tests reach a real 4.6.0 SITL (in its own
network namespace) through the pty the way board tools do: pyserial with raw MSP and CLI
bytes, and our own ``serial://`` link with MspClient, CliSession and MspRcLink, and check
that ``serial://`` gives the same answers as ``tcp://``.  No UDP RC link is started: the first
UDP rc packet would permanently replace MSP as the SITL's RC source.
"""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
import serial  # type: ignore[import-untyped]

from bfsitl.bridges.pty_relay import PtyEndpoint, PtyRelay
from bfsitl.cli.bridge_commands import sitl_upstream
from bfsitl.fc.cli_session import CliSession
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.rc_link import MspRcLink, RcCommand
from bfsitl.link import Link, SerialLink, open_link
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame, MspParser, encode_request
from bfsitl.sitl.process import SitlProcess

pytestmark = pytest.mark.sitl

#: The 4.6.0 default (``imu.c``), read through the CLI.
SMALL_ANGLE_DEFAULT = "25"


@pytest.fixture
def sitl_behind_pty(firmware, tmp_path) -> Iterator[tuple[SitlProcess, PtyEndpoint]]:
    sitl = SitlProcess(firmware, workdir=tmp_path / "run", isolate=True)
    sitl.start()
    try:
        relay = PtyRelay(sitl_upstream(sitl), link_path=tmp_path / "ttyBF")
        with relay.running() as endpoint:
            yield sitl, endpoint
    finally:
        sitl.stop()


def read_until(port: serial.Serial, needle: bytes, timeout_s: float = 3.0) -> bytes:
    deadline = time.monotonic() + timeout_s
    data = bytearray()
    while needle not in data:
        if time.monotonic() > deadline:
            raise AssertionError(f"no {needle!r} within {timeout_s} s; got {bytes(data)!r}")
        data += port.read(max(1, port.in_waiting))
    return bytes(data)


def read_frame(port: serial.Serial, timeout_s: float = 3.0) -> MspFrame:
    parser = MspParser()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for event in parser.feed(port.read(max(1, port.in_waiting))):
            if isinstance(event, MspFrame):
                return event
    raise AssertionError(f"no MSP frame within {timeout_s} s")


def test_pyserial_msp_api_version(sitl_behind_pty):
    _sitl, endpoint = sitl_behind_pty
    with serial.Serial(endpoint.path, 115200, timeout=0.1) as port:
        port.write(encode_request(MspCommand.API_VERSION))
        frame = read_frame(port)
    assert frame.command == MspCommand.API_VERSION and not frame.is_error
    assert msg.ApiVersion.decode(frame.payload).api == (1, 47)


def test_pyserial_cli_get_and_back_to_msp(sitl_behind_pty):
    _sitl, endpoint = sitl_behind_pty
    with serial.Serial(endpoint.path, 115200, timeout=0.1) as port:
        port.write(b"#")
        time.sleep(0.15)  # the FC enters the CLI after a lone '#' and 100 ms of silence
        assert b"Entering CLI Mode" in read_until(port, b"\r\n# ")
        port.write(b"get small_angle\r")
        output = read_until(port, b"\r\n# ").decode("ascii", "replace")
        assert f"small_angle = {SMALL_ANGLE_DEFAULT}" in output
        port.write(b"exit noreboot\r")
        read_until(port, b"leaving CLI mode")
        time.sleep(0.1)
        port.reset_input_buffer()
        port.write(encode_request(MspCommand.API_VERSION))
        assert msg.ApiVersion.decode(read_frame(port).payload).api == (1, 47)


def _open(transport: str, sitl: SitlProcess, endpoint: PtyEndpoint) -> Link:
    if transport == "tcp":
        assert sitl.network is not None
        return open_link(sitl.uri, timeout_s=1.0, socket_factory=sitl.network.socket)
    return open_link(endpoint.uri, timeout_s=1.0)


def _wait_for_rc(client: MspClient, expected: tuple[int, ...], timeout_s: float = 3.0) -> tuple:
    deadline = time.monotonic() + timeout_s
    seen: tuple[int, ...] = ()
    while time.monotonic() < deadline:
        seen = client.get(msg.Rc).channels_us[: len(expected)]
        if seen == expected:
            return seen
        time.sleep(0.05)
    raise AssertionError(f"MSP_RC reads {seen}, expected {expected}")


def _board_checks(link: Link, roll_us: int) -> dict[str, object]:
    """What a real-board session does first: identify, read a setting, send RC over MSP."""
    with MspClient(link, timeout_s=1.0) as client:
        api = client.api_version().api
        with CliSession(link) as cli:
            small_angle = cli.get("small_angle")
        assert client.api_version().api == api  # the port is back in MSP mode
        command = RcCommand(
            roll_us=roll_us, pitch_us=1400, throttle_us=1100, yaw_us=1550, aux_us=(1800,)
        )
        with MspRcLink(client) as rc:
            rc.set(command)
            # MSP_RC answers in the FC's internal order: roll, pitch, yaw, throttle, AUX1.
            rc_read = _wait_for_rc(client, (roll_us, 1400, 1550, 1100, 1800))
            stats = rc.stats()
        return {
            "api": api,
            "small_angle": small_angle,
            "rc": rc_read,
            "rc_errors": stats.send_errors,
        }


def test_serial_uri_answers_like_tcp(sitl_behind_pty):
    sitl, endpoint = sitl_behind_pty
    results = {}
    # Different roll values, so the second run cannot pass on what the first one left.
    for transport, roll_us in (("tcp", 1600), ("serial", 1650)):
        link = _open(transport, sitl, endpoint)
        assert isinstance(link, SerialLink) == (transport == "serial")
        results[transport] = _board_checks(link, roll_us)
    tcp, over_serial = results["tcp"], results["serial"]
    assert tcp["api"] == over_serial["api"] == (1, 47)
    assert tcp["small_angle"] == over_serial["small_angle"] == SMALL_ANGLE_DEFAULT
    assert tcp["rc"] == (1600, 1400, 1550, 1100, 1800)
    assert over_serial["rc"] == (1650, 1400, 1550, 1100, 1800)
    assert tcp["rc_errors"] == over_serial["rc_errors"] == 0
