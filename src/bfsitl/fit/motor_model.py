"""The embedded physics' motor and thrust, as array operations for the fit (what
``kernel/physics.c`` does per step, on a whole log at once), and the FC's filters the fit
must see the model through.

A motor's steady speed, as a share ``x`` of its full speed, solves ``(1 + beta) u - x =
beta x^2`` for the command ``u``: the speed controller's drive against the prop's drag torque
(``beta = k_Q w_max / P``; 0 makes thrust ``u^2``, large makes it linear in ``u``).  The
speed follows as a first-order lag of the motor's time constant, exactly as the physics
steps it, and the thrust is ``x^2`` of the full thrust (no inflow: a log has no vertical
speed).  The score (:mod:`bfsitl.fit.replay`) flies the physics itself, not this.

scipy.signal is imported inside the functions that use it: it takes a second to import, and
every scenario run imports this module (through the replay expectations) without fitting.
"""

from __future__ import annotations

import math

import numpy as np

from bfsitl.physics.params import QuadParams

#: Betaflight's PT2 puts its cut-off where two PT1 stages give -3 dB together.
PT2_CUTOFF_CORRECTION = 1.553773974


def curve_beta(quad: QuadParams) -> float:
    """The thrust curve's shape ``beta`` the physics gives ``quad``: ``k_Q w_max / P``."""
    top = quad.steady_rotor_speed_rad_s(1.0)
    return quad.torque_coefficient_nm_per_rad2_s2 * top / quad.motor_p_gain_nm_s_per_rad


def steady_speed_share(command: np.ndarray, beta: float) -> np.ndarray:
    """The steady rotor speed, a share of full speed, for commands 0..1."""
    u = np.clip(command, 0.0, 1.0)
    if beta < 1e-9:
        return u
    return (np.sqrt(1.0 + 4.0 * beta * (1.0 + beta) * u) - 1.0) / (2.0 * beta)


def lagged(target: np.ndarray, time_constant_s: float, dt_s: float, start: float) -> np.ndarray:
    """``target`` followed by a first-order lag, stepped as the physics steps it."""
    from scipy import signal  # imported when used: see the module docstring

    alpha = -math.expm1(-dt_s / time_constant_s)
    zi = np.array([(1.0 - alpha) * start])
    out, _ = signal.lfilter([alpha], [1.0, alpha - 1.0], target, zi=zi)
    return np.asarray(out)


def rotor_speeds(
    motors: np.ndarray, beta: float, time_constant_s: float, dt_s: float
) -> np.ndarray:
    """Each rotor's speed share over the log (4, N), from rest at the steady speed."""
    steady = steady_speed_share(motors, beta)
    return np.vstack(
        [lagged(steady[i], time_constant_s, dt_s, steady[i][0]) for i in range(len(steady))]
    )


def delayed(values: np.ndarray, frames: int) -> np.ndarray:
    """``values`` (..., N) as seen ``frames`` later: the first value held at the start."""
    if frames <= 0:
        return values
    head = np.repeat(values[..., :1], frames, axis=-1)
    return np.concatenate([head, values[..., :-frames]], axis=-1)


def pt2(
    values: np.ndarray, cutoff_hz: float, dt_s: float, start: float | None = None
) -> np.ndarray:
    """Betaflight's PT2 low-pass (two PT1 stages); ``cutoff_hz`` 0 passes ``values`` on."""
    if cutoff_hz <= 0:
        return values
    from scipy import signal  # imported when used: see the module docstring

    rc = 1.0 / (2.0 * math.pi * cutoff_hz * PT2_CUTOFF_CORRECTION)
    k = dt_s / (rc + dt_s)
    first = values[0] if start is None else start
    once, _ = signal.lfilter([k], [1.0, k - 1.0], values, zi=np.array([(1.0 - k) * first]))
    twice, _ = signal.lfilter([k], [1.0, k - 1.0], once, zi=np.array([(1.0 - k) * first]))
    return np.asarray(twice)


def low_pass(values: np.ndarray, cutoff_hz: float, dt_s: float) -> np.ndarray:
    """A zero-phase second-order Butterworth low-pass along the last axis (both directions)."""
    from scipy import signal  # imported when used: see the module docstring

    nyquist = 0.5 / dt_s
    if cutoff_hz >= 0.95 * nyquist:
        return values
    b, a = signal.butter(2, cutoff_hz / nyquist)
    padlen = min(3 * max(len(a), len(b)), values.shape[-1] - 1)
    return np.asarray(signal.filtfilt(b, a, values, axis=-1, padlen=padlen))


#: Torque on each body axis per unit of each rotor's thrust, as signs: roll from the right
#: rotors (M1, M2) down, pitch from the front ones (M2, M4) up, yaw from the counter-clockwise
#: ones (M2, M3), Betaflight's quad-X with props in.
ROLL_SIGNS = np.array([-1.0, -1.0, 1.0, 1.0])
PITCH_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0])
YAW_SIGNS = np.array([-1.0, 1.0, 1.0, -1.0])
