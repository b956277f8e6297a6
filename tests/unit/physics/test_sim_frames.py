"""Frame conventions: the measured cases and sign table of docs/firmware-facts.md#sign-table."""

from __future__ import annotations

import dataclasses
import math

import pytest

from bfsitl.errors import SimInputError
from bfsitl.physics import IRIS, GeoPoint, Simulator, isa_pressure_pa
from bfsitl.physics.frames import (
    EARTH_RADIUS_M,
    betaflight_acc_raw,
    betaflight_attitude_and_tilt_deg,
    betaflight_attitude_deg,
    betaflight_gyro_raw,
    body_to_world,
    enu_to_ned,
    euler_from_quat_rad,
    frd_to_flu,
    geodetic_to_ned,
    gravity_specific_force_frd,
    ned_to_enu,
    ned_to_geodetic,
    quat_conjugate,
    quat_from_axis_angle,
    quat_from_euler_deg,
    quat_integrate,
    quat_multiply,
    quat_normalize,
    rotation_matrix,
    tilt_deg,
    world_to_body,
)
from bfsitl.protocol.fdm_encoding import FdmEncoder
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE

G = 9.80665


def held_reading(**reset):
    """A reading with the vehicle parked on the test stand at an exact pose."""
    sim = Simulator()
    sim.hold(True)
    sim.reset(**reset)
    sim.step((0.0, 0.0, 0.0, 0.0), 0.001)
    return sim.read_sensors()


# ---- 1.6 worked examples --------------------------------------------------------------------


def test_a_level_at_rest_heading_north():
    reading = Simulator().read_sensors()  # parked on its skids from the start
    assert reading.gyro_frd_rad_s == (0.0, 0.0, 0.0)
    assert reading.specific_force_frd_m_s2 == (0.0, 0.0, -G)
    assert reading.quaternion_wxyz == (1.0, 0.0, 0.0, 0.0)
    assert reading.velocity_ned_m_s == (0.0, 0.0, 0.0)
    # ISA at 0.1937 m (docs/firmware-facts.md#sign-table): the formula (and gz-sensors' variant)
    # gives 101322.673; 101322.66, the figure first written down, is that truncated, not
    # rounded.  The firmware keeps 101322 either way.
    assert isa_pressure_pa(0.1937) == pytest.approx(101322.673, abs=1e-3)
    assert isa_pressure_pa(0.1937) == pytest.approx(101322.66, abs=0.02)
    assert int(isa_pressure_pa(0.1937)) == 101322
    assert int(reading.pressure_pa) == 101322
    assert betaflight_acc_raw(reading.specific_force_frd_m_s2) == (0, 0, 256)
    assert betaflight_attitude_deg(reading.quaternion_wxyz) == pytest.approx((0.0, 0.0, 0.0))


def test_b_nose_down_ten_degrees_held_still():
    q = quat_from_euler_deg(0.0, -10.0, 0.0)
    assert q == pytest.approx((0.996195, 0.0, -0.087156, 0.0), abs=1e-6)
    reading = held_reading(quaternion_wxyz=q)
    assert reading.gyro_frd_rad_s == (0.0, 0.0, 0.0)
    assert reading.specific_force_frd_m_s2 == pytest.approx((-1.70291, 0.0, -9.65766), abs=1e-5)
    assert FdmEncoder(DEFAULT_PROFILE, GeoPoint(0.0, 0.0)).encode(reading, 1.0).accel_m_s2[
        0
    ] == pytest.approx(1.70291, abs=1e-5)
    # Betaflight: pitch +10 (nose down positive); acc raw (+44, 0, 252), (-44, ...) physical x.
    assert betaflight_attitude_deg(q) == pytest.approx((0.0, 10.0, 0.0))
    assert betaflight_acc_raw(reading.specific_force_frd_m_s2) == (44, 0, 252)
    physical = FdmEncoder(DEFAULT_PROFILE, GeoPoint(0.0, 0.0)).encode(reading, 1.0).accel_m_s2
    assert betaflight_acc_raw(physical) == (-44, 0, 252)
    # The firmware's patched rMat[2][0] is -R20.
    assert -rotation_matrix(q)[6] == pytest.approx(-0.17365, abs=1e-5)


