"""The embedded quadrotor physics: hover, free fall, torques, conservation, ground contact."""

from __future__ import annotations

import dataclasses
import math

import pytest

from bfsitl.errors import BfsitlError, SimInputError
from bfsitl.physics import IRIS, QuadParams, Simulator, Wind
from bfsitl.physics.frames import betaflight_attitude_deg, body_to_world, euler_from_quat_rad

G = 9.80665
DT = 0.001
NO_DRAG = dataclasses.replace(
    IRIS, drag_linear_n_s_per_m=(0.0, 0.0, 0.0), drag_quadratic_n_s2_per_m2=(0.0, 0.0, 0.0)
)
OFF = (0.0, 0.0, 0.0, 0.0)


def run(sim: Simulator, motors, seconds: float, dt: float = DT) -> None:
    for _ in range(round(seconds / dt)):
        sim.step(motors, dt)


def airborne(params: QuadParams = IRIS, speeds=None, **kwargs) -> Simulator:
    sim = Simulator(params)
    sim.reset((0.0, 0.0, -50.0), motor_speeds_rad_s=speeds or (0.0,) * 4, **kwargs)
    return sim


# ---- hover ------------------------------------------------------------------------------------


def test_hover_command_is_the_analytic_torque_balance():
    # From the raw SDF numbers, not from QuadParams' helpers: four rotors carry m g at
    # w = sqrt(m g / (4 kT)); the joint P controller holds w where P (838 u - w) equals
    # damping * w + kQ w^2.
    omega = math.sqrt(1.75 * G / (4 * 2.1665e-5))
    u = (0.204 * omega + 4.282e-8 * omega**2) / (0.2 * 838.0)
    assert IRIS.hover_rotor_speed_rad_s == pytest.approx(omega, rel=1e-12)
    assert IRIS.hover_command == pytest.approx(u, rel=1e-12)
    # The hover command derived in docs/firmware-facts.md#iris-motors.
    assert IRIS.hover_command == pytest.approx(0.5417, abs=1e-4)
    assert IRIS.steady_rotor_speed_rad_s(u) == pytest.approx(omega, rel=1e-12)


def test_hover_command_holds_altitude_for_five_seconds():
    sim = airborne(speeds=(IRIS.hover_rotor_speed_rad_s,) * 4)
    run(sim, (IRIS.hover_command,) * 4, 5.0)
    state = sim.state
    assert sim.altitude_m == pytest.approx(50.0, abs=1e-6)
    assert max(abs(v) for v in state.velocity_ned_m_s) < 1e-6
    assert state.motor_speeds_rad_s == pytest.approx((IRIS.hover_rotor_speed_rad_s,) * 4)
    # Thrust equals weight: the accelerometer reads exactly one g up.
    assert sim.read_sensors().specific_force_frd_m_s2 == pytest.approx((0, 0, -G), abs=1e-9)


def test_one_percent_above_hover_climbs_and_inflow_limits_the_climb_rate():
    sim = airborne(speeds=(IRIS.hover_rotor_speed_rad_s,) * 4)
    run(sim, (IRIS.hover_command * 1.01,) * 4, 5.0)
    assert sim.altitude_m > 50.5
    # Without the axial-inflow loss the 2 % extra thrust would keep accelerating (0.2 m/s^2,
    # 1 m/s after 5 s); with it the climb settles where the thrust loss balances the excess:
    # w (w - v / (r a0)) = w_hover^2  ->  v = r a0 (w - w_hover^2 / w).
    omega = IRIS.steady_rotor_speed_rad_s(IRIS.hover_command * 1.01)
    terminal = 0.084 * 0.3 * (omega - IRIS.hover_rotor_speed_rad_s**2 / omega)
    assert -sim.state.velocity_ned_m_s[2] == pytest.approx(terminal, rel=0.02)


def test_spin_up_from_rest_is_slew_limited_by_the_motor_torque_clamp():
    sim = airborne()
    sim.step((1.0,) * 4, DT)
    # First step: +2.5 N m on 1.676e-4 kg m^2 for 1 ms = 14.9 rad/s (not the 0.7 * 821
    # the first-order lag alone would give).
    assert sim.state.motor_speeds_rad_s[0] == pytest.approx(2.5 / 1.67604e-4 * DT, rel=1e-9)
    run(sim, (1.0,) * 4, 0.5)
    # Full command saturates where the clamped torque only balances damping and drag.
    assert sim.state.motor_speeds_rad_s[0] == pytest.approx(620.87, abs=0.05)


