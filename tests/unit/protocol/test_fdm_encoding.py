"""Firmware profiles and the fdm encoding: what each generation makes of what bfsitl sends.

Each test decodes the packet the way that generation's ``sitl.c`` does (re-stated here from the
firmware source, not from our encoder) and checks that the firmware ends up with the same,
physically right, sensors: a wrong sign, axis or quaternion convention fails one of them.
"""

from __future__ import annotations

import math

import pytest

from bfsitl.errors import UnsupportedFirmwareError
from bfsitl.physics import GeoPoint, Simulator
from bfsitl.physics.frames import (
    betaflight_attitude_deg,
    quat_from_euler_deg,
)
from bfsitl.protocol.arming import arming_flags_text, decode_arming_flags
from bfsitl.protocol.fdm_encoding import GPS_LOST_LON_LAT, FdmEncoder, gazebo_quaternion
from bfsitl.protocol.firmware_profile import (
    DEFAULT_PROFILE,
    BuildOptions,
    Generation,
    profile_for,
)
from bfsitl.protocol.sitl_packets import FdmPacket, ServoPacket

HOME = GeoPoint(47.3977, 8.5456, 488.0)
V46 = profile_for("1.47", "4.6.0", has_gps=False)
V46_GPS = profile_for("1.47", "4.6.0", has_gps=True)
MASTER = profile_for("1.49", "2026.12.0-alpha")


def moving_reading(roll_deg: float = 12.0, pitch_deg: float = -7.0, yaw_deg: float = 63.0):
    sim = Simulator(home=HOME)
    sim.reset(
        (30.0, -40.0, -12.0),
        roll_deg=roll_deg,
        pitch_deg=pitch_deg,
        yaw_deg=yaw_deg,
        velocity_ned_m_s=(3.0, 4.0, -1.5),
        angular_velocity_frd_rad_s=(0.1, -0.2, 0.3),
    )
    sim.hold(True)
    return sim.read_sensors()


# -- what each sitl.c does with a packet (from the firmware source) ----------------------------


def firmware_gyro(packet: FdmPacket, generation: Generation) -> tuple[float, float, float]:
    """4.6 sitl.c: (x, -y, -z); master sitl_gyro.h with the Gazebo bridge: (x, -y, +z)."""
    x, y, z = packet.gyro_rad_s
    return (x, -y, -z) if generation is Generation.V4_6 else (x, -y, z)


def firmware_acc(packet: FdmPacket) -> tuple[float, float, float]:
    """Both: every axis negated."""
    x, y, z = packet.accel_m_s2
    return (-x, -y, -z)


def master_attitude(packet: FdmPacket) -> tuple[float, float, float, float]:
    """master sitl.c ENABLE_GAZEBO_BRIDGE: negate qy, qz, then k * (w - z, x - y, y + x, z + w)."""
    w, x, y, z = packet.quaternion_wxyz
    y, z = -y, -z
    k = math.sqrt(0.5)
    return (k * (w - z), k * (x - y), k * (y + x), k * (z + w))


def euler_of_flu_to_nwu(q: tuple[float, float, float, float]) -> tuple[float, float, float]:
    """Betaflight's roll, pitch (nose down +), heading from its FLU -> NWU rotation matrix
    (imu.c: roll atan2(R21, R22), pitch asin(-R20), yaw -atan2(R10, R00))."""
    w, x, y, z = q
    r00 = 1 - 2 * (y * y + z * z)
    r10 = 2 * (x * y + w * z)
    r20 = 2 * (x * z - w * y)
    r21 = 2 * (y * z + w * x)
    r22 = 1 - 2 * (x * x + y * y)
    roll = math.degrees(math.atan2(r21, r22))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, -r20))))
    yaw = -math.degrees(math.atan2(r10, r00)) % 360.0
    return roll, pitch, yaw


# -- profiles ---------------------------------------------------------------------------------


