"""MspClient against the in-memory FC of tests/support/fake_fc.py: matching, retries, pipelining.

The fake answers one queued request per read call, in order, and can drop requests, corrupt or
delay replies, or echo like a port left in CLI mode, so each test below sets up exactly the
wire behaviour it is about.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator

import pytest
from support.fake_fc import FakeFcLink, Handler, fixed, multiple_msp, telemetry_handlers  # noqa: E402

from bfsitl.errors import MspDecodeError, MspErrorReply, MspTimeoutError  # noqa: E402
from bfsitl.fc.msp_client import (  # noqa: E402
    TELEMETRY_COMMANDS,
    MspClient,
    MspRequest,
    Telemetry,
    is_idempotent,
)
from bfsitl.protocol import messages as msg  # noqa: E402
from bfsitl.protocol.arming import ArmingFlag  # noqa: E402
from bfsitl.protocol.boxes import SITL_DEFAULT_BOX_IDS  # noqa: E402
from bfsitl.protocol.msp_codes import MspCommand  # noqa: E402
from bfsitl.protocol.msp_frame import MspFrame, encode_frame, encode_request  # noqa: E402

ATT = msg.Attitude(roll_decideg=15, pitch_decideg=-20, yaw_deg=90)
ALT = msg.Altitude(altitude_cm=1234, vario_cm_s=-5)
ANALOG = msg.Analog(vbat_dv=126, mah_drawn=10, rssi=1023, amperage_ca=150, vbat_cv=1260)
RC = msg.Rc((1500, 1510, 1490, 1000, 1800, 1000, 1500, 1500))
MOTOR = msg.Motor((1000, 1001, 1002, 1003, 0, 0, 0, 0))
#: Level at rest in the SITL: 1 g on body z at 256 LSB per g.
IMU = msg.RawImu(acc_raw=(0, 0, 256), gyro_raw=(1, -2, 3), mag_raw=(0, 0, 0))
#: Armed, with flight-mode bit 4 set: on the stock SITL box list that is FAILSAFE (permanent id
#: 27), not ANTIGRAVITY (permanent id 4).
STATUS = msg.StatusEx(
    cycle_time_us=125,
    i2c_errors=0,
    sensors_mask=0x23,
    flight_mode_flags=0b1_0001,
    pid_profile=0,
    cpu_load_percent=12,
    pid_profile_count=4,
    rate_profile_index=0,
    arming_disable_flag_count=29,
    arming_disable_flags=ArmingFlag.RX_FAILSAFE.mask | ArmingFlag.CLI.mask,
    config_state=0,
    cpu_temp_c=0,
    rate_profile_count=4,
)
MODE_RANGE = msg.ModeRange.from_us(0, 0, 1700, 2100)


def read_handlers() -> dict[int, Handler]:
    """Handlers for the reads the tests use, each answering its codec's encoding."""
    handlers = telemetry_handlers(
        attitude=ATT,
        altitude=ALT,
        status=STATUS,
        analog=ANALOG,
        rc=RC,
        motor=MOTOR,
        imu=IMU,
        box_ids=SITL_DEFAULT_BOX_IDS,
    )
    handlers[MspCommand.SET_MODE_RANGE] = fixed(b"")
    handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(dict(handlers))
    return handlers


def make(timeout_s: float = 0.1, **kwargs: object) -> tuple[FakeFcLink, MspClient]:
    link = FakeFcLink(read_handlers())
    return link, MspClient(link, timeout_s=timeout_s, **kwargs)  # type: ignore[arg-type]


def silent(_request: MspFrame) -> bytes | None:
    """A handler for a request the FC never answers."""
    return None


# --- request ------------------------------------------------------------------------------------


def test_request_returns_the_reply_payload() -> None:
    """request() sends the command once and returns exactly the payload the FC answered."""
    link, client = make()
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()
    assert [f.command for f in link.received] == [MspCommand.ATTITUDE]
    assert client.attitude() == ATT
    assert client.stats.replies == 2 and client.stats.timeouts == 0