def test_small_command_steps_follow_the_first_order_lag():
    omega0 = IRIS.hover_rotor_speed_rad_s
    sim = airborne(speeds=(omega0,) * 4)
    u = IRIS.hover_command + 0.005
    target = IRIS.steady_rotor_speed_rad_s(u)
    sim.step((u,) * 4, DT)
    fraction = (sim.state.motor_speeds_rad_s[0] - omega0) / (target - omega0)
    assert fraction == pytest.approx(1 - math.exp(-DT / 0.00082159), rel=1e-4)


def test_commands_are_clamped_to_zero_and_one():
    a, b = airborne(), airborne()
    a.step((1.7, -0.4, 1.0, 0.0), DT)
    b.step((1.0, 0.0, 1.0, 0.0), DT)
    assert a.state == b.state


# ---- free fall ---------------------------------------------------------------------------------


def test_free_fall_follows_half_g_t_squared_and_the_accelerometer_reads_zero():
    sim = Simulator(NO_DRAG)
    sim.reset((0.0, 0.0, -10.0))
    steps = 1000
    for _ in range(steps):
        sim.step(OFF, DT)
        f = sim.read_sensors().specific_force_frd_m_s2
        assert max(abs(c) for c in f) < 1e-12
    fallen = sim.state.position_ned_m[2] + 10.0
    t = sim.time_s
    assert t == pytest.approx(1.0, abs=1e-12)
    # Symplectic Euler: z_n = g h^2 n (n + 1) / 2, i.e. 1/2 g t^2 plus 1/2 g h t.
    assert fallen == pytest.approx(0.5 * G * t * t + 0.5 * G * DT * t, rel=1e-9)
    assert fallen == pytest.approx(0.5 * G * t * t, rel=2e-3)
    assert sim.state.velocity_ned_m_s[2] == pytest.approx(G * t, rel=1e-9)


def test_body_drag_slows_the_fall_and_shows_on_the_accelerometer():
    sim = Simulator()  # IRIS with its (estimated) body drag
    sim.reset((0.0, 0.0, -1000.0))
    run(sim, OFF, 1.0)
    speed = sim.state.velocity_ned_m_s[2]
    quadratic = IRIS.drag_quadratic_n_s2_per_m2[2]
    assert G * 0.9 < speed < G  # drag is small at first ...
    assert sim.read_sensors().specific_force_frd_m_s2[2] == pytest.approx(
        -quadratic * speed * speed / IRIS.mass_kg, rel=5e-3
    )  # ... and pushes up (-z FRD)
    run(sim, OFF, 6.0)
    terminal = math.sqrt(IRIS.weight_n / quadratic)
    assert sim.state.velocity_ned_m_s[2] == pytest.approx(terminal, rel=0.02)


# ---- torques: signs and magnitudes ---------------------------------------------------------------


def angular_acceleration(commands) -> tuple[float, float, float]:
    """One step from rest at the commands' steady rotor speeds (no spin-up transient)."""
    speeds = tuple(IRIS.steady_rotor_speed_rad_s(u) for u in commands)
    sim = airborne(speeds=speeds)
    sim.step(commands, DT)
    return tuple(w / DT for w in sim.state.angular_velocity_frd_rad_s)


def thrust_difference(lo: float, hi: float) -> float:
    kt = IRIS.thrust_coefficient_n_per_rad2_s2
    return kt * (IRIS.steady_rotor_speed_rad_s(hi) ** 2 - IRIS.steady_rotor_speed_rad_s(lo) ** 2)


LO, HI = IRIS.hover_command - 0.02, IRIS.hover_command + 0.02


def test_left_motors_faster_roll_right():
    p_dot, q_dot, r_dot = angular_acceleration((LO, LO, HI, HI))  # M3, M4 (left) up
    # Roll moment -sum(y T): left arms at y = -0.20 (rear) and -0.22 (front).
    assert p_dot == pytest.approx((0.20 + 0.22) * thrust_difference(LO, HI) / 0.012519, rel=1e-3)
    assert p_dot > 20.0
    assert abs(q_dot) < 1e-9 and abs(r_dot) < 1e-9


