"""The step response of one rate axis, from setpoint to gyro, estimated from free flight.

``bfsitl log replay`` flies a real flight's sticks again through the firmware; whether the
simulated quad behaves like the real one is judged per axis (roll, pitch, yaw) on the step
response from the setpoint (deg/s, what the pilot asked) to the gyro (deg/s, what the quad
did): its rise time, overshoot and settling time.  A flight holds no clean steps, so the
response is estimated from whatever the pilot did, the same way for both logs.

Method (windowed Wiener deconvolution, the usual one for blackbox logs):

* the flight is cut into windows of :data:`WINDOW_S`, each starting :data:`HOP_SHARE` of a
  window after the last (75 % overlap); a window is used only if its samples are all finite
  (NaN gaps are skipped, never bridged), its setpoint moves by at least
  :data:`MIN_INPUT_DPS` (max - min): a still stick says nothing about the response, and its
  gyro follows the setpoint (:data:`MIN_CORRELATION`): the ground or a crash is no rate loop;
* each window's mean is removed and it is Hann-tapered.  Without the mean, a window flown at a
  steady rate (a held roll) leaks its large zero-frequency content through the taper into
  the low frequencies, and the estimated response then sags below its true level;
* the impulse response is ``h = IFFT(S_yx / (S_xx + lambda * max S_xx))``, where ``S_yx`` and
  ``S_xx`` are the windows' cross- and input spectra *summed over the windows* before the
  division: the per-window deconvolution ``Y X* / |X|^2`` averaged with each window
  weighted, frequency by frequency, by the input it holds there.  An unweighted mean of
  per-window responses lets the many windows with little input at a frequency carry their
  gyro noise, divided by that little input, into the result: on a real log's sticks with
  gyro noise added it read overshoots tens to hundreds of percentage points too high;
* ``lambda`` (:data:`REGULARISATION`, relative to the strongest bin of the summed input
  spectrum, so that it does not depend on the sample rate or the flight's length) leaves
  alone the frequencies the pilot excited and fades out those he did not, where the ratio
  would be noise.  Real sticks carry little above 10-20 Hz (1e-4 of their peak at about
  13 Hz on a 5-inch freestyle log), so this also sets the fastest rise the estimate can
  show: a quad faster than the sticks excite reads slower than it is, and differences
  between two quads shrink.  Both logs of a replay share the sticks, hence this limit.
  Measured with that log's sticks flown through known systems, with gyro noise: 1e-4 kept
  the noise's effect to about 1 ms of rise and 2 percentage points of overshoot; 1e-5 read
  the clean systems closer (27 ms, not 34, for a true 23 ms rise) but up to 8 points more
  overshoot with noise, which would set a noisy real log apart from a clean simulated one;
* the step response is the running sum of ``h`` over :data:`RESPONSE_S` (1.0 = the setpoint
  reached), started :data:`LEAD_S` before 0 (see there).

Window length: a 1 s window reads slow responses a little fast (an edge effect of the taper,
growing with the response's lag): -2 % on a 33 ms rise (first-order lag), -9 % on 55 ms,
-15 % on 88 ms; second-order responses with 20-40 ms rises within 3 %.  2 s windows halve
that but give half the windows and a coarser choice of them.

Figures, all relative to the *steady level* (the response's mean from :data:`STEADY_FROM_S`
to its end, i.e. the axis' gain; 1.0 = the gyro follows the setpoint exactly):

* **delay**: time to 50 % of the steady level; **rise time**: from 10 % to 90 %, each the
  first crossing, linearly interpolated between samples;
* **overshoot**: ``(peak / steady level - 1) * 100``, percentage points, 0 if never above;
* **settling time**: when the response enters ``steady level +- 5 %`` for good
  (interpolated at the band edge), 0 if it never left it; it jumps by a half-period when
  the overshoot is near 5 %.

What did not happen (never reached 90 %, still outside the band at the end) is ``inf``; with
a steady level that is not positive (no response, or the gyro's sign inverted) every figure
is NaN.  Only numpy: plain FFTs are all the method needs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bfsitl.errors import MetricsInputError

__all__ = ["StepResponse", "step_response"]

WINDOW_S = 1.0
#: The hop between window starts, as a share of a window (0.25: 75 % overlap, Hann windows
#: overlapped so that every sample is weighted about equally).
HOP_SHARE = 0.25
#: Long enough for a rate loop to settle (tens of ms) and for the slower I-term part to show.
RESPONSE_S = 0.5
STEADY_FROM_S = 0.2
#: A pilot's deliberate stick movement is hundreds of deg/s; hover corrections a few.
MIN_INPUT_DPS = 20.0
#: A window is used only if its gyro follows its setpoint: their correlation, the setpoint
#: delayed by 0 to MAX_LAG_S (a rate loop answers well within it), reaches MIN_CORRELATION.
#: On a real 5-inch log, flown windows read 0.9-1.0; this left out the take-off (the ground
#: holds the quad), a throttle cut and the crash at the end (0.6 and below).  Without it the
#: crash's few windows, which hold much stick input, turned the pitch's gain to -0.02.
MIN_CORRELATION = 0.8
MAX_LAG_S = 0.1
REGULARISATION = 1e-4
SETTLING_BAND = 0.05
#: The regularised estimate is zero-phase: it blurs the response's onset both ways in time,
#: part of it to negative lags (the end of the FFT's circle).  The step response sums ``h``
#: from this far before 0, so that the part is kept: without it, a first-order lag with no
#: delay read a gain of 0.93.  A pilot reacts to the quad far more slowly than this, so
#: these lags hold no feedback from the gyro to the sticks.
LEAD_S = 0.02


@dataclass(frozen=True, slots=True)
class StepResponse:
    """One axis' estimated step response and its figures (see the module docstring)."""

    time_s: np.ndarray  # the response's time axis, from 0, one sample per 1 / rate_hz
    response: np.ndarray  # the averaged step response (1.0 = setpoint reached)
    steady_level: float  # the gain: mean response from STEADY_FROM_S to the end
    delay_ms: float  # time to 50 % of the steady level
    rise_time_ms: float  # 10 % to 90 % of the steady level
    overshoot_pct: float  # percentage points above the steady level at the peak
    settling_time_ms: float  # enters steady level +- 5 % for good
    windows: int  # windows used


