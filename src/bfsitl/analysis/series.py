"""What the analysers compute over a track's points: stretches that pass a test, their
duration, window means, a swing's size and frequency, a descent rate; and how an analyser says
the track lacks what it reads (:func:`require`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence

from bfsitl.analysis.track import Track, TrackPoint
from bfsitl.errors import TrackDataMissingError

#: The autopilot's phase in which it holds a target.
HOLD_PHASE = "hold"


def held_points(track: Track, settle_s: float) -> list[TrackPoint]:
    """Points of the autopilot's holds, after each hold's first ``settle_s`` (which
    settle)."""
    held: list[TrackPoint] = []
    for first, last in runs(track.points, lambda p: p.phase == HOLD_PHASE):
        start = track.points[first].time_s + settle_s
        held.extend(p for p in track.points[first : last + 1] if p.time_s >= start)
    return held


def runs(
    points: Sequence[TrackPoint], test: Callable[[TrackPoint], bool]
) -> Iterator[tuple[int, int]]:
    """(first, last) index of each stretch of consecutive points that pass ``test``."""
    start: int | None = None
    for index, point in enumerate(points):
        if test(point):
            if start is None:
                start = index
        elif start is not None:
            yield start, index - 1
            start = None
    if start is not None:
        yield start, len(points) - 1


def span_s(points: Sequence[TrackPoint], first: int, last: int) -> float:
    """A stretch's duration: to the point after it when there is one (a single point at
    50 Hz lasts a control step, not zero)."""
    end = points[last + 1].time_s if last + 1 < len(points) else points[last].time_s
    return end - points[first].time_s


def require(track: Track, *names: str) -> None:
    missing = [name for name in names if not track.has(name)]
    if missing:
        raise TrackDataMissingError(f"the {track.source} track has no {', '.join(missing)}")


def finite(value: float) -> bool:
    return math.isfinite(value)


def evidence_of(point: TrackPoint) -> dict[str, float | str | bool]:
    """The point as evidence: its time and the values that are known."""
    keep: dict[str, float | str | bool] = {"time_s": point.time_s, "armed": point.armed}
    for name in (
        "alt_m",
        "climb_m_s",
        "north_m",
        "east_m",
        "tilt_deg",
        "roll_deg",
        "pitch_deg",
        "accel_g",
    ):
        value = getattr(point, name)
        if finite(value):
            keep[name] = round(value, 3)
    if point.phase:
        keep["phase"] = point.phase
    if point.motors:
        keep["motors"] = ",".join(f"{m:.2f}" for m in point.motors)
    return keep


def descent_before(track: Track, index: int) -> float:
    """The downward speed in the half second before the point at ``index`` (a line fitted
    to the heights); NaN without heights.  The points are in time order: the window is
    found walking back from the point, not by a look at every point of the track."""
    points = track.points
    time_s = points[index].time_s
    window = []
    for before in range(index - 1, -1, -1):
        p = points[before]
        if p.time_s < time_s - 0.5:
            break
        if p.time_s < time_s and finite(p.alt_m):
            window.append((p.time_s, p.alt_m))
    window.reverse()
    if len(window) < 3:
        return math.nan
    mean_t = sum(t for t, _ in window) / len(window)
    mean_a = sum(a for _, a in window) / len(window)
    spread = sum((t - mean_t) ** 2 for t, _ in window)
    if spread <= 0:
        return math.nan
    return -sum((t - mean_t) * (a - mean_a) for t, a in window) / spread


def window_means(
    points: Sequence[TrackPoint], value: Callable[[TrackPoint], float], window_s: float
) -> Iterator[tuple[int, float]]:
    """(index, mean of ``value`` over the ``window_s`` ending at that point)."""
    total, start = 0.0, 0
    values = [value(p) for p in points]
    for index, point in enumerate(points):
        total += values[index]
        while points[start].time_s < point.time_s - window_s:
            total -= values[start]
            start += 1
        if point.time_s - points[0].time_s >= window_s:
            yield index, total / (index - start + 1)


def swing(values: Sequence[float], times: Sequence[float]) -> tuple[float, float]:
    """(RMS about the mean, frequency in Hz from crossings of the mean with a hysteresis of
    half the RMS) of one window."""
    mean = sum(values) / len(values)
    centred = [v - mean for v in values]
    rms = math.sqrt(sum(c * c for c in centred) / len(centred))
    band = 0.5 * rms
    crossings, side = 0, 0
    for c in centred:
        now = 1 if c > band else -1 if c < -band else 0
        if now and side and now != side:
            crossings += 1
        if now:
            side = now
    duration = times[-1] - times[0]
    return rms, (crossings / (2.0 * duration) if duration > 0 else 0.0)


def sustained_swing(
    points: Sequence[TrackPoint],
    axes: Sequence[tuple[str, Callable[[TrackPoint], float]]],
    window_s: float,
    min_rms: float,
    min_hz: float,
    windows: int,
) -> tuple[str, float, float, float, float] | None:
    """The worst (axis, rms, hz, start time, lasted) of swings sustained over ``windows``
    consecutive windows; None when none is."""
    best: tuple[str, float, float, float, float] | None = None
    if not points:
        return None
    for axis, value in axes:
        start, streak, streak_start, peak, peak_hz = 0, 0, 0.0, 0.0, 0.0
        while start < len(points):
            end = start
            while end < len(points) and points[end].time_s < points[start].time_s + window_s:
                end += 1
            chunk = points[start:end]
            if len(chunk) >= 8 and chunk[-1].time_s - chunk[0].time_s >= 0.8 * window_s:
                rms, hz = swing([value(p) for p in chunk], [p.time_s for p in chunk])
                if rms >= min_rms and hz >= min_hz:
                    if streak == 0:
                        streak_start, peak, peak_hz = chunk[0].time_s, 0.0, 0.0
                    streak += 1
                    if rms > peak:
                        peak, peak_hz = rms, hz
                    if streak >= windows and (best is None or peak > best[1]):
                        best = (axis, peak, peak_hz, streak_start, streak * window_s)
                else:
                    streak = 0
            else:
                streak = 0
            start = end
    return best