def test_front_motors_faster_pitch_nose_up():
    p_dot, q_dot, r_dot = angular_acceleration((LO, HI, LO, HI))  # M2, M4 (front) up
    assert q_dot == pytest.approx(2 * 0.13 * thrust_difference(LO, HI) / 0.017427, rel=1e-3)
    assert q_dot > 9.0
    assert abs(p_dot) < 1e-9 and abs(r_dot) < 1e-9


def test_clockwise_rotors_faster_yaw_the_frame_counter_clockwise():
    p_dot, q_dot, r_dot = angular_acceleration((HI, LO, LO, HI))  # M1, M4 (CW) up
    kq = IRIS.torque_coefficient_nm_per_rad2_s2
    w_hi, w_lo = IRIS.steady_rotor_speed_rad_s(HI), IRIS.steady_rotor_speed_rad_s(LO)
    assert r_dot == pytest.approx(-2 * kq * (w_hi**2 - w_lo**2) / 0.0238, rel=1e-3)
    assert r_dot < 0
    # IRIS's front arms are wider (0.22 vs 0.20 m): the diagonal pair also rolls it a little.
    assert p_dot == pytest.approx(0.02 * thrust_difference(LO, HI) / 0.012519, rel=1e-3)


def test_spinning_up_clockwise_rotors_kicks_the_frame_counter_clockwise():
    # The rotor-acceleration reaction I_r dw/dt, not the drag torque, dominates transient yaw.
    omega = IRIS.hover_rotor_speed_rad_s
    sim = airborne(speeds=(omega,) * 4)
    u = IRIS.hover_command
    sim.step((u + 0.1, u, u, u + 0.1), DT)  # M1, M4 (CW) spin up
    spin_up = sim.state.motor_speeds_rad_s[0] - omega
    r_dot = sim.state.angular_velocity_frd_rad_s[2] / DT
    expected = -2 * 1.67604e-4 * spin_up / DT / 0.0238
    assert r_dot == pytest.approx(expected, rel=0.02)
    assert r_dot < -10.0


def command_for(omega: float) -> float:
    """The servo command whose steady rotor speed is omega (torque balance, as in the SDF)."""
    return (0.204 * omega + 4.282e-8 * omega**2) / (0.2 * 838.0)


def test_rolling_with_net_rotor_momentum_precesses_nose_down():
    # CCW rotors (M2, M3) faster: the rotors' net spin momentum h points up (-z FRD).  Rolling
    # right (+p) then needs +y torque on the rotors, whose reaction pitches the frame nose
    # down: dq/dt = p h / Jy with h = -I_r sum(s Omega), s = +1 for CCW.  (No inflow here: a
    # rolling rotor's own inflow change also pitches this asymmetric frame a little.)
    fast, slow, p = 500.0, 400.0, 3.0
    speeds = (slow, fast, fast, slow)
    sim = airborne(
        dataclasses.replace(IRIS, axial_inflow=False),
        speeds=speeds,
        angular_velocity_frd_rad_s=(p, 0.0, 0.0),
    )
    sim.step(tuple(command_for(w) for w in speeds), DT)
    assert sim.state.motor_speeds_rad_s == pytest.approx(speeds, abs=1e-9)
    h = -1.67604e-4 * (2 * fast - 2 * slow)
    q_dot = sim.state.angular_velocity_frd_rad_s[1] / DT
    assert q_dot == pytest.approx(p * h / 0.017427, rel=1e-3)
    assert q_dot < -5.0


# ---- conservation -------------------------------------------------------------------------------