def test_request_sends_the_payload() -> None:
    """The request payload reaches the FC unchanged (here a SET_MODE_RANGE)."""
    link, client = make()
    client.set_mode_range(3, MODE_RANGE)
    assert link.received[-1].command == MspCommand.SET_MODE_RANGE
    assert link.received[-1].payload == msg.SetModeRange(3, MODE_RANGE).encode()


def test_error_reply_raises_with_the_command() -> None:
    """An ``!`` reply raises MspErrorReply naming the command, and is not retried."""
    link, client = make()
    with pytest.raises(MspErrorReply) as info:
        client.request(MspCommand.NAME)
    assert info.value.command == MspCommand.NAME
    assert client.stats.error_replies == 1
    assert link.sent_commands.count(MspCommand.NAME) == 1


def test_missing_reply_times_out_within_about_timeout() -> None:
    """No reply at all raises MspTimeoutError, also a TimeoutError, after about timeout_s."""
    link, client = make(timeout_s=0.1)
    link.handlers[MspCommand.ATTITUDE] = silent
    start = time.monotonic()
    with pytest.raises(TimeoutError) as info:
        client.request(MspCommand.ATTITUDE, retries=0)
    elapsed = time.monotonic() - start
    assert isinstance(info.value, MspTimeoutError)
    assert 0.09 <= elapsed < 0.35
    assert client.stats.timeouts == 1


def test_unanswered_read_is_tried_retries_plus_one_times() -> None:
    """A read that never gets an answer is sent 1 + retries times, then times out."""
    link, client = make(timeout_s=0.05, retries=2)
    link.handlers[MspCommand.ATTITUDE] = silent
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE)
    assert link.sent_commands.count(MspCommand.ATTITUDE) == 3
    assert client.stats.retries == 2 and client.stats.timeouts == 3


def test_dropped_read_is_retried_and_succeeds() -> None:
    """A lost idempotent read (MSP_ATTITUDE) is sent again once and then succeeds."""
    link, client = make()
    link.drop_next.add(MspCommand.ATTITUDE)
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()
    assert client.stats.retries == 1
    assert link.sent_commands.count(MspCommand.ATTITUDE) == 2


def test_dropped_set_is_not_retried() -> None:
    """A lost SET_MODE_RANGE is sent exactly once: repeating a write could apply it twice."""
    link, client = make()
    link.drop_next.add(MspCommand.SET_MODE_RANGE)
    with pytest.raises(MspTimeoutError):
        client.set_mode_range(0, MODE_RANGE)
    assert link.sent_commands.count(MspCommand.SET_MODE_RANGE) == 1
    assert client.stats.retries == 0


def test_retry_writes_etx_before_resending() -> None:
    """The retry path writes 0x03 (ends a stray non-interactive CLI) right before the resend."""
    link, client = make()
    link.drop_next.add(MspCommand.ATTITUDE)
    client.request(MspCommand.ATTITUDE)
    frame = encode_request(MspCommand.ATTITUDE)
    raw = bytes(link.raw_written)
    first = raw.index(frame)
    second = raw.index(frame, first + len(frame))
    assert raw[first + len(frame) : second] == b"\x03"


# --- pipeline -----------------------------------------------------------------------------------


def test_pipeline_results_are_in_request_order() -> None:
    """Replies, ``!`` errors and timeouts each land at the position of their own request."""
    link, client = make(timeout_s=0.05)
    link.handlers[MspCommand.SET_ARMING_CONFIG] = silent
    requests = [
        MspRequest(MspCommand.ATTITUDE),
        MspRequest(MspCommand.NAME),  # unknown to the fake: '!'
        MspRequest(MspCommand.ALTITUDE),
        MspRequest(MspCommand.SET_ARMING_CONFIG, bytes(3)),  # never answered
        MspRequest(MspCommand.ANALOG),
    ]
    results = client.pipeline(requests)
    assert results[0] == ATT.encode()
    assert isinstance(results[1], MspErrorReply) and results[1].command == MspCommand.NAME
    assert results[2] == ALT.encode()
    assert isinstance(results[3], MspTimeoutError)
    assert results[4] == ANALOG.encode()