def test_the_generation_comes_from_the_msp_api_version():
    assert profile_for("1.47", "4.6.0").generation is Generation.V4_6
    assert profile_for("1.46", "4.5.2").generation is Generation.V4_6
    assert profile_for("1.49", "2026.12.0-alpha").generation is Generation.MASTER
    assert profile_for("1.49", "2026.12.0-alpha").tested
    assert not profile_for("1.49", "2027.6.0").tested
    with pytest.raises(UnsupportedFirmwareError, match="API 1.44 is not supported"):
        profile_for("1.44", "4.4.0")
    with pytest.raises(UnsupportedFirmwareError, match="cannot read"):
        profile_for("banana")


def test_profiles_differ_where_the_firmware_source_says():
    assert (V46.takes_ip_flag, MASTER.takes_ip_flag) == (False, True)
    assert V46.motor_slot_of_betaflight_motor == (3, 0, 1, 2)
    assert MASTER.motor_slot_of_betaflight_motor == (0, 1, 2, 3)
    assert V46.rc.rxloss_after_silence_s is None and MASTER.rc.rxloss_after_silence_s == 0.15
    assert MASTER.rc.msp_rc_empty_before_rc and not V46.rc.msp_rc_empty_before_rc
    assert MASTER.cli.serial_read_only and not V46.cli.serial_read_only
    assert (V46.gyro_rate_hz, MASTER.gyro_rate_hz) == (8000, 1000)
    assert MASTER.fdm.attitude_estimated and not V46.fdm.attitude_estimated
    assert DEFAULT_PROFILE.generation is Generation.V4_6


def test_unsupported_master_build_variants_are_refused_with_what_works():
    with pytest.raises(UnsupportedFirmwareError, match="ENABLE_GAZEBO_BRIDGE=0"):
        profile_for("1.49", "2026.12.0-alpha", BuildOptions(gazebo_bridge=False))
    direct = profile_for("1.49", "2026.12.0-alpha", BuildOptions(attitude_direct=True))
    assert not direct.fdm.attitude_estimated


# -- the encoding -----------------------------------------------------------------------------


@pytest.mark.parametrize("profile", [V46, MASTER], ids=["4.6", "master"])
def test_the_firmware_gets_flu_rates_and_flu_specific_force(profile):
    reading = moving_reading()
    packet = FdmEncoder(profile, HOME).encode(reading, 1.0)
    wx, wy, wz = reading.gyro_frd_rad_s
    fx, fy, fz = reading.specific_force_frd_m_s2
    assert firmware_gyro(packet, profile.generation) == pytest.approx((wx, -wy, -wz))
    assert firmware_acc(packet) == pytest.approx((fx, -fy, -fz))


def test_level_at_rest_reads_plus_one_g_up_on_both():
    sim = Simulator()
    for profile in (V46, MASTER):
        packet = FdmEncoder(profile, GeoPoint(0.0, 0.0)).encode(sim.read_sensors(), 1.0)
        assert firmware_acc(packet) == pytest.approx((0.0, 0.0, 9.80665))


def test_4_6_takes_the_quaternion_and_the_pressure_as_they_are():
    reading = moving_reading()
    packet = FdmEncoder(V46, HOME).encode(reading, 1.0)
    assert packet.quaternion_wxyz == reading.quaternion_wxyz
    assert packet.pressure_pa == reading.pressure_pa
    assert packet.position == reading.position_ned_m  # ignored without GPS


@pytest.mark.parametrize(
    ("roll", "pitch", "yaw"),
    [(0, 0, 0), (20, 0, 0), (0, 15, 0), (0, 0, 90), (10, -10, 45), (-30, 25, 250)],
)
def test_master_reconstructs_the_true_attitude_from_the_gazebo_quaternion(roll, pitch, yaw):
    q = quat_from_euler_deg(roll, pitch, yaw)
    packet = FdmPacket(1.0, quaternion_wxyz=gazebo_quaternion(q))
    expected = betaflight_attitude_deg(q)
    got = euler_of_flu_to_nwu(master_attitude(packet))
    assert got[0] == pytest.approx(expected[0], abs=1e-6)
    assert got[1] == pytest.approx(expected[1], abs=1e-6)
    assert math.remainder(got[2] - expected[2], 360.0) == pytest.approx(0.0, abs=1e-6)


