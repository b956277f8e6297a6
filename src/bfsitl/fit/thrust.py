"""The thrust: how many g the four rotors give at full command, and the command that hovers.

In flight the accelerometer's up axis reads the thrust over the mass, in g.  The ratio is read
where the quad hangs near 1 g, calm: the accelerometer over the model's thrust share there (the
four rotors of :mod:`bfsitl.fit.motor_model` through the FC's own accelerometer low-pass), as a
median.  So the fitted quad hovers at the log's own command.

The curve's shape (how thrust grows with the command) is the base profile's, not fitted: a log
has no airspeed, and a climbing rotor gives less thrust (its blades meet the air at a smaller
angle), so a shape fitted to punch-outs came out 20-25 % low in thrust on synthetic flights of
known quads (the shipped profiles flown by the embedded physics, which has that inflow).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bfsitl.errors import FitError
from bfsitl.fit.log_data import FlightData
from bfsitl.fit.motor_model import pt2, rotor_speeds
from bfsitl.fit.rotation import Estimate

#: A frame counts as hovering within this of 1 g, with the rates below HOVER_RATE_DEG_S.
HOVER_BAND_G = 0.05
HOVER_RATE_DEG_S = 30.0
#: A log needs this long near the hover to give its thrust and its hover command.
MIN_HOVER_S = 0.5


@dataclass(frozen=True, slots=True)
class ThrustFit:
    """The thrust-to-weight ratio (four rotors at full command), the curve's shape ``beta``
    it was read with (0: thrust grows as the command squared; large: linearly), the thrust the
    log spans (5th and 95th percentile, g) and the share of the accelerometer's variance the
    model explains."""

    thrust_to_weight: Estimate
    beta: float
    span_g: tuple[float, float]
    explained: float


def thrust_up_g(
    data: FlightData, thrust_to_weight: float, beta: float, time_constant_s: float
) -> np.ndarray:
    """The model's accelerometer up axis: four rotors' thrust, through the FC's low-pass."""
    speeds = rotor_speeds(data.motors, beta, time_constant_s, data.dt_s)
    raw = thrust_to_weight / 4.0 * np.sum(speeds**2, axis=0)
    return pt2(raw, data.acc_lpf_hz, data.dt_s)


def _widened(std: float, residuals: np.ndarray) -> float:
    """A standard error widened for the residuals' lag-one autocorrelation."""
    if len(residuals) < 3:
        return std
    rho = float(np.corrcoef(residuals[:-1], residuals[1:])[0, 1])
    rho = min(max(rho, 0.0), 0.999)
    return std * math.sqrt((1.0 + rho) / (1.0 - rho))


def fit_thrust(
    data: FlightData, time_constant_s: float, beta: float, *, until: int | None = None
) -> ThrustFit:
    """The thrust-to-weight ratio, read where the quad hangs near 1 g (see the module doc).

    Args:
        data: The flight.
        time_constant_s: The motors' lag (from :func:`~bfsitl.fit.rotation.fit_rotation`).
        beta: The curve's shape (the base profile's).
        until: Only frames before this one (the training share).

    Raises:
        FitError: The quad never hangs near 1 g long enough.
    """
    use = data.usable.copy()
    if until is not None:
        use[until:] = False
    calm = calm_frames(data, until)
    # The ratio is what the accelerometer reads over the model's thrust share where the quad
    # hangs near 1 g (a median: a gust or a climb moves a frame, not the figure).
    share = thrust_up_g(data, 1.0, beta, time_constant_s)
    ratios = data.accel_up_g[calm] / np.maximum(share[calm], 1e-6)
    value = float(np.median(ratios))
    # The median's standard error, widened for neighbouring frames not being independent.
    std = _widened(1.2533 * float(np.std(ratios)) / math.sqrt(len(ratios)), ratios - value)
    explained = 1.0 - float(np.var(data.accel_up_g[use] - value * share[use])) / max(
        float(np.var(data.accel_up_g[use])), 1e-12
    )
    low, high = np.percentile(data.accel_up_g[use], [5, 95])
    return ThrustFit(Estimate(value, std), beta, (float(low), float(high)), explained)


def calm_frames(data: FlightData, until: int | None = None) -> np.ndarray:
    """The frames before ``until`` where the quad hangs near 1 g, calm.

    Raises:
        FitError: Fewer than :data:`MIN_HOVER_S` of them: the thrust cannot be read.
    """
    calm = hovering(data)
    if until is not None:
        calm[until:] = False
    if calm.sum() * data.dt_s < MIN_HOVER_S:
        raise FitError(
            f"{data.label}: the quad never hangs near 1 g for {MIN_HOVER_S:g} s in the part "
            "the fit reads (the first 70 % of the usable flight), so its thrust cannot be read "
            "(fly a hover early in the log)"
        )
    return calm


def hovering(data: FlightData) -> np.ndarray:
    """Frames where the quad hangs near 1 g with calm rates."""
    return (
        data.usable
        & (np.abs(data.accel_up_g - 1.0) < HOVER_BAND_G)
        & np.all(np.abs(data.gyro_frd_rad_s) < math.radians(HOVER_RATE_DEG_S), axis=0)
    )


def hover_command(data: FlightData) -> float:
    """The log's median mean motor command (0..1) where the quad hangs near 1 g, calm.

    Raises:
        FitError: The quad never hangs near 1 g long enough to read it.
    """
    calm = hovering(data)
    if calm.sum() * data.dt_s < MIN_HOVER_S:
        raise FitError(
            f"{data.label}: the quad never hangs near 1 g for {MIN_HOVER_S:g} s, so its hover "
            "command cannot be read (fly a hover in the log)"
        )
    return float(np.median(data.motors.mean(axis=0)[calm]))