def test_pipeline_retries_a_read_lost_in_the_middle_without_waiting() -> None:
    """A later reply proves the request ahead of it lost: it is retried at once, and the other
    replies still resolve their own requests."""
    link, client = make(timeout_s=1.0)
    link.drop_next.add(MspCommand.ALTITUDE)
    requests = [
        MspRequest(c) for c in (MspCommand.ATTITUDE, MspCommand.ALTITUDE, MspCommand.ANALOG)
    ]
    start = time.monotonic()
    results = client.pipeline(requests)
    assert time.monotonic() - start < 0.5  # far below the 1 s timeout
    assert results == [ATT.encode(), ALT.encode(), ANALOG.encode()]
    assert client.stats.lost_requests == 1
    assert client.stats.retries == 1
    assert link.sent_commands.count(MspCommand.ALTITUDE) == 2


def test_pipeline_fails_a_write_lost_in_the_middle_without_resending() -> None:
    """A SET lost between two answered reads fails with a timeout and is never resent."""
    link, client = make(timeout_s=1.0)
    link.drop_next.add(MspCommand.SET_MODE_RANGE)
    requests = [
        MspRequest(MspCommand.ATTITUDE),
        MspRequest(MspCommand.SET_MODE_RANGE, msg.SetModeRange(0, MODE_RANGE).encode()),
        MspRequest(MspCommand.ALTITUDE),
    ]
    results = client.pipeline(requests)
    assert results[0] == ATT.encode() and results[2] == ALT.encode()
    assert isinstance(results[1], MspTimeoutError)
    assert client.stats.lost_requests == 1
    assert link.sent_commands.count(MspCommand.SET_MODE_RANGE) == 1


def test_pipeline_caps_bytes_in_flight() -> None:
    """Unanswered request bytes never exceed max_in_flight_bytes, yet requests still overlap."""
    link = FakeFcLink(read_handlers())
    client = MspClient(link, timeout_s=0.1, max_in_flight_bytes=20)
    telemetry = client.telemetry_request()  # 12-byte frame
    requests = [MspRequest(MspCommand.ATTITUDE) if i % 3 else telemetry for i in range(30)]
    results = client.pipeline(requests, depth=10)
    assert all(isinstance(r, bytes) for r in results)
    assert link.max_unanswered_bytes <= client.max_in_flight_bytes
    assert link.max_unanswered_bytes >= 12  # more than one request was in flight


def test_pipeline_sends_a_frame_larger_than_the_cap_alone() -> None:
    """A single frame above the byte cap is still sent when nothing else is in flight."""
    link = FakeFcLink(read_handlers())
    client = MspClient(link, timeout_s=0.1, max_in_flight_bytes=4)
    results = client.pipeline([MspRequest(MspCommand.ATTITUDE)] * 3)
    assert results == [ATT.encode()] * 3
    assert link.max_unanswered_requests == 1


@pytest.mark.parametrize("depth", [1, 3, 6])
def test_pipeline_depth_limits_outstanding_requests(depth: int) -> None:
    """At most ``depth`` requests are unanswered at any time, and the window is used fully."""
    link, client = make()
    results = client.pipeline([MspRequest(MspCommand.ATTITUDE)] * 12, depth=depth)
    assert len(results) == 12
    assert link.max_unanswered_requests == depth


def test_pipeline_consumes_a_generator_lazily() -> None:
    """A generator is pulled as the window opens, not drained up front."""
    _link, client = make()
    pulled = 0
    pulled_at_reply: list[int] = []

    def source() -> Iterator[MspRequest]:
        nonlocal pulled
        for _ in range(10):
            pulled += 1
            yield MspRequest(MspCommand.ATTITUDE)

    results = client.pipeline(
        source(), depth=2, on_reply=lambda _req, _payload: pulled_at_reply.append(pulled)
    )
    assert len(results) == 10
    assert pulled_at_reply[0] <= 2
    # Never more than depth requests ahead of the replies.
    assert all(count <= index + 1 + 2 for index, count in enumerate(pulled_at_reply))


