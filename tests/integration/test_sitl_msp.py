"""The MSP stack against the real Betaflight 4.6.0 SITL."""

from __future__ import annotations

import os
import signal
import time

import pytest

from bfsitl.errors import LinkClosedError, MspErrorReply, MspTimeoutError, SitlExitedError
from bfsitl.fc.identity import read_identity
from bfsitl.fc.msp_client import MspClient, MspRequest
from bfsitl.fc.telemetry_poller import TelemetryPoller
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspVersion, encode_request

pytestmark = pytest.mark.sitl


def test_identity_is_betaflight_4_6_sitl(sitl):
    identity = read_identity(sitl.client)
    assert identity.variant == "BTFL"
    assert identity.firmware_version == "4.6.0"
    assert identity.api_version == "1.47"
    assert identity.is_sitl


def test_boot_flags_are_decoded_and_bootgrace_clears_after_five_seconds(sitl):
    status = sitl.client.status()
    names = {flag.cli_name for flag in status.arming_blockers}
    # Without RC and fdm packets the FC reports these right after boot.
    assert {"RXLOSS", "ANGLE", "BOOTGRACE"} <= names
    assert status.arming_disable_flag_count == 29
    assert not status.armed
    assert set(status.sensors) >= {"GYRO", "ACC", "BARO"}
    deadline = time.monotonic() + 12.0
    while time.monotonic() < deadline:
        names = {flag.cli_name for flag in sitl.client.status().arming_blockers}
        if "BOOTGRACE" not in names and "CALIB" not in names:
            break
        time.sleep(0.2)
    assert "BOOTGRACE" not in names and "CALIB" not in names
    assert {"RXLOSS", "ANGLE"} <= names  # these need RC and fdm, which nobody sends here


def test_arm_mode_range_set_and_read_back(sitl):
    arm = msg.ModeRange.from_us(box_id=0, aux_channel_index=0, start_us=1700, end_us=2100)
    sitl.client.set_mode_range(0, arm)
    ranges = sitl.client.mode_ranges().ranges
    assert ranges[0] == arm
    assert (ranges[0].start_us, ranges[0].end_us) == (1700, 2100)
    assert not any(r.is_used for r in ranges[1:])


def test_unknown_command_gets_an_error_reply_and_the_link_goes_on(sitl):
    with pytest.raises(MspErrorReply):
        sitl.client.request(23)
    with pytest.raises(MspErrorReply):
        sitl.client.request(0x4242)  # unknown v2 id
    assert sitl.client.api_version().api == (1, 47)


def test_v2_native_and_v2_over_v1_framings_are_answered(sitl):
    link = sitl.client.link
    from bfsitl.protocol.msp_frame import MspParser

    for version in (MspVersion.V2, MspVersion.V2_OVER_V1):
        parser = MspParser()
        link.write(encode_request(MspCommand.API_VERSION, b"", version))
        frames = []
        deadline = time.monotonic() + 2
        while not frames and time.monotonic() < deadline:
            frames = parser.feed(link.read_some(0.1))
        assert frames and frames[0].payload == b"\x00\x01\x2f"
        assert frames[0].version is version


def test_garbage_and_bad_checksums_on_the_port_do_not_break_the_client(sitl):
    client = sitl.client
    # Garbage without the FC's special bytes ('#', 'R', 0x02 switch modes or reboot).
    client.link.write(bytes(range(0x04, 0x23)) + b"$M<\xff" + b"\x00" * 20)
    bad = bytearray(encode_request(MspCommand.ATTITUDE))
    bad[-1] ^= 0x55
    client.link.write(bytes(bad))  # the FC silently drops it
    assert client.get(msg.Attitude).roll_decideg == 0
    results = client.pipeline([MspRequest(MspCommand.API_VERSION)] * 10, depth=4)
    assert all(r == b"\x00\x01\x2f" for r in results)


def test_multiple_msp_and_telemetry_snapshot(sitl):
    snapshot = sitl.client.telemetry()
    assert snapshot.motors.motors_us[:4] == (1000, 1000, 1000, 1000)
    assert snapshot.rc.throttle_us == 885  # rx_min_usec before any RC
    assert not snapshot.armed
    assert "RXLOSS" in snapshot.arming_blockers
    assert snapshot.box_ids[0] == 0  # ARM is always the first box


