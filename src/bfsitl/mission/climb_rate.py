"""Vertical speed from the FC's altitude readings.

The FC's own vario (MSP_ALTITUDE) cannot be used as a speed: 4.6.0 computes it as the change
of altitude per task run times 100 (``flight/position.c``: ``* TASK_ALTITUDE_RATE_HZ``), and in
the SITL the low-priority ALTITUDE task runs at about half its nominal 100 Hz, so the vario reads
about twice the true climb rate (measured 1.40 m/s at a true 0.72 m/s).  The slope of the
altitude itself over a short window is right, whatever the task rate.
"""

from __future__ import annotations

from collections import deque

#: Long enough to span several of the FC's altitude updates, short enough not to lag.
DEFAULT_WINDOW_S = 0.25


class ClimbRateEstimator:
    """Least-squares slope of (time_s, altitude_m) over the last ``window_s`` seconds."""

    def __init__(self, window_s: float = DEFAULT_WINDOW_S) -> None:
        if not window_s > 0:
            raise ValueError(f"window_s must be positive, got {window_s}")
        self.window_s = window_s
        self._points: deque[tuple[float, float]] = deque()
        #: The slope over the window, worked out once per reading (a control step reads it
        #: more than once).
        self._rate_m_s = 0.0

    def reset(self) -> None:
        self._points.clear()
        self._rate_m_s = 0.0

    def update(self, time_s: float, altitude_m: float) -> float:
        """Add a reading and return the climb rate in m/s (up positive); 0 until two points."""
        points = self._points
        if points and time_s <= points[-1][0]:
            return self._rate_m_s  # a repeated or out-of-order time adds nothing
        points.append((time_s, altitude_m))
        while len(points) > 2 and time_s - points[0][0] > self.window_s:
            points.popleft()
        self._rate_m_s = _slope(points)
        return self._rate_m_s

    @property
    def rate_m_s(self) -> float:
        return self._rate_m_s


def _slope(points: deque[tuple[float, float]]) -> float:
    """The least-squares slope of the points (0 for fewer than two, or one instant)."""
    n = len(points)
    if n < 2:
        return 0.0
    sum_t = sum_h = 0.0
    for t, h in points:
        sum_t += t
        sum_h += h
    mean_t, mean_h = sum_t / n, sum_h / n
    var_t = cov = 0.0
    for t, h in points:
        dt = t - mean_t
        var_t += dt**2  # as the original did: the same rounding, the same flights
        cov += dt * (h - mean_h)
    if var_t <= 0.0:
        return 0.0
    return cov / var_t