def test_pipeline_calls_on_reply_for_each_successful_reply() -> None:
    """on_reply gets (request, payload) once per good reply, in order, and not for errors."""
    _link, client = make()
    seen: list[tuple[MspRequest, bytes]] = []
    requests = [
        MspRequest(MspCommand.ATTITUDE),
        MspRequest(MspCommand.NAME),
        MspRequest(MspCommand.ALTITUDE),
    ]
    client.pipeline(requests, on_reply=lambda req, payload: seen.append((req, payload)))
    assert seen == [(requests[0], ATT.encode()), (requests[2], ALT.encode())]


# --- robustness of matching ---------------------------------------------------------------------


def test_garbage_before_and_between_replies_does_not_break_matching() -> None:
    """CLI text and junk around replies is skipped; every request gets its own reply."""
    link, client = make()
    link.inject(b"\r\nEntering CLI Mode\r\n# $M junk $X\r\n")
    att_reply = link.handlers[MspCommand.ATTITUDE]

    def noisy(request: MspFrame) -> bytes | None:
        link.inject(b"###ERROR IN input###\r\n# \x00\xff$")
        return att_reply(request)

    link.handlers[MspCommand.ATTITUDE] = noisy
    requests = [
        MspRequest(MspCommand.ALTITUDE),
        MspRequest(MspCommand.ATTITUDE),
        MspRequest(MspCommand.ANALOG),
    ]
    assert client.pipeline(requests) == [ALT.encode(), ATT.encode(), ANALOG.encode()]
    assert client.stats.timeouts == 0


def test_stalled_garbage_header_is_looked_behind() -> None:
    """A garbage ``$M>`` with a large size hides the real reply only until the deadline."""
    link, client = make(timeout_s=0.1)
    link.inject(b"$M>\xc8")
    assert client.request(MspCommand.ATTITUDE, retries=0) == ATT.encode()


def test_bad_checksum_is_counted_and_the_read_retried() -> None:
    """A corrupted reply is counted in checksum_failures, and the read then succeeds on retry."""
    link, client = make()
    link.corrupt_next.add(MspCommand.ATTITUDE)
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()
    assert client.stats.checksum_failures == 1
    assert client.stats.retries == 1


def test_bad_checksum_without_retries_times_out() -> None:
    """With retries=0 a corrupted reply ends in MspTimeoutError, never in a corrupt payload."""
    link, client = make()
    link.corrupt_next.add(MspCommand.ATTITUDE)
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE, retries=0)
    assert client.stats.checksum_failures == 1


def test_stray_reply_is_counted_and_ignored() -> None:
    """A reply for a command that is not outstanding neither resolves nor breaks a request."""
    link, client = make()
    link.inject(encode_frame(MspFrame(MspCommand.ALTITUDE, ALT.encode())))
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()
    assert client.stats.stray_replies == 1
    assert client.stats.lost_requests == 0


def test_echoed_request_is_not_taken_as_the_reply() -> None:
    """Only ``>``/``!`` frames answer a request; the line's echo of our own ``<`` does not.

    Regression: the echo of a request (half-duplex wire, loopback adapter) was taken as its
    own empty reply.
    """
    link, client = make()
    link.echo_requests = True
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()


def test_slow_head_does_not_fail_the_set_queued_behind_it() -> None:
    """A read answered late is retried, and the SET behind it still gets its own reply.

    Regression: the request behind a timed-out head was failed at once (its clock was not
    restarted), and the late reply to the retried head marked it lost.
    """
    link, client = make(timeout_s=0.1)
    # In order: ATTITUDE is answered only after 150 ms (past its 100 ms timeout), then the SET.
    link.reply_delay_s = {MspCommand.ATTITUDE: 0.15}
    requests = [
        MspRequest(MspCommand.ATTITUDE),
        MspRequest(MspCommand.SET_MODE_RANGE, msg.SetModeRange(0, MODE_RANGE).encode()),
    ]
    results = client.pipeline(requests, depth=2)
    assert results[0] == ATT.encode()
    assert results[1] == b""
    assert link.sent_commands.count(MspCommand.SET_MODE_RANGE) == 1


