"""Link statistics of the dashboard: updates per second, failed polls, MSP round trip.

The dashboard polls synchronously (one MSP_MULTIPLE_MSP round trip per frame), so the round
trip is simply the time one poll took.  Rates are taken over a short sliding window rather
than since start: after a stall (a SITL restart, a busy machine) the figure should recover
within seconds, not be diluted by minutes of history.  Time comes in as arguments, never from
a clock read here, so the arithmetic is tested with literal numbers.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

#: Seconds of history behind ``updates_per_s`` and the round-trip figures.
DEFAULT_WINDOW_S = 2.0


@dataclass(frozen=True, slots=True)
class LinkStats:
    """The link as the dashboard shows it; all figures are over the last window."""

    updates: int
    errors: int
    updates_per_s: float
    #: Round trip of the newest successful poll; None before the first.
    rtt_last_ms: float | None
    rtt_mean_ms: float | None
    rtt_max_ms: float | None
    #: Seconds since the newest successful poll; None before the first.
    age_s: float | None
    last_error: str | None
    elapsed_s: float


class LinkMeter:
    """Accumulates poll outcomes; :meth:`stats` summarises them at a given time."""

    def __init__(self, started_at_s: float, window_s: float = DEFAULT_WINDOW_S) -> None:
        if window_s <= 0:
            raise ValueError("window_s must be positive")
        self.started_at_s = started_at_s
        self.window_s = window_s
        self._samples: deque[tuple[float, float]] = deque()  # (at_s, rtt_s) of successes
        self._updates = 0
        self._errors = 0
        self._last_ok_at_s: float | None = None
        self._last_rtt_s: float | None = None
        self._last_error: str | None = None

    def record_update(self, rtt_s: float, at_s: float) -> None:
        """A poll answered after ``rtt_s``; ``at_s`` is when the reply was in."""
        self._updates += 1
        self._last_ok_at_s = at_s
        self._last_rtt_s = rtt_s
        self._samples.append((at_s, rtt_s))
        self._forget_before(at_s - self.window_s)

    def record_error(self, message: str, at_s: float) -> None:
        """A poll failed (timeout, error reply, undecodable reply)."""
        self._errors += 1
        self._last_error = message
        self._forget_before(at_s - self.window_s)

    def _forget_before(self, cutoff_s: float) -> None:
        while self._samples and self._samples[0][0] < cutoff_s:
            self._samples.popleft()

    def stats(self, now_s: float) -> LinkStats:
        elapsed_s = max(0.0, now_s - self.started_at_s)
        recent = [rtt_s for at_s, rtt_s in self._samples if at_s >= now_s - self.window_s]
        span_s = min(self.window_s, elapsed_s)
        rate = len(recent) / span_s if span_s > 0 else 0.0
        return LinkStats(
            updates=self._updates,
            errors=self._errors,
            updates_per_s=rate,
            rtt_last_ms=None if self._last_rtt_s is None else self._last_rtt_s * 1000.0,
            rtt_mean_ms=sum(recent) / len(recent) * 1000.0 if recent else None,
            rtt_max_ms=max(recent) * 1000.0 if recent else None,
            age_s=None if self._last_ok_at_s is None else max(0.0, now_s - self._last_ok_at_s),
            last_error=self._last_error,
            elapsed_s=elapsed_s,
        )