def step_response(
    setpoint_dps: np.ndarray,
    gyro_dps: np.ndarray,
    rate_hz: float,
    *,
    window_s: float = WINDOW_S,
    response_s: float = RESPONSE_S,
    steady_from_s: float = STEADY_FROM_S,
    min_input_dps: float = MIN_INPUT_DPS,
    regularisation: float = REGULARISATION,
) -> StepResponse | None:
    """The step response from one axis' setpoint to its gyro, both sampled uniformly at
    ``rate_hz``; None if no window has enough stick input (and a gyro following it)."""
    x = np.asarray(setpoint_dps, dtype=float)
    y = np.asarray(gyro_dps, dtype=float)
    _check(x, y, rate_hz, window_s, response_s, steady_from_s, regularisation)
    n = int(round(window_s * rate_hz))
    m = int(round(response_s * rate_hz))
    starts = _usable_starts(x, y, n, max(1, int(round(n * HOP_SHARE))), min_input_dps)
    if len(starts) == 0:
        return None
    index = starts[:, None] + np.arange(n)[None, :]
    xs, ys = x[index], y[index]
    taper = np.hanning(n)
    # Zero-padded to hold the window and the response: h's first m samples do not wrap round.
    n_fft = 1 << (n + m - 1).bit_length()
    x_w = (xs - xs.mean(axis=1, keepdims=True)) * taper
    y_w = (ys - ys.mean(axis=1, keepdims=True)) * taper
    x_f, y_f = np.fft.rfft(x_w, n_fft), np.fft.rfft(y_w, n_fft)
    cross = y_f * np.conj(x_f)
    # Each window's correlation of gyro and setpoint at the lags a rate loop answers within;
    # its size, so that a gyro of inverted sign still gives a (negative) steady level.
    lagged = np.fft.irfft(cross, n_fft, axis=1)[:, : int(round(MAX_LAG_S * rate_hz)) + 1]
    energy = np.sqrt(np.sum(x_w**2, axis=1) * np.sum(y_w**2, axis=1))
    follows = np.abs(lagged).max(axis=1) > MIN_CORRELATION * energy  # a still gyro: 0 > 0
    if not follows.any():
        return None
    s_xx = np.sum(np.abs(x_f[follows]) ** 2, axis=0)
    s_yx = np.sum(cross[follows], axis=0)
    impulse = np.fft.irfft(s_yx / (s_xx + regularisation * s_xx.max()), n_fft)
    lead = int(round(LEAD_S * rate_hz))
    response = np.cumsum(impulse[:m]) + impulse[n_fft - lead :].sum()
    time_s = np.arange(m) / rate_hz
    for array in (time_s, response):
        array.setflags(write=False)
    return _with_figures(time_s, response, steady_from_s, int(follows.sum()))