def test_late_reply_is_not_taken_for_the_next_request() -> None:
    """A reply arriving after its request timed out is absorbed, not handed to the next
    request of the same command (which would get stale data)."""
    link, client = make(timeout_s=0.1)
    counter = iter(range(1, 100))
    link.handlers[MspCommand.ATTITUDE] = lambda _req: msg.Attitude(0, 0, next(counter)).encode()
    link.reply_delay_s = {MspCommand.ATTITUDE: 0.3}
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE, retries=0)
    link.reply_delay_s = {}  # the FC now sends the late reply, then answers the new request
    assert client.attitude().yaw_deg == 2
    assert client.stats.late_replies == 1


def test_retry_of_a_large_read_is_sent_despite_the_byte_cap() -> None:
    """A read using most of the byte cap is still retried, then times out normally."""
    link = FakeFcLink(read_handlers())
    client = MspClient(link, timeout_s=0.05, max_in_flight_bytes=20)
    link.handlers[MspCommand.MULTIPLE_MSP] = silent
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.MULTIPLE_MSP, client.telemetry_request().payload, retries=1)
    assert link.sent_commands.count(MspCommand.MULTIPLE_MSP) == 2


def test_ghost_of_an_earlier_call_does_not_block_the_next_request() -> None:
    """After a timeout, the next request is sent and answered even under a small byte cap."""
    link = FakeFcLink(read_handlers())
    client = MspClient(link, timeout_s=0.05, max_in_flight_bytes=16)
    link.handlers[MspCommand.MULTIPLE_MSP] = silent
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.MULTIPLE_MSP, client.telemetry_request().payload, retries=0)
    assert client.request(MspCommand.ATTITUDE) == ATT.encode()


# --- timeout messages ---------------------------------------------------------------------------


def test_timeout_message_names_cli_mode_when_the_port_echoes() -> None:
    """On a port left in CLI mode (it echoes text) the timeout says so and how to fix it."""
    link, client = make(timeout_s=0.05)
    link.cli_mode = True
    with pytest.raises(MspTimeoutError) as info:
        client.request(MspCommand.ATTITUDE, retries=0)
    assert "CLI mode" in str(info.value)
    assert "leave()" in str(info.value)


def test_timeout_message_without_echo_does_not_blame_cli() -> None:
    """A silent FC gets the generic message, naming the command and the link."""
    link, client = make(timeout_s=0.05)
    link.handlers[MspCommand.ATTITUDE] = silent
    with pytest.raises(MspTimeoutError) as info:
        client.request(MspCommand.ATTITUDE, retries=0)
    text = str(info.value)
    assert "CLI" not in text
    assert "MSP_ATTITUDE (108)" in text and link.uri in text


def test_old_cli_text_does_not_blame_cli_for_a_later_timeout() -> None:
    """Once the port answers MSP again, a new timeout is not reported as CLI mode.

    Regression: CLI text skipped long ago kept blaming CLI mode for every later timeout.
    """
    link, client = make(timeout_s=0.05)
    link.cli_mode = True
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE, retries=0)
    link.cli_mode = False
    assert client.request(MspCommand.ALTITUDE) == ALT.encode()
    link.handlers[MspCommand.ATTITUDE] = silent
    with pytest.raises(MspTimeoutError) as info:
        client.request(MspCommand.ATTITUDE, retries=0)
    assert "CLI" not in str(info.value)