def test_pipeline_keeps_in_flight_bytes_under_the_sitl_ring(sitl):
    # 300 x 6-byte requests sent at once overflow the SITL's 1400-byte ring (measured: only
    # 66 answers); the client's window must deliver every one.
    results = sitl.client.pipeline([MspRequest(MspCommand.API_VERSION)] * 300, depth=300)
    assert len(results) == 300 and all(r == b"\x00\x01\x2f" for r in results)
    assert sitl.client.stats.timeouts == 0


def test_poller_hands_out_fresh_snapshots(sitl):
    with TelemetryPoller(sitl.client, rate_hz=None) as poller:
        first = poller.wait_next(0, timeout_s=2.0)
        assert first is not None
        later = poller.wait_next(poller.sequence, timeout_s=2.0)
        assert later is not None and later.received_at_s > first.received_at_s
        time.sleep(1.0)
    stats = poller.stats()
    assert stats.errors == 0 and stats.updates >= 40


def test_second_sitl_in_the_same_network_is_reported_not_shared(sitl, firmware, tmp_path):
    from bfsitl.errors import PortInUseError
    from bfsitl.sitl.process import SitlProcess

    second = SitlProcess(firmware, workdir=tmp_path / "second", network=sitl.network)
    with pytest.raises(PortInUseError) as caught:
        second.start()
    assert str(sitl.pid) in str(caught.value)
    assert "5761" in str(caught.value)
    assert second.pid is None  # never started
    assert sitl.client.api_version().api == (1, 47)  # the first one is unharmed


def test_crash_is_seen_as_closed_link_and_restart_recovers(sitl):
    os.kill(sitl.pid, signal.SIGKILL)
    with pytest.raises((LinkClosedError, MspTimeoutError)):
        for _ in range(5):
            sitl.client.api_version()
    assert sitl.wait_exit(5.0) == -signal.SIGKILL
    sitl.restart()
    assert sitl.client.api_version().api == (1, 47)
    assert sitl.starts == 2


def test_reboot_ends_the_process_and_restart_after_reboot_brings_it_back(sitl):
    sitl.client.reboot()
    sitl.restart_after_reboot()
    assert sitl.starts == 2
    assert read_identity(sitl.client).firmware_version == "4.6.0"


def test_a_binary_that_dies_at_start_is_reported_with_its_log(tmp_path):
    from bfsitl.sitl.firmware import FirmwareBinary
    from bfsitl.sitl.process import SitlProcess

    fake = tmp_path / "betaflight_9.9.9_SITL"
    fake.write_text("#!/bin/sh\necho 'simulated init failure'\nexit 3\n")
    fake.chmod(0o755)
    process = SitlProcess(FirmwareBinary(fake, "explicit"), workdir=tmp_path / "run", isolate=True)
    with pytest.raises(SitlExitedError) as caught:
        process.start()
    process.stop()
    assert caught.value.returncode == 3
    assert "simulated init failure" in str(caught.value)


def test_client_without_sitl_times_out_cleanly_when_nothing_answers(sitl):
    # A v1 request with payload over 192 bytes: refused before it reaches the wire.
    from bfsitl.errors import MspFrameError

    with pytest.raises(MspFrameError):
        sitl.client.request(MspCommand.SET_NAME, bytes(193))
    assert isinstance(sitl.client, MspClient)


def test_msp_rc_link_sets_the_channels_the_fc_reads(sitl):
    """MSP_SET_RAW_RC takes AETR; MSP_RC answers in the internal order R, P, Y, T."""
    from bfsitl.fc.rc_link import MspRcLink, RcCommand

    with MspRcLink(sitl.client) as link:
        link.set(
            RcCommand(roll_us=1100, pitch_us=1200, throttle_us=1300, yaw_us=1400, aux_us=(1800,))
        )
        deadline = time.monotonic() + 3.0
        while time.monotonic() < deadline:
            rc = sitl.client.get(msg.Rc)
            if rc.channels_us[:5] == (1100, 1200, 1400, 1300, 1800):
                break
            time.sleep(0.05)
        assert rc.channels_us[:5] == (1100, 1200, 1400, 1300, 1800)
        assert link.stats().send_errors == 0
    # Closing sent disarm and low throttle.
    assert sitl.client.get(msg.Rc).channels_us[:5] == (1500, 1500, 1500, 1000, 1000)