def test_free_rotation_conserves_energy_momentum_and_unit_quaternion_for_a_minute():
    rates = (0.05, 3.0, 0.05)  # near the intermediate (unstable) axis: it tumbles
    sim = Simulator(NO_DRAG)
    sim.reset((0.0, 0.0, -19000.0), angular_velocity_frd_rad_s=rates)
    jx, jy, jz = IRIS.inertia_kg_m2

    def energy(w):
        return 0.5 * (jx * w[0] ** 2 + jy * w[1] ** 2 + jz * w[2] ** 2)

    def momentum(state):
        w = state.angular_velocity_frd_rad_s
        return body_to_world(state.quaternion_wxyz, (jx * w[0], jy * w[1], jz * w[2]))

    e0, l0 = energy(rates), momentum(sim.state)
    worst_norm = worst_energy = worst_momentum = 0.0
    lowest_pitch_rate = 3.0
    for k in range(60_000):
        sim.step(OFF, DT)
        state = sim.state
        q = state.quaternion_wxyz
        worst_norm = max(worst_norm, abs(math.sqrt(sum(c * c for c in q)) - 1.0))
        lowest_pitch_rate = min(lowest_pitch_rate, state.angular_velocity_frd_rad_s[1])
        if k % 100 == 0:
            worst_energy = max(worst_energy, abs(energy(state.angular_velocity_frd_rad_s) / e0 - 1))
            worst_momentum = max(worst_momentum, math.dist(momentum(state), l0))
    assert worst_norm < 1e-9
    assert worst_energy < 1e-6
    assert worst_momentum < 1e-6 * math.dist(l0, (0, 0, 0))
    # It really tumbled: the pitch rate reversed (intermediate-axis flips), so the gyroscopic
    # coupling that an integrator can get wrong was exercised, not a steady spin.
    assert lowest_pitch_rate < -2.0


def test_a_minute_parked_with_no_input_changes_nothing():
    sim = Simulator()
    start = sim.state
    run(sim, OFF, 60.0)
    end = sim.state
    assert end.position_ned_m == start.position_ned_m
    assert end.quaternion_wxyz == start.quaternion_wxyz
    assert end.velocity_ned_m_s == (0.0, 0.0, 0.0)
    assert end.angular_velocity_frd_rad_s == (0.0, 0.0, 0.0)
    assert end.time_s == pytest.approx(60.0, abs=1e-9)


# ---- resting on the ground -------------------------------------------------------------------


@pytest.mark.parametrize("yaw_deg", [0.0, 37.0])
def test_resting_thirty_seconds_armed_idle_no_drift_exact_sensors(yaw_deg):
    sim = Simulator()
    sim.reset(yaw_deg=yaw_deg)
    start = sim.state
    assert start.on_ground and sim.at_rest
    assert sim.altitude_m == pytest.approx(IRIS.contact_bottom_m - IRIS.resting_sag_m, abs=1e-12)
    for k in range(30_000):
        # Armed idle with a little PID-like differential: the skids carry it.
        jitter = 0.01 * ((k * 7) % 5 - 2) / 2
        sim.step((0.055 + jitter, 0.055 - jitter, 0.055, 0.055 + jitter), DT)
        if k % 1000 == 0:
            reading = sim.read_sensors()
            assert reading.gyro_frd_rad_s == (0.0, 0.0, 0.0)
            assert reading.specific_force_frd_m_s2 == pytest.approx((0, 0, -G), abs=1e-12)
    end = sim.state
    assert end.position_ned_m == start.position_ned_m
    assert end.quaternion_wxyz == start.quaternion_wxyz
    assert end.on_ground


def test_sideways_wind_below_the_friction_limit_does_not_creep():
    sim = Simulator(wind=Wind(velocity_ned_m_s=(8.0, 3.0, 0.0)))
    start = sim.state.position_ned_m
    run(sim, OFF, 10.0)
    assert sim.state.position_ned_m == start and sim.at_rest


def drag_n(speed_m_s: float) -> float:
    return IRIS.drag_linear_n_s_per_m[1] * speed_m_s + IRIS.drag_quadratic_n_s2_per_m2[1] * (
        speed_m_s**2
    )


def test_wind_just_below_the_friction_limit_holds_and_just_above_slides_upright():
    # mu m g = 17.16 N of friction; tipping over the skid edge would take more,
    # 0.235 / 0.196 x 17.16 = 20.6 N (the wind pushes at the CoM, 0.196 m up).
    assert drag_n(16.0) < IRIS.weight_n < drag_n(17.5) < IRIS.weight_n * 0.235 / 0.196
    calm = Simulator(wind=Wind((0.0, 16.0, 0.0)))
    run(calm, OFF, 2.0)
    assert calm.at_rest and calm.state.position_ned_m[1] == 0.0
    stormy = Simulator(wind=Wind((0.0, 17.5, 0.0)))
    run(stormy, OFF, 2.0)
    assert stormy.state.position_ned_m[1] > 0.5  # blown east, sliding
    roll, pitch, _ = betaflight_attitude_deg(stormy.state.quaternion_wxyz)
    assert abs(roll) < 1.0 and abs(pitch) < 1.0  # on its skids
    assert not stormy.at_rest