# --- idempotence --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("command", "expected"),
    [
        (MspCommand.ATTITUDE, True),
        (MspCommand.STATUS_EX, True),
        (MspCommand.BOXIDS, True),
        (MspCommand.MULTIPLE_MSP, True),
        (MspCommand.MSP2_SENSOR_CONFIG_ACTIVE, True),
        (MspCommand.SET_MODE_RANGE, False),
        (MspCommand.SET_RAW_RC, False),
        (MspCommand.MSP2_SET_TEXT, False),
        (MspCommand.REBOOT, False),
        (MspCommand.EEPROM_WRITE, False),
        (MspCommand.RESET_CONF, False),
        (MspCommand.ACC_CALIBRATION, False),
        (9999, False),
        (252, False),  # no such command in 4.6
    ],
)
def test_is_idempotent(command: int, expected: bool) -> None:
    """Reads may be repeated; writes, reboots, calibrations and unknown ids may not."""
    assert is_idempotent(command) is expected


def test_camera_control_is_not_idempotent() -> None:
    """Repeating a camera key press presses it twice: it must not be retried.

    Regression: MSP_CAMERA_CONTROL has no SET in its name and counted as a read.
    """
    assert is_idempotent(MspCommand.CAMERA_CONTROL) is False


# --- typed helpers and telemetry ----------------------------------------------------------------


def test_telemetry_decodes_every_field_in_one_round_trip() -> None:
    """telemetry() asks MULTIPLE_MSP once and decodes each sub-reply with its codec."""
    link, client = make()
    t = client.telemetry()
    assert (t.attitude, t.altitude, t.status, t.analog, t.rc, t.motors, t.imu) == (
        ATT,
        ALT,
        STATUS,
        ANALOG,
        RC,
        MOTOR,
        IMU,
    )
    assert t.armed is True
    assert t.arming_blockers == ("RXLOSS", "CLI")
    # Bit 4 is the fifth entry of BOXIDS (FAILSAFE on the stock SITL), not permanent id 4.
    assert t.flight_modes == ("ARM", "FAILSAFE")
    multiple = [f for f in link.received if f.command == MspCommand.MULTIPLE_MSP]
    assert len(multiple) == 1
    assert tuple(multiple[0].payload) == TELEMETRY_COMMANDS


def test_telemetry_reads_box_ids_once() -> None:
    """The BOXIDS list is fetched on first use and cached for later snapshots."""
    link, client = make()
    client.telemetry()
    client.telemetry()
    assert link.sent_commands.count(MspCommand.BOXIDS) == 1
    assert link.sent_commands.count(MspCommand.MULTIPLE_MSP) == 2


def test_telemetry_not_armed_without_bit_zero() -> None:
    """``armed`` follows bit 0 of the flight-mode flags, and no blockers means an empty tuple."""
    link, client = make()
    status = msg.StatusEx(
        cycle_time_us=125,
        i2c_errors=0,
        sensors_mask=0,
        flight_mode_flags=0b10,
        pid_profile=0,
        cpu_load_percent=0,
        pid_profile_count=4,
        rate_profile_index=0,
        arming_disable_flag_count=29,
        arming_disable_flags=0,
        config_state=0,
    )
    handlers = read_handlers()
    handlers[MspCommand.STATUS_EX] = fixed(status.encode())
    link.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(handlers)
    t = client.telemetry()
    assert t.armed is False
    assert t.arming_blockers == ()
    assert t.flight_modes == ("ANGLE",)


def test_multiple_raises_when_sub_replies_are_missing() -> None:
    """Fewer sub-replies than commands (FC buffer full) raises MspDecodeError."""
    link, client = make()
    link.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(read_handlers(), limit=3)
    with pytest.raises(MspDecodeError):
        client.multiple(TELEMETRY_COMMANDS)


def test_multiple_returns_empty_payload_for_unanswerable_command() -> None:
    """A command the FC cannot answer inside MULTIPLE_MSP comes back as an empty payload."""
    _link, client = make()
    assert client.multiple([MspCommand.ATTITUDE, MspCommand.NAME]) == (ATT.encode(), b"")


