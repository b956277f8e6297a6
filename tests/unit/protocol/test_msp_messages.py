"""MSP payload codecs against byte strings written out by hand from the 4.6.0 firmware layouts.

Every literal below was built field by field from ``src/main/msp/msp.c`` (or copied from bytes
a stock SITL sent, ``docs/firmware-facts.md#recorded-replies``), not produced by the encoder
under test.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bfsitl.errors import MspDecodeError, MspFrameError
from bfsitl.protocol import messages as m
from bfsitl.protocol.arming import ArmingFlag
from bfsitl.protocol.msp_codes import MspCommand


def h(text: str) -> bytes:
    """Spaced hex, grouped by field, so each literal reads like the firmware layout."""
    return bytes.fromhex(text.replace(" ", ""))


# MSP_STATUS_EX recorded from a stock 4.6.0 SITL (docs/firmware-facts.md#recorded-replies).
STATUS_EX_SITL = h("9100 0000 2300 00000000 00 0000 04 00 00 1d 04030000 00 0000 04")
# The same state as MSP_STATUS: U16 0 instead of pidProfileCount/rateProfileIndex.
STATUS_SITL = h("9100 0000 2300 00000000 00 0000 0000 00 1d 04030000 00 0000 04")

BOARD_INFO_SITL = (
    b"SITL"  # board id
    + h("0000")  # hardware revision
    + h("00")  # fc type
    + h("00")  # capabilities
    + b"\x04SITL"  # target name
    + h("00")  # board name ""
    + h("00")  # manufacturer ""
    + bytes(32)  # signature
    + h("00")  # mcu type
    + h("01")  # configuration state
    + h("401f")  # gyro 8000 Hz
    + h("00000000")  # problems
    + h("00 00")  # spi, i2c
)

BOXNAMES_SITL = (
    b"ARM;ANGLE;HORIZON;HEADFREE;FAILSAFE;HEADADJ;BEEPER;OSD DISABLE;BLACKBOX;FPV ANGLE MIX;"
    b"CAMERA CONTROL 1;CAMERA CONTROL 2;CAMERA CONTROL 3;PREARM;PARALYZE;LAUNCH CONTROL;"
    b"STICK COMMANDS DISABLE;BEEPER MUTE;READY;"
)
BOXIDS_SITL = bytes([0, 1, 2, 6, 27, 7, 13, 19, 26, 30, 32, 33, 34, 36, 45, 49, 51, 52, 53])

MODE_RANGES_ARM_AUX1 = h("00 00 20 30") + bytes(4 * 19)


# (class, full payload, shortest accepted length, tolerates appended bytes)
SAMPLES: list[tuple[type, bytes, int, bool]] = [
    (m.ApiVersion, h("00 01 2f"), 3, True),
    (m.FcVariant, b"BTFL", 4, True),
    (m.FcVersion, h("04 06 00"), 3, False),
    (m.FcVersion, h("1a 0c 00 0f") + b"2026.12.0-alpha", 3, False),
    (m.BoardInfo, BOARD_INFO_SITL, 4 + 2 + 1 + 1 + 1, True),
    (m.BuildInfo, b"Nov 21 2026" + b"14:42:00" + b"abcdef0" + h("1f40 2b20"), 26, False),
    (m.McuInfo, b"\x00\x09SIMULATOR", 2, True),
    (m.CraftName, b"quad", 0, False),
    (m.Uid, h("00000000 01000000 02000000"), 12, True),
    (m.Status, STATUS_SITL, 22, True),
    (m.StatusEx, STATUS_EX_SITL, 22, True),
    (m.RawImu, h("0000 0000 0001  ab03 0000 55fc  0000 0000 0000"), 18, True),
    (m.Motor, h("e803 e803 e803 e803 0000 0000 0000 0000"), 16, True),
    (m.Rc, h("dc05 dc05 dc05 7503") + h("dc05") * 14, 8, False),
    (m.Rc, b"", 0, False),
    (m.RawGps, h("02 0c 404b4c00 80969800 6400 2c01 0807 9600"), 16, True),
    (m.Attitude, h("f1ff 6400 6701"), 6, True),
    (m.Altitude, h("11040000 fbff"), 6, True),
    (m.Analog, h("a8 0201 ff03 6aff 9006"), 7, True),
    (m.BatteryState, h("04 dc05 a8 0000 0000 00 9006"), 9, True),
    (m.SensorConfigActive, h("01 02 03 ff 00 ff"), 6, True),
    (m.Debug, h("0100 ffff 0300 0000 0000 0000 0000 0080"), 0, False),
    (m.MotorTelemetry, h("01 10270000 1027 1e 9006 f401 0a00"), 1, True),
    (m.ArmingConfig, h("05 00 19 00"), 4, True),
    (m.SetArmingConfig, h("05 00 19 01"), 4, True),
    (m.FeatureConfig, h("00404010"), 4, True),
    (m.SetFeatureConfig, h("00404010"), 4, True),
    (m.RxMap, h("00 01 03 02 04 05 06 07"), 8, True),
    (m.SetRxMap, h("03 00 01 02 04 05 06 07"), 8, True),
    (m.BoxNames, BOXNAMES_SITL, 0, False),
    (m.BoxIds, BOXIDS_SITL, 0, False),
    (m.ModeRanges, MODE_RANGES_ARM_AUX1, 0, False),
    (m.SetModeRange, h("03 01 01 00 30 01 00"), 5, True),
    (m.SetRawRc, h("4c04 b004 1405 7805"), 2, False),
    (m.EepromWrite, b"", 0, True),
    (m.Reboot, h("00"), 0, True),
    (m.RebootReply, h("02 01"), 1, True),
    (m.SetRtc, h("00f15365 fa00"), 6, True),
    (m.Rtc, h("e807 03 05 0a 14 1e c801"), 9, True),
    (m.MultipleMspRequest, bytes([116, 116, 101]), 1, False),
    (m.MultipleMspReply, h("03 00012f 00 04") + b"BTFL", 0, False),
]


def _name(value: object) -> str:
    return getattr(value, "__name__", "")


ROUND_TRIP = [(cls, payload) for cls, payload, _, _ in SAMPLES]
SHORT = [(cls, payload, min_len) for cls, payload, min_len, _ in SAMPLES if min_len]


@pytest.mark.parametrize(("cls", "payload"), ROUND_TRIP, ids=_name)
def test_round_trip_is_byte_exact(cls: Any, payload: bytes) -> None:
    msg = cls.decode(payload)
    assert isinstance(msg, cls)
    assert msg.encode() == payload


@pytest.mark.parametrize(("cls", "payload", "min_len"), SHORT, ids=_name)
def test_short_payloads_raise_decode_error(cls: Any, payload: bytes, min_len: int) -> None:
    for size in range(min_len):
        if cls in (m.Rtc, m.Rc) and size == 0:
            continue  # empty = clock not set / no channels yet, tested below
        with pytest.raises(MspDecodeError):
            cls.decode(payload[:size])


def test_master_fc_version_carries_its_calendar_version_string() -> None:
    version = m.FcVersion.decode(h("1a 0c 00 0f") + b"2026.12.0-alpha")
    assert (version.major, version.minor, version.text) == (26, 12, "2026.12.0-alpha")
    assert m.FcVersion.decode(h("04 06 00")).text == "4.6.0"


def test_an_empty_rc_reply_means_no_channels_yet() -> None:
    """Master's UDP receiver reports no channels until the first RC packet."""
    rc = m.Rc.decode(b"")
    assert not rc.has_channels and rc.throttle_us == 0
    with pytest.raises(MspDecodeError, match="0 or at least 4"):
        m.Rc.decode(h("dc05 dc05"))