def _check(
    x: np.ndarray,
    y: np.ndarray,
    rate_hz: float,
    window_s: float,
    response_s: float,
    steady_from_s: float,
    regularisation: float,
) -> None:
    if x.ndim != 1 or x.shape != y.shape:
        raise MetricsInputError(
            f"setpoint and gyro must be 1-D series of one length, got {x.shape} and {y.shape}"
        )
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise MetricsInputError(f"rate_hz must be > 0, got {rate_hz}")
    if not 0 < steady_from_s < response_s <= window_s:
        raise MetricsInputError(
            "need 0 < steady_from_s < response_s <= window_s, got "
            f"{steady_from_s}, {response_s}, {window_s}"
        )
    if (response_s - steady_from_s) * rate_hz < 1:
        raise MetricsInputError(f"at {rate_hz} Hz the steady part of the response is empty")
    if not (math.isfinite(regularisation) and regularisation > 0):
        raise MetricsInputError(f"regularisation must be > 0, got {regularisation}")


def _usable_starts(
    x: np.ndarray, y: np.ndarray, n: int, hop: int, min_input_dps: float
) -> np.ndarray:
    """Starts of the windows that are all finite and in which the setpoint moves enough."""
    if len(x) < n:
        return np.zeros(0, dtype=np.int64)
    starts = np.arange(0, len(x) - n + 1, hop)
    bad = np.concatenate([[0], np.cumsum(~(np.isfinite(x) & np.isfinite(y)))])
    starts = starts[bad[starts + n] == bad[starts]]
    if len(starts) == 0:
        return starts
    views = np.lib.stride_tricks.sliding_window_view(x, n)[starts]
    return starts[np.ptp(views, axis=1) >= min_input_dps]


def _with_figures(
    time_s: np.ndarray, response: np.ndarray, steady_from_s: float, windows: int
) -> StepResponse:
    steady = float(np.mean(response[time_s >= steady_from_s - 1e-12]))
    nan = math.nan
    delay = rise = overshoot = settling = nan
    if math.isfinite(steady) and steady > 0:
        relative = response / steady
        t10, t50, t90 = (_first_crossing(time_s, relative, level) for level in (0.1, 0.5, 0.9))
        delay = t50 * 1e3
        rise = (t90 - t10) * 1e3 if math.isfinite(t90) else math.inf
        overshoot = max(0.0, (float(relative.max()) - 1.0) * 100.0)
        settling = _settling_time(time_s, relative) * 1e3
    return StepResponse(
        time_s=time_s,
        response=response,
        steady_level=steady,
        delay_ms=delay,
        rise_time_ms=rise,
        overshoot_pct=overshoot,
        settling_time_ms=settling,
        windows=windows,
    )


def _first_crossing(time_s: np.ndarray, relative: np.ndarray, level: float) -> float:
    """Interpolated time at which ``relative`` first reaches ``level`` (inf if never)."""
    above = np.flatnonzero(relative >= level)
    if len(above) == 0:
        return math.inf
    i = int(above[0])
    if i == 0:
        return float(time_s[0])
    r0, r1 = relative[i - 1], relative[i]
    return float(time_s[i - 1] + (level - r0) / (r1 - r0) * (time_s[i] - time_s[i - 1]))


def _settling_time(time_s: np.ndarray, relative: np.ndarray) -> float:
    """When ``relative`` enters ``1 +- SETTLING_BAND`` for good (0 if never outside, inf if
    still outside at the end), the crossing interpolated at the band's edge."""
    error = np.abs(relative - 1.0)
    outside = np.flatnonzero(error > SETTLING_BAND)
    if len(outside) == 0:
        return 0.0
    i = int(outside[-1])
    if i == len(error) - 1:
        return math.inf
    e0, e1 = error[i], error[i + 1]
    return float(time_s[i] + (e0 - SETTLING_BAND) / (e0 - e1) * (time_s[i + 1] - time_s[i]))