def test_c_pitching_further_nose_down_at_30_deg_s():
    rate = -math.radians(30.0)  # FRD q is nose-up positive
    reading = held_reading(pitch_deg=-10.0, angular_velocity_frd_rad_s=(0.0, rate, 0.0))
    assert reading.gyro_frd_rad_s == pytest.approx((0.0, -0.523599, 0.0), abs=1e-6)
    # The SITL stores trunc(0.523599 * 16.4 * 57.2958) = 492 (positive: nose down in FLU);
    # 491 was read back through MSP_RAW_IMU, one LSB lower after the gyro filters
    # (docs/firmware-facts.md#sign-table).
    assert betaflight_gyro_raw(reading.gyro_frd_rad_s) == (0, 492, 0)
    # And free, the attitude really moves that way: Betaflight's pitch grows.
    sim = Simulator()
    sim.reset((0.0, 0.0, -30.0), pitch_deg=-10.0, angular_velocity_frd_rad_s=(0.0, rate, 0.0))
    for _ in range(100):
        sim.step((0.0, 0.0, 0.0, 0.0), 0.001)
    assert betaflight_attitude_deg(sim.state.quaternion_wxyz)[1] == pytest.approx(13.0, abs=1e-3)


def test_d_hovering_tilted_the_accelerometer_does_not_point_at_gravity():
    # As the example: no drag, and no inflow (flying forward nose-down, air comes up through
    # the discs and costs thrust; 0.03 % after 10 ms, enough to move the third decimal).
    params = dataclasses.replace(
        IRIS,
        drag_linear_n_s_per_m=(0.0, 0.0, 0.0),
        drag_quadratic_n_s2_per_m2=(0.0, 0.0, 0.0),
        axial_inflow=False,
    )
    # Thrust m g / cos 10 deg along -z body holds altitude while accelerating forward.
    omega = math.sqrt(
        params.weight_n / math.cos(math.radians(10.0)) / 4 / params.thrust_coefficient_n_per_rad2_s2
    )
    command = (params.rotor_damping_nm_s_per_rad + params.motor_p_gain_nm_s_per_rad) * omega
    command += params.torque_coefficient_nm_per_rad2_s2 * omega**2
    command /= params.motor_p_gain_nm_s_per_rad * params.motor_command_speed_rad_s
    sim = Simulator(params)
    sim.reset((0.0, 0.0, -20.0), pitch_deg=-10.0, motor_speeds_rad_s=(omega,) * 4)
    for _ in range(10):
        sim.step((command,) * 4, 0.001)
    reading = sim.read_sensors()
    assert reading.specific_force_frd_m_s2 == pytest.approx((0.0, 0.0, -9.958), abs=5e-4)
    assert reading.specific_force_frd_m_s2[2] == pytest.approx(-G / math.cos(math.radians(10)))
    assert reading.velocity_ned_m_s[2] == pytest.approx(0.0, abs=1e-6)  # altitude held
    assert reading.velocity_ned_m_s[0] > 0.01  # ... accelerating north (nose down)


def test_e_heading_east_level():
    q = quat_from_euler_deg(0.0, 0.0, 90.0)
    assert q == pytest.approx((math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)))
    reading = held_reading(yaw_deg=90.0)
    assert reading.specific_force_frd_m_s2 == pytest.approx((0.0, 0.0, -G), abs=1e-12)
    assert betaflight_attitude_deg(reading.quaternion_wxyz) == pytest.approx((0.0, 0.0, 90.0))
    assert body_to_world(q, (1.0, 0.0, 0.0)) == pytest.approx((0.0, 1.0, 0.0), abs=1e-15)