def test_full_left_motors_on_the_ground_roll_it_over_to_the_right():
    # 3.5 N m of roll torque against a weight that, lifted by 16.7 N of thrust, can no longer
    # hold the centre of pressure inside the skids: the freeze lets go and it tips right.
    sim = Simulator()
    run(sim, (0.0, 0.0, 0.75, 0.75), 0.05)
    assert sim.at_rest  # spinning up: still held by the skids
    run(sim, (0.0, 0.0, 0.75, 0.75), 0.25)
    roll, _, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
    assert roll > 15.0 and sim.state.angular_velocity_frd_rad_s[0] > 3.0  # and flipping on
    assert not sim.at_rest


def test_a_slide_never_tips_a_box_wider_than_mu_times_its_height():
    # Sliding, friction caps the ground force at mu N, so its tipping moment mu N 0.196 stays
    # below the weight's N 0.235: even a 30 m/s gale only slides it along.
    sim = Simulator(wind=Wind((0.0, 30.0, 0.0)))
    run(sim, OFF, 2.0)
    roll, _, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
    assert sim.state.position_ned_m[1] > 5.0 and abs(roll) < 1.0


def test_ground_spring_alone_settles_exactly_without_the_rest_freeze():
    # With the rest freeze disabled, the contact springs themselves must hold still too.
    sim = Simulator()
    sim._sim.freeze_at_rest = 0  # the C structure's switch (physics.h)
    sim.reset((0.0, 0.0, -0.5))
    run(sim, OFF, 3.0)
    assert not sim.at_rest and sim.on_ground
    before = sim.state
    run(sim, OFF, 1.0)
    after = sim.state
    assert after.position_ned_m == pytest.approx(before.position_ned_m, abs=1e-9)
    assert sim.altitude_m == pytest.approx(IRIS.resting_height_m, abs=1e-6)
    assert sim.read_sensors().specific_force_frd_m_s2 == pytest.approx((0, 0, -G), abs=1e-9)


# ---- take-off and landing ---------------------------------------------------------------------


def test_take_off_then_motors_off_lands_without_bounce_or_sinking():
    sim = Simulator()
    rest_height = sim.altitude_m
    heights, lifted_at = [], None
    for k in range(6000):
        sim.step((0.62,) * 4 if k < 1000 else OFF, DT)
        heights.append(sim.altitude_m)
        if lifted_at is None and not sim.on_ground:
            lifted_at = k * DT
    assert lifted_at is not None and lifted_at < 0.15  # T/W = 1.31 leaves the ground at once
    assert max(heights) > 1.0
    touchdown = next(k for k in range(1000, 6000) if heights[k] < IRIS.contact_bottom_m)
    deepest = min(range(touchdown, 6000), key=heights.__getitem__)
    # No rebound: after the deepest point it never rises above its final resting height.
    assert max(heights[deepest:]) <= rest_height + 1e-4
    # No sinking: the skids sink at most 2 cm at a ~5 m/s touchdown, and end at the static sag.
    assert IRIS.contact_bottom_m - heights[deepest] < 0.02
    assert heights[-1] == pytest.approx(rest_height, abs=1e-4)
    assert sim.at_rest
    assert sim.read_sensors().specific_force_frd_m_s2 == pytest.approx((0, 0, -G), abs=1e-3)


def test_every_drop_height_comes_to_rest_at_the_static_sag():
    # The rest freeze must wait for the springs to settle, not catch the vehicle at the bottom
    # of its compression, where the speed passes through zero with the spring loaded: sweep
    # the phase of touchdown finely (without the acceleration condition ~1 in 8 freezes there,
    # millimetres deep).
    for k in range(60):
        sim = Simulator()
        sim.reset((0.0, 0.0, -(IRIS.resting_height_m + 0.02 + 0.0013 * k)))
        run(sim, OFF, 0.8)
        assert sim.at_rest, k
        assert sim.altitude_m == pytest.approx(IRIS.resting_height_m, abs=1e-4), k


