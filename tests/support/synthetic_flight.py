"""A flight with known physics, as a fit reads a log: the embedded physics flown by a simple
rate controller (random stick steps on every axis and the throttle), recorded the way a
blackbox records it.  No firmware: the unit tests of the fit run in a second; the integration
test flies the same kind of log through the real SITL."""

from __future__ import annotations

import math

import numpy as np

from bfsitl.fit.log_data import FlightData
from bfsitl.fit.motor_model import PITCH_SIGNS, ROLL_SIGNS, YAW_SIGNS, pt2
from bfsitl.physics import Simulator
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import QuadParams

ACC_LPF_HZ = 25.0
RATE_GAIN = 0.04  # command share per rad/s of rate error
LEVEL_GAIN = 3.0  # rad/s of setpoint per radian of tilt
CLIMB_GAIN = 0.05  # command share per m/s of climb
DRIFT_GAIN = 0.1  # radians of lean per m/s of drift
PUNCH = 2.5


def _roll_pitch(quaternion: tuple[float, float, float, float]) -> tuple[float, float]:
    w, x, y, z = quaternion
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
    return roll, pitch


def _body_velocity(
    quaternion: tuple[float, float, float, float], velocity_ned: tuple[float, float, float]
) -> np.ndarray:
    """The velocity in the body's axes (forward, right, down)."""
    w, x, y, z = quaternion
    to_ned = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    return np.asarray(to_ned.T @ np.array(velocity_ned))


def synthetic_flight(
    quad: QuadParams,
    *,
    seconds: float = 40.0,
    dt_s: float = 0.001,
    seed: int = 1,
    punch_share: float = 0.0,
) -> FlightData:
    """Fly ``quad`` high above the ground for ``seconds`` and record it as a log would;
    ``punch_share`` of the quarter-seconds are punch-outs (the throttle at 2.5 times the
    hover's), which a fit needs for the thrust curve's shape."""
    rng = np.random.default_rng(seed)
    sim = Simulator(quad)
    hover = quad.hover_command
    sim.reset((0.0, 0.0, -500.0), motor_speeds_rad_s=(quad.steady_rotor_speed_rad_s(hover),) * 4)
    steps = int(seconds / dt_s)
    motors = np.empty((4, steps))
    gyro = np.empty((3, steps))
    accel = np.empty(steps)
    setpoint = np.zeros(3)
    collective = hover
    for step in range(steps):
        if step % int(0.25 / dt_s) == 0:
            setpoint = rng.uniform([-2.0, -2.0, -1.0], [2.0, 2.0, 1.0])
            draw = rng.random()
            if draw < punch_share:
                collective = PUNCH * hover
            else:
                collective = hover * (1.0 if draw < 0.5 else rng.uniform(0.85, 1.3))
        state = sim.state
        rates = np.array(state.angular_velocity_frd_rad_s)
        roll, pitch = _roll_pitch(state.quaternion_wxyz)
        # Lean against the drift, as a pilot does: a fast quad's rotors see other air.
        forward, right, _ = _body_velocity(state.quaternion_wxyz, state.velocity_ned_m_s)
        lean = np.array([roll + DRIFT_GAIN * right, pitch - DRIFT_GAIN * forward, 0.0])
        wanted = setpoint - LEVEL_GAIN * lean
        torque = RATE_GAIN * (wanted - rates)
        # Climbing or sinking fast changes what a rotor gives (the blades' inflow): hold
        # the height loosely, as a pilot does.
        climb_m_s = -state.velocity_ned_m_s[2]
        command = (
            collective - CLIMB_GAIN * climb_m_s + torque[0] * ROLL_SIGNS + torque[1] * PITCH_SIGNS
        )
        command = np.clip(command + torque[2] * YAW_SIGNS, 0.02, 1.0)
        sim.step(tuple(float(c) for c in command), dt_s)
        motors[:, step] = command
        gyro[:, step] = sim.state.angular_velocity_frd_rad_s
        accel[step] = -sim.specific_force_frd_m_s2[2] / STANDARD_GRAVITY_M_S2
    # What the log holds for a frame is what the FC read before it wrote the motors.
    gyro = np.concatenate([gyro[:, :1], gyro[:, :-1]], axis=1)
    accel = np.concatenate([accel[:1], accel[:-1]])
    every = np.ones(steps, dtype=bool)
    # The first second settles the rotors from the hover they were started at.
    settled = every.copy()
    settled[: int(1.0 / dt_s)] = False
    return FlightData(
        label="synthetic",
        firmware="none",
        craft=quad.name,
        dt_s=dt_s,
        time_s=np.arange(steps) * dt_s,
        motors=motors,
        gyro_frd_rad_s=gyro,
        accel_up_g=pt2(accel, ACC_LPF_HZ, dt_s),
        throttle=motors.mean(axis=0),
        acc_lpf_hz=ACC_LPF_HZ,
        flying=every,
        usable=settled,
        gaps_s=0.0,
    )