def test_raw_gps_decodes_degrees_and_speed() -> None:
    gps = m.RawGps.decode(h("02 0c 404b4c00 80969800 6400 2c01 0807 9600"))
    assert gps.has_fix and gps.satellites == 12
    assert gps.lat_deg == pytest.approx(0.5) and gps.lon_deg == pytest.approx(1.0)
    assert gps.altitude_m == 100 and gps.ground_speed_m_s == pytest.approx(3.0)


TOLERANT = [(cls, payload) for cls, payload, _, tolerant in SAMPLES if tolerant]


@pytest.mark.parametrize(("cls", "payload"), TOLERANT, ids=_name)
def test_trailing_bytes_are_ignored(cls: Any, payload: bytes) -> None:
    """Newer firmware appends fields; layouts that end in a fixed field must ignore them."""
    assert cls.decode(payload + h("aa bb cc dd")) == cls.decode(payload)


def test_every_command_matches_its_msp_code() -> None:
    expected = {
        m.ApiVersion: MspCommand.API_VERSION,
        m.StatusEx: MspCommand.STATUS_EX,
        m.Status: MspCommand.STATUS,
        m.SetRawRc: MspCommand.SET_RAW_RC,
        m.SensorConfigActive: 0x300A,
        m.Rtc: 247,
        m.SetRtc: 246,
        m.Uid: 160,
        m.ArmingConfig: 61,
        m.FeatureConfig: 36,
        m.MultipleMspRequest: 230,
        m.MultipleMspReply: 230,
        m.RebootReply: 68,
        m.CraftName: 10,
    }
    for cls, command in expected.items():
        assert cls.COMMAND == command, cls.__name__
    for command, cls in m.REPLY_TYPES.items():
        assert cls.COMMAND == command
    assert m.REPLY_TYPES[150] is m.StatusEx
    assert m.REQUEST_TYPES[200] is m.SetRawRc