def test_f_right_wing_down_twenty_degrees():
    q = quat_from_euler_deg(20.0, 0.0, 0.0)
    assert q == pytest.approx((math.cos(math.radians(10)), math.sin(math.radians(10)), 0, 0))
    reading = held_reading(quaternion_wxyz=q)
    assert reading.specific_force_frd_m_s2 == pytest.approx((0.0, -3.354, -9.215), abs=1e-3)
    assert betaflight_attitude_deg(q) == pytest.approx((20.0, 0.0, 0.0))
    assert betaflight_acc_raw(reading.specific_force_frd_m_s2) == (0, 87, 240)


def test_the_measured_gyro_sign_table():
    # Measured: +1 rad/s on FRD x / y / z -> raw (939,0,0) / (0,-939,0) / (0,0,-939)
    # (docs/firmware-facts.md#sign-table).
    assert betaflight_gyro_raw((1.0, 0.0, 0.0)) == (939, 0, 0)
    assert betaflight_gyro_raw((0.0, 1.0, 0.0)) == (0, -939, 0)
    assert betaflight_gyro_raw((0.0, 0.0, 1.0)) == (0, 0, -939)
    assert betaflight_gyro_raw((100.0, -100.0, 0.0)) == (32767, 32767, 0)  # saturates


# ---- quaternion and rotation algebra ------------------------------------------------------------


ATTITUDES = [(0, 0, 0), (20, 0, 0), (0, -10, 0), (0, 0, 90), (35, -60, 200), (-170, 80, -45)]


@pytest.mark.parametrize("roll,pitch,yaw", ATTITUDES)
def test_euler_round_trip_and_orthonormal_matrix(roll, pitch, yaw):
    q = quat_from_euler_deg(roll, pitch, yaw)
    assert math.fsum(c * c for c in q) == pytest.approx(1.0, abs=1e-15)
    r = rotation_matrix(q)
    rows = [r[0:3], r[3:6], r[6:9]]
    for i in range(3):
        for j in range(3):
            dot = sum(rows[i][k] * rows[j][k] for k in range(3))
            assert dot == pytest.approx(1.0 if i == j else 0.0, abs=1e-14)
    back = [math.degrees(a) for a in euler_from_quat_rad(q)]
    expected = [roll, pitch, (yaw + 180) % 360 - 180]
    assert back == pytest.approx(expected, abs=1e-9)
    v = (0.3, -1.2, 2.5)
    assert world_to_body(q, body_to_world(q, v)) == pytest.approx(v, abs=1e-14)


def test_euler_order_is_yaw_then_pitch_then_roll_about_body_axes():
    yaw = quat_from_axis_angle((0, 0, 1), math.radians(30))
    pitch = quat_from_axis_angle((0, 1, 0), math.radians(20))
    roll = quat_from_axis_angle((1, 0, 0), math.radians(10))
    composed = quat_multiply(quat_multiply(yaw, pitch), roll)
    assert quat_from_euler_deg(10, 20, 30) == pytest.approx(composed, abs=1e-15)


def test_quaternion_rotates_body_frd_into_world_ned():
    # Nose pitched up 90 deg: body forward points up, i.e. -D.
    q = quat_from_euler_deg(0.0, 90.0, 0.0)
    assert body_to_world(q, (1.0, 0.0, 0.0)) == pytest.approx((0.0, 0.0, -1.0), abs=1e-15)
    # Hamilton convention: the vector form agrees with q v q*.
    q = quat_from_euler_deg(35, -60, 200)
    v = (0.3, -1.2, 2.5)
    rotated = quat_multiply(quat_multiply(q, (0.0, *v)), quat_conjugate(q))
    assert rotated[1:] == pytest.approx(body_to_world(q, v), abs=1e-14)


def test_gravity_specific_force_is_r_transpose_minus_g():
    q = quat_from_euler_deg(35, -60, 200)
    assert gravity_specific_force_frd(q) == pytest.approx(world_to_body(q, (0.0, 0.0, -G)))


def test_quat_integrate_matches_the_axis_angle_rotation():
    q0 = quat_from_euler_deg(10, 20, 30)
    rate = (0.4, -2.0, 1.1)
    for dt in (0.001, 0.3):  # series branch and trigonometric branch
        angle = math.dist(rate, (0, 0, 0)) * dt
        expected = quat_multiply(q0, quat_from_axis_angle(rate, angle))
        assert quat_integrate(q0, rate, dt) == pytest.approx(expected, abs=1e-13)


