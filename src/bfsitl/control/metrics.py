"""Step-response figures of an altitude trace: rise, overshoot, settling, steady error, tilt.

Conventions (the usual control-textbook ones, spelled out because each has variants):

* the step is commanded at ``step_time_s`` (default: the first sample) from ``start_m`` to
  ``target_m``; downward steps work the same way, mirrored;
* **rise time**: from the first crossing of 10 % of the step to the first crossing of 90 %,
  each crossing time linearly interpolated between samples;
* **overshoot**: how far the trace went beyond the target, in % of the step (0 if never);
* **settling time**: from the command until the trace enters the band ``target +- band_m``
  for good (interpolated at the band edge after the last sample outside it); 0 if it never
  left the band, ``inf`` if the last sample is still outside;
* **steady-state RMS**: root mean square of ``altitude - target`` over the last
  ``steady_window_s`` seconds of the trace (the hold), with the mean error (bias) beside it;
* **max attitude**: the largest ``|roll|`` or ``|pitch|`` seen (NaN when not given): an
  altitude controller that pumps the throttle shakes the attitude loop too.

Whatever did not happen (never reached 90 %, never settled) is ``inf``: worse than any number,
so ``settling_time_s < 4`` is simply false.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from bfsitl.errors import (
    MetricsInputError,
)

DEFAULT_BAND_M = 0.05
DEFAULT_STEADY_WINDOW_S = 5.0


@dataclass(frozen=True, slots=True)
class StepMetrics:
    """How well an altitude step was followed (see the module docstring for definitions)."""

    rise_time_s: float
    overshoot_pct: float
    settling_time_s: float
    steady_state_rms_m: float
    steady_state_mean_error_m: float
    max_attitude_deg: float
    peak_alt_m: float
    band_m: float
    steady_window_s: float

    @property
    def settled(self) -> bool:
        return math.isfinite(self.settling_time_s)


def step_response(
    time_s: Sequence[float],
    altitude_m: Sequence[float],
    *,
    target_m: float,
    start_m: float = 0.0,
    band_m: float = DEFAULT_BAND_M,
    steady_window_s: float = DEFAULT_STEADY_WINDOW_S,
    step_time_s: float | None = None,
    roll_deg: Sequence[float] | None = None,
    pitch_deg: Sequence[float] | None = None,
) -> StepMetrics:
    """Measure one step response; ``time_s`` must be strictly increasing."""
    times, alts = _checked(time_s, altitude_m, target_m, start_m, band_m, steady_window_s)
    t0 = times[0] if step_time_s is None else float(step_time_s)
    step = target_m - start_m
    sign = 1.0 if step > 0 else -1.0
    # Progress along the step, 0 at the start, 1 at the target, whatever the direction.
    progress = [(a - start_m) / step for a in alts]
    t10 = _first_crossing(times, progress, 0.1)
    t90 = _first_crossing(times, progress, 0.9)
    rise_s = t90 - t10 if math.isfinite(t10) and math.isfinite(t90) else math.inf
    peak = max(alts) if sign > 0 else min(alts)
    overshoot_pct = max(0.0, (peak - target_m) * sign / abs(step) * 100.0)
    settle_s = _settling_time(times, [a - target_m for a in alts], band_m) - t0
    window_start = times[-1] - steady_window_s
    errors = [a - target_m for t, a in zip(times, alts, strict=True) if t >= window_start]
    rms = math.sqrt(sum(e * e for e in errors) / len(errors))
    mean_error = sum(errors) / len(errors)
    return StepMetrics(
        rise_time_s=rise_s,
        overshoot_pct=overshoot_pct,
        settling_time_s=max(0.0, settle_s),
        steady_state_rms_m=rms,
        steady_state_mean_error_m=mean_error,
        max_attitude_deg=_max_attitude(len(times), roll_deg, pitch_deg),
        peak_alt_m=peak,
        band_m=band_m,
        steady_window_s=steady_window_s,
    )


def _checked(
    time_s: Sequence[float],
    altitude_m: Sequence[float],
    target_m: float,
    start_m: float,
    band_m: float,
    steady_window_s: float,
) -> tuple[list[float], list[float]]:
    times = [float(t) for t in time_s]
    alts = [float(a) for a in altitude_m]
    if len(times) != len(alts):
        raise MetricsInputError(f"time_s has {len(times)} samples but altitude_m has {len(alts)}")
    if len(times) < 2:
        raise MetricsInputError(f"a step response needs at least 2 samples, got {len(times)}")
    if not all(math.isfinite(v) for v in times + alts):
        raise MetricsInputError("time_s and altitude_m must be finite numbers")
    if any(b <= a for a, b in zip(times, times[1:], strict=False)):
        raise MetricsInputError("time_s must be strictly increasing")
    if not (math.isfinite(target_m) and math.isfinite(start_m) and target_m != start_m):
        raise MetricsInputError(
            f"target_m ({target_m}) and start_m ({start_m}) must be finite and differ"
        )
    if not (math.isfinite(band_m) and band_m > 0):
        raise MetricsInputError(f"band_m must be > 0, got {band_m}")
    if not (math.isfinite(steady_window_s) and steady_window_s > 0):
        raise MetricsInputError(f"steady_window_s must be > 0, got {steady_window_s}")
    return times, alts


def _first_crossing(times: list[float], progress: list[float], level: float) -> float:
    """Interpolated time at which ``progress`` first reaches ``level`` (inf if never)."""
    if progress[0] >= level:
        return times[0]
    for i in range(1, len(times)):
        if progress[i] >= level:
            p0, p1 = progress[i - 1], progress[i]
            return times[i - 1] + (level - p0) / (p1 - p0) * (times[i] - times[i - 1])
    return math.inf


def _settling_time(times: list[float], errors: list[float], band_m: float) -> float:
    """Absolute time the error enters ``+-band_m`` for good (``-inf`` if never outside)."""
    last_out = -1
    for i in range(len(errors) - 1, -1, -1):
        if abs(errors[i]) > band_m:
            last_out = i
            break
    if last_out < 0:
        return -math.inf
    if last_out == len(errors) - 1:
        return math.inf
    e0, e1 = errors[last_out], errors[last_out + 1]
    edge = band_m if e0 > 0 else -band_m
    if e1 == e0:
        return times[last_out + 1]
    fraction = min(1.0, max(0.0, (edge - e0) / (e1 - e0)))
    return times[last_out] + fraction * (times[last_out + 1] - times[last_out])


def _max_attitude(
    count: int,
    roll_deg: Sequence[float] | None,
    pitch_deg: Sequence[float] | None,
) -> float:
    worst = math.nan
    for name, series in (("roll_deg", roll_deg), ("pitch_deg", pitch_deg)):
        if series is None:
            continue
        values = [abs(float(v)) for v in series]
        if len(values) != count:
            raise MetricsInputError(f"{name} has {len(values)} samples, time_s has {count}")
        if values:
            biggest = max(values)
            worst = biggest if math.isnan(worst) else max(worst, biggest)
    return worst