# ---------------------------------------------------------------------------------------------
# values


def test_identity_messages() -> None:
    api = m.ApiVersion.decode(h("00 01 2f"))
    assert (api.protocol_version, api.api) == (0, (1, 47))
    assert api.api >= (1, 46)
    assert m.FcVariant.decode(b"BTFL").identifier == "BTFL"
    assert m.FcVersion.decode(h("04 06 00")).text == "4.6.0"
    mcu = m.McuInfo.decode(b"\x00\x09SIMULATOR")
    assert (mcu.mcu_type_id, mcu.name) == (0, "SIMULATOR")
    assert m.CraftName.decode(b"").name == ""
    assert m.CraftName.decode(b"quad").name == "quad"
    uid = m.Uid.decode(h("00000000 01000000 02000000"))
    assert uid.uid == (0, 1, 2)
    assert uid.text == "000000000000000100000002"


def test_board_info_sitl() -> None:
    info = m.BoardInfo.decode(BOARD_INFO_SITL)
    assert len(BOARD_INFO_SITL) == 57
    assert info.board_id == "SITL"
    assert info.target_name == "SITL"
    assert info.board_name == "" and info.manufacturer_id == ""
    assert info.signature == bytes(32)
    assert info.configuration_state == 1
    assert info.gyro_sample_rate_hz == 8000
    assert info.configuration_problems == 0 and info.problems == ()
    assert (info.spi_device_count, info.i2c_device_count) == (0, 0)


def test_board_info_old_firmware_has_no_tail() -> None:
    old = m.BoardInfo.decode(b"ABCD" + h("0100 02 41") + b"\x03FOO")
    assert (old.hardware_revision, old.fc_type, old.target_capabilities) == (1, 2, 0x41)
    assert old.target_name == "FOO"
    assert old.board_name is None and old.i2c_device_count is None
    assert old.encode() == b"ABCD" + h("0100 02 41") + b"\x03FOO"


def test_board_info_half_a_tail_field_is_an_error() -> None:
    with pytest.raises(MspDecodeError):
        m.BoardInfo.decode(BOARD_INFO_SITL[:-7])  # cuts the U16 gyro rate in half


def test_board_info_problem_names() -> None:
    payload = BOARD_INFO_SITL[:-6] + h("03000000 00 00")
    assert m.BoardInfo.decode(payload).problems == (
        "ACC_NEEDS_CALIBRATION",
        "MOTOR_PROTOCOL_DISABLED",
    )


def test_build_info() -> None:
    info = m.BuildInfo.decode(b"Nov 21 2026" + b"14:42:00" + b"abcdef0" + h("1f40 2b20"))
    assert (info.date, info.time, info.git_revision) == ("Nov 21 2026", "14:42:00", "abcdef0")
    assert info.build_options == (16415, 8235)
    assert info.option_names == ("MAG", "PWM_OUTPUT")


def test_build_info_without_git_stops_at_nul_and_odd_tail_is_an_error() -> None:
    # Seen on a build without git metadata: the revision field over-reads "\0HORIZO".
    info = m.BuildInfo.decode(b"Nov 21 2026" + b"14:42:00" + b"\x00HORIZO")
    assert info.git_revision == "" and info.build_options == ()
    with pytest.raises(MspDecodeError):
        m.BuildInfo.decode(b"Nov 21 2026" + b"14:42:00" + b"abcdef0" + h("1f"))


def test_status_ex_sitl_capture() -> None:
    status = m.StatusEx.decode(STATUS_EX_SITL)
    assert status.cycle_time_us == 145
    assert status.i2c_errors == 0
    assert status.sensors == ("ACC", "BARO", "GYRO")
    assert status.flight_mode_flags == 0 and not status.armed
    assert (status.pid_profile, status.pid_profile_count, status.rate_profile_index) == (0, 4, 0)
    assert status.arming_disable_flag_count == 29
    assert status.arming_disable_flags == 0x304
    assert [f.name for f in status.arming_blockers] == ["RX_FAILSAFE", "ANGLE", "BOOT_GRACE_TIME"]
    assert [f.cli_name for f in status.arming_blockers] == ["RXLOSS", "ANGLE", "BOOTGRACE"]
    assert status.config_state == 0 and not status.reboot_required
    assert status.cpu_temp_c == 0
    assert status.rate_profile_count == 4