def test_pipelined_telemetry_requests_decode() -> None:
    """telemetry_request() pipelined and decode_telemetry() give the same snapshot."""
    _link, client = make()
    client.box_ids()
    results = client.pipeline([client.telemetry_request()] * 3)
    snapshots = [client.decode_telemetry(r) for r in results if isinstance(r, bytes)]
    assert len(snapshots) == 3
    assert all(s.attitude == ATT and s.flight_modes == ("ARM", "FAILSAFE") for s in snapshots)


def imu_snapshot(
    roll_decideg: int, pitch_decideg: int, acc_z: int, acc_x: int = 0, acc_y: int = 0
) -> Telemetry:
    """A snapshot whose only meaningful parts are the attitude and the accelerometer."""
    return Telemetry(
        received_at_s=0.0,
        attitude=msg.Attitude(roll_decideg, pitch_decideg, 0),
        altitude=ALT,
        status=STATUS,
        analog=ANALOG,
        rc=RC,
        motors=MOTOR,
        imu=msg.RawImu((acc_x, acc_y, acc_z), (0, 0, 0), (0, 0, 0)),
    )


def test_accel_up_is_zero_level_at_rest() -> None:
    """1 g on body z, level: the accelerometer reads gravity alone, so no acceleration."""
    assert imu_snapshot(0, 0, 256).accel_up_m_s2() == 0.0


def test_accel_up_level_at_two_g_is_one_g_up() -> None:
    """2 g on body z, level: gravity removed leaves 1 g upwards."""
    assert imu_snapshot(0, 0, 512).accel_up_m_s2() == pytest.approx(9.80665)


@pytest.mark.parametrize(("roll_decideg", "pitch_decideg"), [(600, 0), (-600, 0), (0, 600)])
def test_accel_up_projects_body_z_onto_the_vertical(roll_decideg: int, pitch_decideg: int) -> None:
    """Tilted 60 deg with 2 g along the thrust axis: cos(60) = 1/2 of it is up, holding 1 g."""
    t = imu_snapshot(roll_decideg, pitch_decideg, 512)
    assert t.accel_up_m_s2() == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("roll_deg", "pitch_deg"), [(20.0, 0.0), (0.0, 15.0), (-12.0, 9.0)])
def test_accel_up_counts_the_body_x_and_y_readings_too(roll_deg: float, pitch_deg: float) -> None:
    """Tilted and still (hovering in a steady state): the accelerometer reads 1 g straight up
    in the world, which in Betaflight's FLU body axes (pitch positive nose down, roll positive
    right wing down) is (-sin(pitch), sin(roll) cos(pitch), cos(roll) cos(pitch)) g.  All of
    it, x and y included, projects back to 1 g up: no acceleration.  Body z alone would read
    an acceleration of g (cos^2 - 1), and a horizontal push (rotor drag) would leak into the
    vertical through the tilt."""
    r, p = math.radians(roll_deg), math.radians(pitch_deg)
    lsb = 256
    t = imu_snapshot(
        round(roll_deg * 10),
        round(pitch_deg * 10),
        acc_z=round(lsb * math.cos(r) * math.cos(p)),
        acc_x=round(-lsb * math.sin(p)),
        acc_y=round(lsb * math.sin(r) * math.cos(p)),
    )
    assert t.accel_up_m_s2() == pytest.approx(0.0, abs=0.05)  # LSB rounding only
    # A pure forward push (x) while nose-down: part of it is "down", none of it "up".
    pushed = imu_snapshot(0, round(pitch_deg * 10), acc_z=lsb, acc_x=64)
    if pitch_deg > 0:
        assert pushed.accel_up_m_s2() < imu_snapshot(0, round(pitch_deg * 10), lsb).accel_up_m_s2()


def test_accel_up_takes_the_sensor_scale() -> None:
    """A real IMU's 2048 LSB per g: the same reading means 1/8 of the SITL's g."""
    assert imu_snapshot(0, 0, 2048).accel_up_m_s2(acc_1g_lsb=2048) == pytest.approx(0.0)
    assert imu_snapshot(0, 0, 3072).accel_up_m_s2(acc_1g_lsb=2048) == pytest.approx(0.5 * 9.80665)
    assert imu_snapshot(0, 0, 2048).accel_up_m_s2() == pytest.approx(7 * 9.80665)