def test_tilted_drops_come_to_rest_level():
    for k in range(12):
        sim = Simulator()
        tilt = (6.0, -9.0, 12.0)[k % 3]
        sim.reset(
            (0.0, 0.0, -(IRIS.resting_height_m + 0.05 + 0.037 * k)),
            roll_deg=tilt,
            pitch_deg=tilt / 2,
        )
        run(sim, OFF, 1.5)
        assert sim.at_rest, k
        assert sim.altitude_m == pytest.approx(IRIS.resting_height_m, abs=1e-4), k
        roll, pitch, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
        assert abs(roll) < 0.01 and abs(pitch) < 0.01, (k, roll, pitch)


@pytest.mark.parametrize("drop_m", [0.3, 1.0, 3.0])
def test_drops_do_not_rebound(drop_m):
    sim = Simulator()
    rest_height = sim.altitude_m
    sim.reset((0.0, 0.0, -(rest_height + drop_m)))
    heights = []
    for _ in range(3000):
        sim.step(OFF, DT)
        heights.append(sim.altitude_m)
    deepest = min(range(len(heights)), key=heights.__getitem__)
    assert max(heights[deepest:]) <= rest_height + 1e-4
    assert sim.at_rest


def test_tilted_landing_with_sideways_speed_settles_level_on_the_skids():
    sim = Simulator()
    sim.reset(
        (0.0, 0.0, -0.7),
        roll_deg=15.0,
        pitch_deg=-8.0,
        yaw_deg=30.0,
        velocity_ned_m_s=(2.0, -1.0, 0.0),
        angular_velocity_frd_rad_s=(0.0, 0.0, 2.0),
    )
    run(sim, OFF, 3.0)
    assert sim.at_rest
    roll, pitch, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
    assert abs(roll) < 0.02 and abs(pitch) < 0.02
    assert sim.altitude_m == pytest.approx(IRIS.resting_height_m, abs=1e-4)


def test_a_roll_past_the_tipping_angle_ends_on_its_back():
    # The box tips over its skid edge beyond atan(0.235 / 0.196) = 50 deg; the CoM sits near
    # the top of the Gazebo collision box, so it rolls on over onto its back.
    sim = Simulator()
    sim.reset((0.0, 0.0, -1.0), roll_deg=60.0)
    run(sim, OFF, 4.0)
    assert sim.on_ground and not sim.at_rest
    roll, _, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
    assert abs(roll) == pytest.approx(180.0, abs=0.1)
    assert sim.altitude_m == pytest.approx(-IRIS.contact_top_m - IRIS.resting_sag_m, abs=1e-3)
    assert sim.read_sensors().specific_force_frd_m_s2 == pytest.approx((0, 0, G), abs=1e-6)


# ---- closed loop -------------------------------------------------------------------------------


def toy_flight_controller(
    sim: Simulator, altitude_m: float, pitch_deg: float = 0.0, yaw_deg: float = 0.0
) -> tuple[float, float, float, float]:
    """Altitude PD, angle P -> rate P, mixed like Betaflight's quad-X (in FRD senses)."""
    state = sim.state
    roll, pitch, yaw = euler_from_quat_rad(state.quaternion_wxyz)
    p, q, r = state.angular_velocity_frd_rad_s
    climb = -state.velocity_ned_m_s[2]
    throttle = IRIS.hover_command + 0.15 * (altitude_m - sim.altitude_m) - 0.12 * climb
    throttle = min(max(throttle, 0.0), 0.75)
    yaw_error = (math.radians(yaw_deg) - yaw + math.pi) % (2 * math.pi) - math.pi
    # Yaw rate gain kept low: the rotor spin-up reaction makes yaw respond within one step.
    roll_cmd = 0.02 * (6 * -roll - p)
    pitch_cmd = 0.025 * (6 * (math.radians(pitch_deg) - pitch) - q)
    yaw_cmd = 0.05 * (3 * yaw_error - r)
    motors = (
        throttle - roll_cmd - pitch_cmd - yaw_cmd,  # M1 rear right, CW
        throttle - roll_cmd + pitch_cmd + yaw_cmd,  # M2 front right, CCW
        throttle + roll_cmd - pitch_cmd + yaw_cmd,  # M3 rear left, CCW
        throttle + roll_cmd + pitch_cmd - yaw_cmd,  # M4 front left, CW
    )
    return tuple(min(max(m, 0.0), 1.0) for m in motors)  # type: ignore[return-value]