def test_status_and_status_ex_differ_only_in_the_middle() -> None:
    status = m.Status.decode(STATUS_SITL)
    ex = m.StatusEx.decode(STATUS_EX_SITL)
    for name in ("cycle_time_us", "sensors_mask", "arming_disable_flags", "rate_profile_count"):
        assert getattr(status, name) == getattr(ex, name)
    assert not hasattr(status, "pid_profile_count")
    assert (ex.pid_profile_count, ex.rate_profile_index) == (4, 0)
    assert status.encode() == STATUS_SITL  # the U16 0 is written back, not the profile count


def test_status_extra_flight_mode_bytes_are_combined() -> None:
    # armed (bit 0) + ANGLE (bit 1), and one extra byte with bit 32 and bit 39 set.
    payload = h("7d00 0000 2100 03000000 01 0a00 0000 01 81 1d 00000000 01")
    status = m.Status.decode(payload)
    assert status.flight_mode_flags == 0b11 | 1 << 32 | 1 << 39
    assert status.armed
    assert status.flight_mode_extra_bytes == 1
    assert status.cpu_load_percent == 10 and status.pid_profile == 1
    assert status.reboot_required
    assert status.cpu_temp_c is None and status.rate_profile_count is None  # API < 1.46
    assert status.encode() == payload


def test_status_keeps_an_all_zero_extra_byte() -> None:
    # 33..40 active boxes: N = 1 even when none of the high modes is on.
    payload = h("7d00 0000 2100 00000000 00 0000 0000 01 00 1d 00000000 00 2800 03")
    status = m.Status.decode(payload)
    assert status.flight_mode_flags == 0
    assert status.cpu_temp_c == 40 and status.rate_profile_count == 3
    assert status.encode() == payload


def test_status_encode_grows_extra_bytes_for_high_flags() -> None:
    status = m.Status(125, 0, 0x21, 1 << 40, 0, 0, 29, 0, 0)
    decoded = m.Status.decode(status.encode())
    assert decoded.flight_mode_flags == 1 << 40
    assert decoded.flight_mode_extra_bytes == 2


def test_status_negative_cpu_temperature() -> None:
    payload = STATUS_SITL[:-3] + h("f6ff 04")
    assert m.Status.decode(payload).cpu_temp_c == -10


def test_raw_imu_units() -> None:
    imu = m.RawImu.decode(h("0000 0000 0001  ab03 0000 55fc  0000 0000 0000"))
    assert imu.acc_raw == (0, 0, 256)
    assert imu.gyro_raw == (939, 0, -939)
    assert imu.mag_raw == (0, 0, 0)
    assert imu.acc_g() == (0.0, 0.0, 1.0)
    assert imu.acc_g(2048)[2] == pytest.approx(0.125)
    roll_dps = imu.gyro_dps()[0]
    assert roll_dps == pytest.approx(math.degrees(1.0), abs=0.05)  # 1 rad/s in the SITL test
    assert imu.gyro_dps()[2] == pytest.approx(-roll_dps)
    assert m.SITL_ACC_1G_LSB == 256 and m.GYRO_LSB_PER_DPS == 16.384


def test_motor() -> None:
    motor = m.Motor.decode(h("e803 e803 e803 e803 0000 0000 0000 0000"))
    assert motor.motors_us == (1000,) * 4 + (0,) * 4
    assert m.Motor((1055,) * 4).encode() == h("1f04 1f04 1f04 1f04 0000 0000 0000 0000")
    with pytest.raises(MspFrameError):
        m.Motor((1000,) * 9).encode()


def test_rc_is_internal_order() -> None:
    rc = m.Rc.decode(h("dc05 dc05 dc05 7503") + h("dc05") * 14)
    assert len(rc.channels_us) == 18
    assert (rc.roll_us, rc.pitch_us, rc.yaw_us, rc.throttle_us) == (1500, 1500, 1500, 885)
    assert rc.aux_us == (1500,) * 14
    with pytest.raises(MspDecodeError):
        m.Rc.decode(h("dc05 dc05 dc05 7503 dc"))  # half a channel


def test_attitude_units() -> None:
    att = m.Attitude.decode(h("f1ff 6400 6701"))
    assert (att.roll_decideg, att.pitch_decideg, att.yaw_deg) == (-15, 100, 359)
    assert att.roll_deg == -1.5
    assert att.pitch_deg == 10.0  # nose down
    assert att.yaw_deg == 359  # whole degrees, not decidegrees