# --- identical requests after a loss (the telemetry poller's pattern) ----------------------------


def test_one_dropped_poll_costs_at_most_one_timeout_in_a_pipeline() -> None:
    """A lost request among identical ones must not make every later poll time out.

    Regression: a timed-out request's ghost used to take the next identical request's reply,
    which then timed out and left a ghost of its own: one timeout per poll, forever.
    """
    link, client = make(timeout_s=0.1)
    link.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(link.handlers)
    request = client.telemetry_request()
    link.drop_next.add(MspCommand.MULTIPLE_MSP)
    results = client.pipeline([request] * 50, depth=3, retries=0)
    assert sum(isinstance(r, MspTimeoutError) for r in results) <= 1
    assert client.stats.timeouts <= 1


def test_one_dropped_read_costs_one_timeout_in_sequential_calls() -> None:
    link, client = make(timeout_s=0.1)
    link.drop_next.add(MspCommand.ATTITUDE)
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE, retries=0)
    for _ in range(10):
        assert client.attitude() == ATT
    assert client.stats.timeouts == 1


# --- the direct path of a lone request ----------------------------------------------------------


def _set_up(case: str, link: FakeFcLink) -> None:
    """One wire behaviour for the request of the test below."""
    if case == "dropped":
        link.drop_next.add(MspCommand.ATTITUDE)
    elif case == "corrupted":
        link.corrupt_next.add(MspCommand.ATTITUDE)
    elif case == "garbage first":
        link.inject(b"\x00\x17$Mxx" + encode_frame(MspFrame(MspCommand.RC, RC.encode())))
    elif case == "echoed":
        link.echo_requests = True
    elif case == "error reply":
        link.handlers.pop(MspCommand.ATTITUDE)
    elif case == "silent":
        link.handlers[MspCommand.ATTITUDE] = silent


@pytest.mark.parametrize(
    "case", ["plain", "dropped", "corrupted", "garbage first", "echoed", "error reply", "silent"]
)
def test_a_lone_request_ends_as_the_pipeline_ends_it(case: str) -> None:
    """request() of one read with nothing else on the wire takes a direct path when the link
    needs no wake bytes (lockstep, a board); whatever the wire does, it ends with the result
    and counters that pipeline() of the same request gives."""
    outcomes = []
    for direct in (True, False):
        link, client = make(timeout_s=0.05)
        _set_up(case, link)
        try:
            if direct:
                result: object = client.request(MspCommand.ATTITUDE)
            else:
                result = client.pipeline([MspRequest(MspCommand.ATTITUDE)])[0]
                if isinstance(result, Exception):
                    raise result
        except (MspErrorReply, MspTimeoutError) as exc:
            result = type(exc)
        outcomes.append((result, client.stats, link.sent_commands))
    assert outcomes[0] == outcomes[1]
    if case in ("plain", "dropped", "corrupted", "garbage first", "echoed"):
        assert outcomes[0][0] == ATT.encode()  # it is a path to the answer, not around it


def test_a_lone_request_after_a_timeout_goes_through_the_pipeline_for_its_ghost() -> None:
    """A late reply to a request that timed out must not be taken for the next request's:
    with a ghost on the wire, request() leaves the direct path and the ghost absorbs it."""
    link, client = make(timeout_s=0.05)
    link.reply_delay_s[MspCommand.ATTITUDE] = 0.08
    with pytest.raises(MspTimeoutError):
        client.request(MspCommand.ATTITUDE, retries=0)
    link.reply_delay_s.clear()
    link.handlers[MspCommand.ATTITUDE] = fixed(msg.Attitude(1, 2, 3).encode())
    assert client.request(MspCommand.ATTITUDE) == msg.Attitude(1, 2, 3).encode()
    assert client.stats.late_replies == 1