@pytest.mark.parametrize("wind", [None, Wind((3.0, 1.0, 0.0), gust_std_m_s=1.0)])
def test_a_simple_controller_flies_a_mission_and_parks(wind):
    sim = Simulator(wind=wind, seed=1)
    for k in range(12_000):
        t = k * DT
        if t < 6.0:
            motors = toy_flight_controller(sim, 2.0, yaw_deg=60.0 if t > 3.0 else 0.0)
        elif t < 8.0:
            motors = toy_flight_controller(sim, 2.0, pitch_deg=-10.0)  # nose down: go north
        elif t < 9.0:
            motors = toy_flight_controller(sim, 2.0)
        else:
            motors = toy_flight_controller(sim, -0.5)  # descend into the ground
        sim.step(motors, DT)
        if k == 5999:
            roll, pitch, yaw = betaflight_attitude_deg(sim.state.quaternion_wxyz)
            assert sim.altitude_m == pytest.approx(2.0, abs=0.25 if wind else 0.01)
            assert yaw == pytest.approx(60.0, abs=3.0)
            north_at_six = sim.state.position_ned_m[0]
        if k == 7999:
            assert sim.state.position_ned_m[0] - north_at_six > 1.5
            assert betaflight_attitude_deg(sim.state.quaternion_wxyz)[1] == pytest.approx(
                10.0, abs=0.5
            )  # Betaflight reads nose-down positive
    # Still commanding 0.44 throttle into the ground, gusts or not: parked and frozen.
    assert sim.at_rest
    roll, pitch, _ = betaflight_attitude_deg(sim.state.quaternion_wxyz)
    assert abs(roll) < 0.1 and abs(pitch) < 0.1
    assert sim.read_sensors().specific_force_frd_m_s2 == pytest.approx((0, 0, -G), abs=0.02)


# ---- hold, reset, state ------------------------------------------------------------------------


def test_hold_freezes_the_pose_and_reports_the_given_rates():
    sim = Simulator()
    sim.hold(True)
    sim.reset((0.0, 0.0, -3.0), roll_deg=20.0, angular_velocity_frd_rad_s=(1.0, 0.0, 0.0))
    run(sim, (1.0,) * 4, 0.5)  # full throttle: a held vehicle still does not move
    state = sim.state
    assert state.position_ned_m == (0.0, 0.0, -3.0)
    assert betaflight_attitude_deg(state.quaternion_wxyz)[0] == pytest.approx(20.0)
    assert state.motor_speeds_rad_s[0] == pytest.approx(620.87, abs=0.05)
    reading = sim.read_sensors()
    assert reading.gyro_frd_rad_s == (1.0, 0.0, 0.0)
    assert reading.specific_force_frd_m_s2 == pytest.approx(
        (0.0, -G * math.sin(math.radians(20)), -G * math.cos(math.radians(20)))
    )
    assert sim.time_s == pytest.approx(0.5)
    sim.hold(False)
    sim.reset((0.0, 0.0, -3.0))
    run(sim, (1.0,) * 4, 0.5)
    assert sim.altitude_m > 3.5  # released, it climbs


def test_reset_on_the_ground_rests_on_the_lowest_corner_and_keeps_time():
    sim = Simulator()
    run(sim, OFF, 0.25)
    sim.reset(pitch_deg=30.0)
    assert sim.time_s == pytest.approx(0.25)
    assert sim.on_ground and not sim.at_rest
    run(sim, OFF, 3.0)  # falls back onto its skids
    assert sim.at_rest


def test_state_fields_and_altitude():
    sim = Simulator()
    sim.reset(
        (1.0, -2.0, -7.5),
        velocity_ned_m_s=(0.5, 0.0, -1.0),
        motor_speeds_rad_s=(100.0, 200.0, 300.0, 400.0),
    )
    state = sim.state
    assert state.position_ned_m == (1.0, -2.0, -7.5)
    assert state.velocity_ned_m_s == (0.5, 0.0, -1.0)
    assert state.motor_speeds_rad_s == (100.0, 200.0, 300.0, 400.0)
    assert state.quaternion_wxyz == (1.0, 0.0, 0.0, 0.0)
    assert not state.on_ground
    assert sim.altitude_m == sim.agl_m == 7.5