def test_altitude_units() -> None:
    alt = m.Altitude.decode(h("11040000 fbff"))
    assert (alt.altitude_cm, alt.vario_cm_s) == (1041, -5)
    assert alt.altitude_m == pytest.approx(10.41)
    assert alt.vario_m_s == pytest.approx(-0.05)
    assert m.Altitude.decode(h("ecffffff 0000")).altitude_m == pytest.approx(-0.2)


def test_analog_prefers_centivolts() -> None:
    analog = m.Analog.decode(h("ff 0201 ff03 6aff 7c0b"))
    assert analog.vbat_dv == 255  # clamped at 25.5 V
    assert analog.vbat_cv == 2940
    assert analog.battery_v == pytest.approx(29.40)
    assert analog.mah_drawn == 0x0102
    assert analog.rssi == 1023 and analog.rssi_percent == pytest.approx(100.0)
    assert analog.amperage_ca == -150 and analog.amperage_a == pytest.approx(-1.5)
    old = m.Analog.decode(h("a8 0000 0000 0000"))
    assert old.vbat_cv is None and old.battery_v == pytest.approx(16.8)
    assert old.encode() == h("a8 0000 0000 0000")


def test_battery_state() -> None:
    bat = m.BatteryState.decode(h("04 dc05 a8 0a00 c8ff 01 9206"))
    assert (bat.cell_count, bat.capacity_mah, bat.mah_drawn) == (4, 1500, 10)
    assert bat.battery_v == pytest.approx(16.82)
    assert bat.amperage_a == pytest.approx(-0.56)
    assert bat.state_name == "WARNING"
    assert m.BatteryState.decode(h("00 0000 00 0000 0000 09")).state_name == "UNKNOWN_9"


def test_sensor_config_active() -> None:
    cfg = m.SensorConfigActive.decode(h("01 02 03 ff 00 ff"))
    assert (cfg.gyro_hw, cfg.acc_hw, cfg.baro_hw) == (1, 2, 3)
    assert cfg.mag_hw == m.SENSOR_NOT_BUILT
    assert (cfg.rangefinder_hw, cfg.opticalflow_hw) == (0, 0xFF)


def test_debug_is_signed() -> None:
    assert m.Debug.decode(h("0100 ffff 0300 0000 0000 0000 0000 0080")).values == (
        1, -1, 3, 0, 0, 0, 0, -32768,
    )  # fmt: skip


def test_motor_telemetry() -> None:
    sitl = m.MotorTelemetry.decode(h("04") + bytes(4 * 13))
    assert len(sitl.motors) == 4 and sitl.motors[0].rpm == 0
    tel = m.MotorTelemetry.decode(h("01 10270000 1027 1e 9006 f401 0a00"))
    motor = tel.motors[0]
    assert motor.rpm == 10000
    assert motor.invalid_percent == pytest.approx(100.0)
    assert motor.temperature_c == 30
    assert motor.voltage_v == pytest.approx(16.8)
    assert motor.current_a == pytest.approx(5.0)
    assert motor.consumption_mah == 10
    with pytest.raises(MspDecodeError):
        m.MotorTelemetry.decode(h("02") + bytes(13))  # count says 2, one present


def test_arming_and_feature_config() -> None:
    arming = m.ArmingConfig.decode(h("05 00 19 00"))
    assert (arming.auto_disarm_delay_s, arming.small_angle_deg, arming.gyro_cal_on_first_arm) == (
        5, 25, 0,
    )  # fmt: skip
    assert m.SetArmingConfig(5, 30, 0).encode() == h("05 00 1e 00")
    features = m.FeatureConfig.decode(h("00404010"))
    assert features.feature_mask == 0x10404000
    assert features.features == ("RX_MSP", "AIRMODE", "ANTI_GRAVITY")
    assert m.FeatureConfig(1 << 17 | 1 << 30).features == ("DISPLAY", "BIT30")


def test_rx_map_letters() -> None:
    rx_map = m.RxMap.decode(h("00 01 03 02 04 05 06 07"))
    assert rx_map.rcmap == m.DEFAULT_RCMAP
    assert rx_map.letters == "AETR1234"
    taer = m.RxMap.from_letters("taer1234")
    assert taer.rcmap == (1, 2, 3, 0, 4, 5, 6, 7)
    assert taer.letters == "TAER1234"
    with pytest.raises(MspFrameError):
        m.RxMap.from_letters("AETR1233")
    with pytest.raises(MspFrameError):
        m.SetRxMap((0, 1, 2, 3, 4, 5, 6, 9))
    with pytest.raises(MspDecodeError):
        m.SetRxMap.decode(h("00 00 00 00 00 00 00 00"))