def test_quat_normalize_refuses_garbage():
    assert quat_normalize((2.0, 0.0, 0.0, 0.0)) == (1.0, 0.0, 0.0, 0.0)
    with pytest.raises(SimInputError):
        quat_normalize((0.0, 0.0, 0.0, 0.0))
    with pytest.raises(SimInputError):
        quat_normalize((float("nan"), 0.0, 0.0, 1.0))


def test_axis_conversions():
    assert frd_to_flu((1.0, 2.0, 3.0)) == (1.0, -2.0, -3.0)
    assert frd_to_flu(frd_to_flu((1.0, 2.0, 3.0))) == (1.0, 2.0, 3.0)
    assert ned_to_enu((1.0, 2.0, 3.0)) == (2.0, 1.0, -3.0)  # north 1, east 2, down 3
    assert enu_to_ned(ned_to_enu((1.0, 2.0, 3.0))) == (1.0, 2.0, 3.0)


# ---- geodetic -------------------------------------------------------------------------------


def test_ned_to_geodetic_flat_earth():
    home = GeoPoint(47.0, 8.0, 500.0)
    point = ned_to_geodetic((1000.0, 1000.0, -20.0), home)
    assert point.lat_deg == pytest.approx(47.0 + math.degrees(1000.0 / EARTH_RADIUS_M))
    assert point.lat_deg - 47.0 == pytest.approx(0.0089832, abs=1e-7)
    east_deg = math.degrees(1000.0 / (EARTH_RADIUS_M * math.cos(math.radians(47.0))))
    assert point.lon_deg == pytest.approx(8.0 + east_deg)
    assert point.lon_deg - 8.0 > point.lat_deg - 47.0  # a metre east is more longitude
    assert point.alt_m == 520.0
    assert geodetic_to_ned(point, home) == pytest.approx((1000.0, 1000.0, -20.0), abs=1e-9)


def test_betaflight_distance_constant_round_trips():
    # Betaflight: 1.113195 cm per 1e-7 degree of latitude (EARTH_ANGLE_TO_CM).
    point = ned_to_geodetic((1000.0, 0.0, 0.0), GeoPoint(0.0, 0.0))
    assert point.lat_deg * 1e7 * 1.113195 / 100 == pytest.approx(1000.0, rel=1e-6)


def test_geopoint_validation():
    with pytest.raises(SimInputError):
        GeoPoint(95.0, 0.0)
    with pytest.raises(SimInputError):
        GeoPoint(0.0, 181.0)
    with pytest.raises(SimInputError):
        GeoPoint(float("nan"), 0.0)


@pytest.mark.parametrize(
    "euler_deg",
    [
        (0.0, 0.0, 0.0),
        (12.5, -7.25, 33.0),
        (-170.0, 80.0, 359.0),
        (0.0, 90.0, 10.0),
        (179.0, -89.9, 181.0),
    ],
)
def test_the_attitude_and_the_tilt_of_one_rotation_are_the_two_functions_to_the_bit(euler_deg):
    q = quat_from_euler_deg(*euler_deg)
    attitude_deg, tilt = betaflight_attitude_and_tilt_deg(q)
    assert attitude_deg == betaflight_attitude_deg(q)
    assert tilt == tilt_deg(q)
    assert tilt > 0.0 or euler_deg == (0.0, 0.0, 0.0)


def test_kinematics_is_the_state_in_one_read():
    sim = Simulator(seed=3)
    for _ in range(50):  # moving and turning: no field is zero by chance
        sim.step((0.7, 0.6, 0.7, 0.6), 0.01)
    state = sim.state
    assert sim.kinematics() == (
        state.time_s,
        state.position_ned_m,
        state.velocity_ned_m_s,
        state.quaternion_wxyz,
    )
    assert all(value != 0.0 for value in (*state.velocity_ned_m_s, *state.quaternion_wxyz[1:]))