def test_the_gazebo_quaternion_is_not_the_plain_one():
    """Sending the 4.6 quaternion to master would turn the heading by 90 degrees."""
    q = quat_from_euler_deg(0, 0, 0)
    wrong = euler_of_flu_to_nwu(master_attitude(FdmPacket(1.0, quaternion_wxyz=q)))
    assert abs(math.remainder(wrong[2], 360.0)) == pytest.approx(90.0)


def test_master_barometer_altitude_turns_back_into_the_same_pressure():
    reading = moving_reading()
    packet = FdmEncoder(MASTER, HOME).encode(reading, 1.0)
    altitude_m = packet.position[2]
    firmware_pressure = 101325.0 * (1.0 - 2.25577e-5 * altitude_m) ** 5.25588
    assert firmware_pressure == pytest.approx(reading.pressure_pa, abs=1e-6)
    assert altitude_m == pytest.approx(HOME.alt_m + 12.0, abs=0.01)


def test_master_gps_is_mirrored_so_that_its_first_fix_mirror_gives_the_truth():
    encoder = FdmEncoder(MASTER, HOME)
    at_home = Simulator(home=HOME).read_sensors()
    first = encoder.encode(at_home, 0.0)
    origin_lon, origin_lat = first.position[0], first.position[1]
    assert (origin_lon, origin_lat) == pytest.approx((HOME.lon_deg, HOME.lat_deg))
    reading = moving_reading()
    lon, lat, _ = encoder.encode(reading, 1.0).position
    # master sitl.c: corrected = 2 * origin - received
    assert (2 * origin_lon - lon, 2 * origin_lat - lat) == pytest.approx(reading.geodetic[:2])
    assert encoder.encode(reading, 1.0).velocity_m_s == reading.velocity_enu_m_s


def test_a_4_6_gps_build_gets_plain_lon_lat_alt_and_enu_velocity():
    reading = moving_reading()
    packet = FdmEncoder(V46_GPS, HOME).encode(reading, 1.0)
    assert packet.position == reading.geodetic
    assert packet.velocity_m_s == reading.velocity_enu_m_s


def test_gps_loss_sends_the_out_of_range_sentinel_on_master_only():
    reading = moving_reading()
    master = FdmEncoder(MASTER, HOME)
    master.gps_lost = True
    assert master.encode(reading, 1.0).position[:2] == GPS_LOST_LON_LAT
    v46 = FdmEncoder(V46_GPS, HOME)
    v46.gps_lost = True  # 4.6 has no sentinel: it keeps the real position
    assert v46.encode(reading, 1.0).position[:2] == reading.geodetic[:2]


@pytest.mark.parametrize("profile", [V46, MASTER], ids=["4.6", "master"])
def test_servo_slots_round_trip_through_the_profile(profile):
    slots = profile.motor_slot_of_betaflight_motor
    packet = ServoPacket.from_betaflight_motors((0.1, 0.2, 0.3, 0.4), slots)
    assert packet.betaflight_motors(slots) == pytest.approx((0.1, 0.2, 0.3, 0.4))


def test_master_sends_motors_in_plain_order_and_4_6_remapped():
    raw = ServoPacket((0.1, 0.2, 0.3, 0.4))
    assert raw.betaflight_motors(MASTER.motor_slot_of_betaflight_motor) == pytest.approx(
        (0.1, 0.2, 0.3, 0.4)
    )
    assert raw.betaflight_motors(V46.motor_slot_of_betaflight_motor) == pytest.approx(
        (0.4, 0.1, 0.2, 0.3)
    )


# -- arming flags -----------------------------------------------------------------------------