def test_box_names_and_ids() -> None:
    names = m.BoxNames.decode(BOXNAMES_SITL).names
    assert len(names) == 19
    assert names[0] == "ARM" and names[4] == "FAILSAFE" and names[-1] == "READY"
    assert m.BoxNames.decode(b"").names == ()
    assert m.BoxIds.decode(BOXIDS_SITL).ids[4] == 27


def test_mode_ranges() -> None:
    ranges = m.ModeRanges.decode(MODE_RANGES_ARM_AUX1)
    assert len(ranges.ranges) == 20
    arm = ranges.ranges[0]
    assert (arm.box_id, arm.aux_channel_index) == (0, 0)
    assert (arm.start_us, arm.end_us) == (1700, 2100)
    assert arm.is_used
    assert not ranges.ranges[1].is_used  # all-zero slot: ARM with an empty range
    assert ranges.used == ((0, arm),)
    with pytest.raises(MspDecodeError):
        m.ModeRanges.decode(MODE_RANGES_ARM_AUX1[:-1])


def test_mode_range_from_us() -> None:
    assert m.ModeRange.from_us(0, 0, 1700, 2100) == m.ModeRange(0, 0, 32, 48)
    assert m.ModeRange.from_us(1, 13, 900, 925) == m.ModeRange(1, 13, 0, 1)
    for start, end in ((1690, 2100), (875, 1000), (1700, 2125), (1800, 1800), (1900, 1800)):
        with pytest.raises(MspFrameError):
            m.ModeRange.from_us(0, 0, start, end)
    with pytest.raises(ValueError):  # also a ValueError
        m.ModeRange.from_us(0, 14, 1700, 2100)


def test_set_mode_range() -> None:
    req = m.SetModeRange.decode(h("00 00 00 20 30"))
    assert req == m.SetModeRange(0, m.ModeRange.from_us(0, 0, 1700, 2100))
    linked = m.SetModeRange(3, m.ModeRange(1, 1, 0, 48), mode_logic=1, linked_to=0)
    assert linked.encode() == h("03 01 01 00 30 01 00")
    assert m.SetModeRange.decode(h("03 01 01 00 30 01 00")) == linked
    with pytest.raises(MspFrameError):
        m.SetModeRange(20, m.ModeRange(0, 0, 32, 48))
    with pytest.raises(MspFrameError):
        m.SetModeRange(0, m.ModeRange(0, 0, 32, 48), mode_logic=0)
    with pytest.raises(MspFrameError):
        m.SetModeRange(0, m.ModeRange(0, 0, 32, 48), mode_logic=0, linked_to=9)  # retired id
    with pytest.raises(MspDecodeError):
        m.SetModeRange.decode(h("14 00 00 20 30"))  # slot 20


def test_set_raw_rc_aetr_order() -> None:
    # Verified on SITL: SET_RAW_RC 1100,1200,1300,1400 read back by MSP_RC as 1100,1200,1400,1300.
    req = m.SetRawRc.from_sticks(roll_us=1100, pitch_us=1200, yaw_us=1400, throttle_us=1300)
    assert req.channels_us == (1100, 1200, 1300, 1400)
    assert req.encode() == h("4c04 b004 1405 7805")
    with_aux = m.SetRawRc.from_sticks(1500, 1500, 1500, 1000, aux_us=(1800, 1000, 1000, 1000))
    assert with_aux.channels_us == (1500, 1500, 1000, 1500, 1800, 1000, 1000, 1000)
    taer = m.SetRawRc.from_sticks(1, 2, 3, 4, rcmap=m.RxMap.from_letters("TAER1234").rcmap)
    assert taer.channels_us == (4, 1, 2, 3)


def test_set_raw_rc_validation() -> None:
    assert len(m.SetRawRc((1500,) * 18).encode()) == 36
    for bad in ((1500,) * 19, (), (70000,), (-1, 1500)):
        with pytest.raises(MspFrameError):
            m.SetRawRc(bad)
    with pytest.raises(MspFrameError):
        m.SetRawRc.from_sticks(1500, 1500, 1500, 1000, rcmap=(0, 1, 2, 3, 4, 5, 6, 6))
    with pytest.raises(MspDecodeError):
        m.SetRawRc.decode(h("dc05") * 19)