# ---- bad input --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "motors",
    [
        (0.5, float("nan"), 0.5, 0.5),
        (0.5, 0.5, float("inf"), 0.5),
        (0.5, 0.5, 0.5),
        (0.5,) * 5,
        ("a", "b", "c", "d"),
        None,
    ],
)
def test_bad_motor_commands_raise_and_leave_the_state_alone(motors):
    sim = Simulator()
    before = sim.state
    with pytest.raises(SimInputError, match="M|motors") as info:
        sim.step(motors, DT)
    assert isinstance(info.value, BfsitlError) and isinstance(info.value, ValueError)
    assert sim.state == before


def test_nan_names_the_motor():
    with pytest.raises(SimInputError, match="M3"):
        Simulator().step((0.1, 0.1, float("nan"), 0.1), DT)


@pytest.mark.parametrize("dt", [0.0, -0.001, float("nan"), 0.5])
def test_bad_step_length_raises(dt):
    with pytest.raises(SimInputError, match="dt_s"):
        Simulator().step(OFF, dt)


def test_bad_reset_arguments_raise_and_change_nothing():
    sim = Simulator()
    sim.reset((1.0, 2.0, -3.0), roll_deg=5.0, motor_speeds_rad_s=(100.0,) * 4)
    before = sim.state
    with pytest.raises(SimInputError):
        sim.reset(quaternion_wxyz=(0.0, 0.0, 0.0, 0.0))
    with pytest.raises(SimInputError, match="not both"):
        sim.reset(quaternion_wxyz=(1.0, 0.0, 0.0, 0.0), roll_deg=5.0)
    with pytest.raises(SimInputError, match="position_ned_m"):
        sim.reset((0.0, float("nan"), 0.0))
    with pytest.raises(SimInputError, match="motor speeds"):
        sim.reset(motor_speeds_rad_s=(-1.0, 0.0, 0.0, 0.0))
    with pytest.raises(SimInputError, match="into the ground"):
        sim.reset((0.0, 0.0, 0.0), yaw_deg=90.0)  # the CoM on the ground plane: box 0.2 m deep
    assert sim.state == before
    sim.reset((0.0, 0.0, -0.1937))  # docs/firmware-facts.md#model-choices: 2.6 mm deep, accepted


def test_bad_parameters_raise():
    with pytest.raises(SimInputError, match="mass_kg"):
        dataclasses.replace(IRIS, mass_kg=0.0)
    with pytest.raises(SimInputError, match="contact_top_m"):
        dataclasses.replace(IRIS, contact_top_m=0.5)
    with pytest.raises(SimInputError, match="gust"):
        Wind(gust_std_m_s=-1.0)


# ---- wind -------------------------------------------------------------------------------------


def test_gusts_are_repeatable_with_the_seed():
    def trajectory(seed: int):
        sim = Simulator(
            wind=Wind((2.0, 0.0, 0.0), gust_std_m_s=1.5, gust_time_constant_s=0.5), seed=seed
        )
        sim.reset((0.0, 0.0, -20.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
        run(sim, (IRIS.hover_command,) * 4, 2.0)
        return sim.state.position_ned_m, sim.wind_ned_m_s

    assert trajectory(3) == trajectory(3)
    assert trajectory(3) != trajectory(4)


def test_wind_blows_a_hovering_vehicle_downwind():
    sim = Simulator(wind=Wind((3.0, -2.0, 0.0)))
    sim.reset((0.0, 0.0, -20.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    run(sim, (IRIS.hover_command,) * 4, 2.0)
    vn, ve, _ = sim.state.velocity_ned_m_s
    assert vn > 0.5 and ve < -0.3
    assert vn / -ve == pytest.approx(1.5, rel=0.05)  # along the wind


@pytest.mark.parametrize(
    "make",
    [
        lambda: Wind((51.0, 0.0, 0.0)),
        lambda: Wind((0.0, 0.0, 0.0), gust_std_m_s=21.0),
        lambda: Wind((0.0, 0.0, 0.0), gust_time_constant_s=0.0),
        lambda: Wind.from_direction(60.0),
    ],
)
def test_one_wind_range_for_every_way_of_giving_one(make) -> None:
    """The CLI, a scenario's [wind] and the wind fault check against the same limits."""
    with pytest.raises(SimInputError):
        make()
