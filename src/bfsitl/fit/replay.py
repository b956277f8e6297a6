"""The open-loop replay, the fit's score: the logged motor commands flown by the embedded
physics, reset to the logged rates at each half-second window's start.

Each window starts the physics high above the ground, level and still, at the logged body
rates and with each rotor at the speed the motor model gives the logged commands there; it is
then stepped with the logged commands at the log's own interval.  The score per axis is the RMS
of the predicted rate's error over the RMS of the logged rate, both low-passed at
:data:`SCORE_CUTOFF_HZ`; the vertical acceleration's is the same on the accelerometer's up axis
(the prediction's change from the window's start, added to the logged value there and put
through the FC's accelerometer low-pass), over the RMS
of the logged acceleration less 1 g (what the quad climbed and sank with, not gravity).  "hold" is
the score of predicting no change at all: a model worth having scores well below it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfsitl.fit.log_data import FlightData
from bfsitl.fit.motor_model import curve_beta, delayed, low_pass, pt2, rotor_speeds
from bfsitl.fit.windows import Windows
from bfsitl.physics import Simulator
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import QuadParams

SCORE_CUTOFF_HZ = 50.0
#: Where each window starts: high enough that no window reaches the ground.
START_ALTITUDE_M = 500.0


@dataclass(frozen=True, slots=True)
class ReplayScore:
    """Error over signal per body axis (roll, pitch, yaw) and on the vertical acceleration."""

    rates: tuple[float, float, float]
    accel_up: float

    def as_dict(self) -> dict[str, float]:
        roll, pitch, yaw = self.rates
        return {"roll": roll, "pitch": pitch, "yaw": yaw, "accel_up": self.accel_up}


@dataclass(frozen=True, slots=True)
class Replay:
    """The predicted and logged traces per window: rates (3, windows, length) rad/s, the
    accelerometer's up axis (windows, length) g."""

    predicted_rates: np.ndarray
    logged_rates: np.ndarray
    predicted_accel_up_g: np.ndarray
    logged_accel_up_g: np.ndarray


def replay(
    data: FlightData, windows: Windows, quad: QuadParams, *, delay_frames: int = 0
) -> Replay:
    """Fly each window of ``data`` with ``quad`` (see the module doc), the motors seen
    ``delay_frames`` late (the log's gyro filtering, as the fit found it)."""
    top = quad.steady_rotor_speed_rad_s(1.0)
    commands = delayed(data.motors, delay_frames)
    speeds = rotor_speeds(commands, curve_beta(quad), quad.motor_time_constant_s, data.dt_s) * top
    sim = Simulator(quad)
    count, length = len(windows), windows.length
    rates = np.empty((3, count, length))
    accel = np.empty((count, length))
    for row, start in enumerate(windows.starts.tolist()):
        motors = commands[:, start : start + length].T.tolist()
        roll, pitch, yaw = (float(v) for v in data.gyro_frd_rad_s[:, start])
        # The gyro at a frame has felt the rotors as they were after the step before it (the
        # physics moves the motors first, then the body).
        m1, m2, m3, m4 = (float(v) for v in speeds[:, max(start - 1, 0)])
        sim.reset(
            (0.0, 0.0, -START_ALTITUDE_M),
            angular_velocity_frd_rad_s=(roll, pitch, yaw),
            motor_speeds_rad_s=(m1, m2, m3, m4),
        )
        level = -sim.specific_force_frd_m_s2[2] / STANDARD_GRAVITY_M_S2
        for column in range(length):
            sim.step(motors[column], data.dt_s)
            rates[:, row, column] = sim.state.angular_velocity_frd_rad_s
            accel[row, column] = -sim.specific_force_frd_m_s2[2] / STANDARD_GRAVITY_M_S2 - level
    logged_accel = windows.spans(data.accel_up_g)
    # The acceleration is reset to the logged one too: the log has no airspeed, and a rotor's
    # thrust at a command depends on it (the blades' inflow), so the physics started still
    # gives another level; what the motors change from there is the prediction.
    start_level = logged_accel[:, :1]
    moved = accel + start_level
    filtered = np.vstack(
        [
            pt2(moved[row], data.acc_lpf_hz, data.dt_s, start=float(start_level[row, 0]))
            for row in range(count)
        ]
    )
    return Replay(
        predicted_rates=rates,
        logged_rates=windows.spans(data.gyro_frd_rad_s)[:, :, 1:],
        predicted_accel_up_g=filtered,
        logged_accel_up_g=logged_accel[:, 1:],
    )


def _ratio(predicted: np.ndarray, logged: np.ndarray, dt_s: float, *, level: float = 0.0) -> float:
    error = low_pass(predicted - logged, SCORE_CUTOFF_HZ, dt_s)
    signal = low_pass(logged - level, SCORE_CUTOFF_HZ, dt_s)
    return float(np.sqrt(np.mean(error**2)) / max(np.sqrt(np.mean(signal**2)), 1e-12))


def score(result: Replay, dt_s: float) -> ReplayScore:
    """Error over signal per axis (see the module doc)."""
    rates = tuple(
        _ratio(result.predicted_rates[axis], result.logged_rates[axis], dt_s) for axis in range(3)
    )
    accel = _ratio(result.predicted_accel_up_g, result.logged_accel_up_g, dt_s, level=1.0)
    return ReplayScore((rates[0], rates[1], rates[2]), accel)


def hold_score(data: FlightData, windows: Windows) -> ReplayScore:
    """The score of predicting that nothing changes from each window's start."""
    logged = windows.spans(data.gyro_frd_rad_s)
    held = np.broadcast_to(logged[:, :, :1], logged[:, :, 1:].shape)
    accel = windows.spans(data.accel_up_g)
    held_accel = np.broadcast_to(accel[:, :1], accel[:, 1:].shape)
    rates = tuple(_ratio(held[axis], logged[axis, :, 1:], data.dt_s) for axis in range(3))
    return ReplayScore(
        (rates[0], rates[1], rates[2]), _ratio(held_accel, accel[:, 1:], data.dt_s, level=1.0)
    )