def test_control_messages() -> None:
    assert m.EepromWrite().encode() == b""
    assert m.Reboot().encode() == h("00")
    assert m.Reboot.decode(b"").mode == m.RebootMode.FIRMWARE
    assert m.Reboot(m.RebootMode.BOOTLOADER_ROM).encode() == h("01")
    assert m.RebootReply.decode(h("02 01")) == m.RebootReply(2, msc_ready=1)


def test_rtc() -> None:
    req = m.SetRtc.from_timestamp(1700000000.25)
    assert (req.unix_seconds, req.millis) == (1700000000, 250)
    assert req.encode() == h("00f15365 fa00")
    with pytest.raises(MspFrameError):
        m.SetRtc(-1)
    with pytest.raises(MspFrameError):
        m.SetRtc(0, 1000)
    rtc = m.Rtc.decode(h("e807 03 05 0a 14 1e c801"))
    assert (rtc.year, rtc.month, rtc.day, rtc.hours, rtc.minutes, rtc.seconds) == (
        2024, 3, 5, 10, 20, 30,
    )  # fmt: skip
    assert rtc.millis == 456
    assert rtc.datetime_utc == datetime(2024, 3, 5, 10, 20, 30, 456000, tzinfo=UTC)
    unset = m.Rtc.decode(b"")
    assert not unset.is_set and unset.datetime_utc is None and unset.encode() == b""


def test_multiple_msp_request_validation() -> None:
    assert m.MultipleMspRequest((116, 116, 101)).encode() == bytes([116, 116, 101])
    assert len(m.MultipleMspRequest((101,) * 192).encode()) == 192
    for bad in ((), (101,) * 193, (255,), (-1,), (0x300A,)):
        with pytest.raises(MspFrameError):
            m.MultipleMspRequest(bad)


def test_multiple_msp_reply() -> None:
    reply = m.MultipleMspReply.decode(h("03 00012f 00 04") + b"BTFL")
    assert reply.payloads == (h("00012f"), b"", b"BTFL")
    api, failed, variant, missing = reply.decode_replies([1, 23, 2, 3])
    assert api == m.ApiVersion(0, 1, 47)
    assert failed is None and missing is None
    assert variant == m.FcVariant("BTFL")
    with pytest.raises(MspDecodeError):
        m.MultipleMspReply.decode(h("05 0001"))  # length runs past the end
    with pytest.raises(MspDecodeError):
        m.MultipleMspReply.decode(h("01 00")).decode_replies([101])  # garbage, not a failure


def test_decode_reply_dispatch() -> None:
    status = m.decode_reply(MspCommand.STATUS_EX, STATUS_EX_SITL)
    assert isinstance(status, m.StatusEx)
    assert ArmingFlag.ANGLE.mask & status.arming_disable_flags
    with pytest.raises(MspDecodeError):
        m.decode_reply(0x4242, b"")
    with pytest.raises(MspDecodeError):
        m.decode_request(MspCommand.STATUS, b"")
    assert m.decode_request(MspCommand.SET_RAW_RC, h("dc05")) == m.SetRawRc((1500,))


def test_encode_reports_fields_that_do_not_fit() -> None:
    with pytest.raises(MspFrameError):
        m.Attitude(40000, 0, 0).encode()
    with pytest.raises(MspFrameError):
        m.FcVariant("BETAFLIGHT").encode()
    with pytest.raises(MspFrameError):
        m.CraftName("\u2708").encode()


def test_messages_are_frozen_with_slots() -> None:
    msg = m.Attitude(1, 2, 3)
    with pytest.raises(AttributeError):
        msg.roll_decideg = 5  # type: ignore[misc]
    assert not hasattr(msg, "__dict__")


# ---------------------------------------------------------------------------------------------
# property: random bytes never escape as anything but MspDecodeError

ALL_TYPES = sorted(
    {*m.REPLY_TYPES.values(), *m.REQUEST_TYPES.values()}, key=lambda cls: cls.__name__
)


@pytest.mark.parametrize("cls", ALL_TYPES, ids=lambda cls: cls.__name__)
@settings(max_examples=150, deadline=None)
@given(payload=st.binary(max_size=300))
def test_random_bytes_only_raise_decode_error(cls: Any, payload: bytes) -> None:
    try:
        msg = cls.decode(payload)
    except MspDecodeError:
        return
    # Whatever decodes re-encodes to bytes that decode to the same message.
    assert cls.decode(msg.encode()) == msg


@settings(max_examples=300, deadline=None)
@given(command=st.sampled_from(sorted(m.REPLY_TYPES)), payload=st.binary(max_size=120))
def test_decode_reply_random(command: int, payload: bytes) -> None:
    try:
        m.decode_reply(command, payload)
    except MspDecodeError:
        pass


