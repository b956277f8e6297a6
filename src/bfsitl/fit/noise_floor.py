"""The sensors' noise floor as the log holds it: what is left of the gyro and the
accelerometer above :data:`NOISE_ABOVE_HZ` (or a quarter of the log's rate, if lower) while the
quad hangs calm near the hover: a quad's own motion seldom reaches that high.

The log's gyro and accelerometer have been through the FC's own filters, so this is the noise
the PID loop saw, not the raw sensor's; the report says so.  A zero-phase low-pass
(:func:`~bfsitl.fit.motor_model.low_pass`) takes the motion out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bfsitl.fit.log_data import FlightData
from bfsitl.fit.motor_model import low_pass
from bfsitl.fit.thrust import hovering

NOISE_ABOVE_HZ = 100.0


@dataclass(frozen=True, slots=True)
class NoiseFloor:
    """RMS above ``above_hz`` on the calm frames: gyro per axis (deg/s), the accelerometer's
    up axis (g), and how many seconds it was read over."""

    gyro_deg_s: tuple[float, float, float]
    accel_up_g: float
    calm_s: float
    above_hz: float


def noise_floor(data: FlightData) -> NoiseFloor:
    """The noise floor of ``data`` (see the module doc); NaN where the log is never calm."""
    calm = hovering(data)
    above_hz = min(NOISE_ABOVE_HZ, 0.25 / data.dt_s)
    if not calm.any():
        return NoiseFloor((math.nan, math.nan, math.nan), math.nan, 0.0, above_hz)
    gyro = data.gyro_frd_rad_s - low_pass(data.gyro_frd_rad_s, above_hz, data.dt_s)
    accel = data.accel_up_g - low_pass(data.accel_up_g, above_hz, data.dt_s)
    rms = np.degrees(np.sqrt(np.mean(gyro[:, calm] ** 2, axis=1)))
    return NoiseFloor(
        (float(rms[0]), float(rms[1]), float(rms[2])),
        float(np.sqrt(np.mean(accel[calm] ** 2))),
        float(calm.sum()) * data.dt_s,
        above_hz,
    )