def test_the_flag_count_picks_the_arming_table():
    assert arming_flags_text(1 << 28, 29) == "ARM_SWITCH"
    assert arming_flags_text(1 << 28, 30) == "AUTOPILOT"
    assert arming_flags_text(1 << 29, 30) == "ARM_SWITCH"
    assert arming_flags_text((1 << 2) | (1 << 9), 30) == "RXLOSS BOOTGRACE"
    # A newer firmware with more flags: ARM_SWITCH is still the last one.
    assert [f.cli_name for f in decode_arming_flags((1 << 30) | (1 << 29), 31)] == [
        "UNKNOWN_29",
        "ARM_SWITCH",
    ]


# -- wind, health targets and attitude tracking -----------------------------------------------


def test_wind_from_the_north_moves_the_air_south_and_from_the_east_west():
    from bfsitl.errors import SimInputError
    from bfsitl.physics.wind import Wind

    assert Wind.from_direction(3.0, 0.0).velocity_ned_m_s == pytest.approx((-3.0, 0.0, 0.0))
    assert Wind.from_direction(3.0, 90.0).velocity_ned_m_s == pytest.approx((0.0, -3.0, 0.0))
    assert Wind.from_direction(2.0, 0.0, 1.5).gust_std_m_s == 1.5
    with pytest.raises(SimInputError, match="speed"):
        Wind.from_direction(-1.0)


def test_health_targets_follow_the_firmwares_own_pid_rate():
    from bfsitl.sim.health import meets_targets, targets_for

    assert targets_for(V46) == (150.0, 0.99)
    assert targets_for(MASTER) == (1200.0, 0.85)
    # Master's 1000 us cycle is healthy; on 4.6.0 it would mean a starving 8 kHz loop.
    assert meets_targets(1.0, 1000.0, 0.92, MASTER)
    assert not meets_targets(1.0, 1000.0, 0.995, V46)


def test_attitude_tracking_compares_the_fc_with_the_truth_in_the_air_only():
    from bfsitl.mission.flight_metrics import attitude_tracking
    from bfsitl.mission.flight_row import FlightRow

    def row(phase: str, alt_m: float, fc_roll: float, sim_roll: float) -> FlightRow:
        return FlightRow(
            0.0,
            phase,
            2.0,
            alt_m,
            alt_m,
            0.0,
            0.0,
            0.0,
            fc_roll,
            0.0,
            0.0,
            abs(sim_roll),
            sim_roll,
            0.0,
            0.0,
            1500,
            1500,
            1500,
            1500,
            1800,
            1800,
            0.5,
            0.5,
            0.5,
            0.5,
            True,
            0.0,
        )

    rows = [row("ground", 0.0, 9.0, 0.0), row("hold", 2.0, 1.0, 4.0), row("hold", 2.0, 2.0, 2.0)]
    tracking = attitude_tracking(rows)
    assert tracking is not None and tracking.samples == 2
    assert tracking.max_abs_error_deg == pytest.approx(3.0)
    assert tracking.roll_rms_error_deg == pytest.approx((9.0 / 2) ** 0.5)
    assert tracking.max_true_tilt_deg == pytest.approx(4.0)
    assert attitude_tracking(rows[:1]) is None


def test_status_names_the_conventions_and_whether_they_were_tested():
    from dataclasses import replace

    from bfsitl.cli.render import conventions_text
    from bfsitl.fc.identity import FcIdentity

    sitl = FcIdentity("BTFL", "4.6.0", "1.47", "SITL", "SITL", "", "", "", "", None)
    assert conventions_text(sitl) == "4.6 (tested with bfsitl)"
    newer = replace(sitl, firmware_version="2027.6.0", api_version="1.50")
    assert "not tested" in conventions_text(newer) and "2026.12.0-alpha" in conventions_text(newer)
    assert conventions_text(replace(sitl, api_version="1.44")).startswith("unsupported")
    assert conventions_text(replace(sitl, board_id="S7X7", target_name="STM32F7X2")) is None