@settings(max_examples=200, deadline=None)
@given(
    commands=st.lists(st.sampled_from(sorted(c for c in m.REPLY_TYPES if c < 255)), max_size=6),
    payload=st.binary(max_size=200),
)
def test_multiple_msp_decode_replies_random(commands: list[int], payload: bytes) -> None:
    try:
        m.MultipleMspReply.decode(payload).decode_replies(commands)
    except MspDecodeError:
        pass


def test_short_payload_messages_name_the_first_missing_byte() -> None:
    """As the field-by-field readers said it, though the codecs now read runs of fields."""
    cases = [
        (m.Attitude, h("f1ff 64"), "MSP Attitude: needs at least 4 bytes, got 3"),
        (m.RawImu, bytes(7), "MSP RawImu: needs at least 8 bytes, got 7"),
        (m.Analog, h("a8 0201 ff03 6aff 90"), "MSP Analog: needs at least 9 bytes, got 8"),
        (m.StatusEx, STATUS_EX_SITL[:20], "MSP StatusEx: needs at least 21 bytes, got 20"),
        (
            m.Status,
            h("7d00 0000 2100 03000000 01 0a00 0000 02 81"),
            "MSP Status: needs at least 18 bytes, got 17",
        ),
        (m.ArmingConfig, h("05"), "MSP ArmingConfig: needs at least 2 bytes, got 1"),
        (m.SetArmingConfig, h("05 00 19"), "MSP SetArmingConfig: needs at least 4 bytes, got 3"),
        (
            m.BoardInfo,
            b"SITL" + h("0000 00 00 05") + b"SIT",
            "MSP BoardInfo: needs at least 14 bytes, got 12",
        ),
        (
            m.MotorTelemetry,
            h("01 10270000 10"),
            "MSP MotorTelemetry: needs at least 7 bytes, got 6",
        ),
        (m.MultipleMspReply, h("05 0001"), "MSP MultipleMspReply: needs at least 6 bytes, got 3"),
        (
            m.BuildInfo,
            b"Nov 21 2026" + b"14:42:00" + b"abcdef0" + h("1f"),
            "MSP BuildInfo options: 1 bytes is not a whole number of 2-byte items",
        ),
        (m.ModeRanges, bytes(5), "MSP ModeRanges: 5 bytes is not a whole number of 4-byte items"),
    ]
    for cls, payload, message in cases:
        with pytest.raises(MspDecodeError) as caught:
            cls.decode(payload)
        assert str(caught.value) == message, cls.__name__


def test_optional_tails_half_present_and_read_only_when_whole() -> None:
    with pytest.raises(MspDecodeError, match="needs at least 9 bytes, got 8"):
        m.Analog.decode(h("a8 0201 ff03 6aff 90"))  # half the 0.01 V field: broken
    gps = h("02 0c 404b4c00 80969800 6400 2c01 0807")
    assert m.RawGps.decode(gps + h("96")).pdop is None  # PDOP was always read only when whole
    tuning = h("07 00 43 44 43 00 00 00 00 00 00 07 08 05")
    assert m.RcTuning.decode(tuning + bytes(8)).rates_type is None
    assert m.RcTuning.decode(tuning + bytes(8) + h("03")).rates_type == m.RcTuning.ACTUAL
    assert m.RcTuning(7, 0, 67, 68, 67, 0, 7, 8, 5, 3).encode() == tuning + bytes(8) + h("03")


def test_values_that_do_not_fit_are_request_errors_everywhere() -> None:
    """Also where bytes() used to raise a bare ValueError; MspRequestError is a ValueError."""
    for bad in (
        lambda: m.BoxIds((256,)).encode(),
        lambda: m.RxMap((0,) * 7 + (256,)).encode(),
        lambda: m.McuInfo(0, "x" * 256).encode(),
        lambda: m.PidAdvanced(256).encode(),
        lambda: m.Uid((1, 2)).encode(),
        lambda: m.RawImu((0, 0), (0, 0, 0), (0, 0, 0)).encode(),
    ):
        with pytest.raises(MspFrameError):
            bad()
    with pytest.raises(MspFrameError, match="a channel map has 8 entries, got 7"):
        m.RxMap((0,) * 7).encode()
    with pytest.raises(MspFrameError, match="signature must be 32 bytes, got 3"):
        m.BoardInfo("SITL", 0, 0, 0, "SITL", "", "", b"abc").encode()
    with pytest.raises(MspFrameError):
        m.Reboot(None).encode()  # type: ignore[arg-type]  # the mode is always written
