"""fdm timestamps that keep the firmware's clock equal to simulated time (sans-I/O).

Stock 4.6.0 SITL never reads the fdm timestamp as a time.  It estimates a clock *rate*,
``simRate = Δtimestamp / Δarrival``, from every pair of packets whose Δtimestamp lies in
(0, 20 ms), unsmoothed, and runs every firmware timer on wall time × simRate (``sitl.c``
``updateState``).  Arrival jitter biases that estimate upward: with Gazebo-style timestamps
(timestamp = sim time) the firmware clock was measured 2.9x to 8.8x faster than sim time.

The rate-frozen scheme (``docs/lockstep.md``):

1. primers: a few packets with timestamps 0.0625 s apart.  The first packet after boot (or
   after a 500 ms gap) takes the SITL's timeout branch, which does not record its arrival;
   the primers get the estimator a clean reference.
2. one calibration pair whose Δtimestamp is below 20 ms and equals ``speed × Δwall``: the SITL
   then sets ``simRate = speed``.  At speed 1 it can be skipped (simRate starts at 1.0).
3. from then on every timestamp advances by 0.0625 s, an exact binary fraction well above
   20 ms (0.02 itself fails by float rounding), so simRate is never touched again.

The firmware clock then runs at ``speed`` × wall time, and the bridge paces simulated time at
the same ``speed``: firmware time / sim time stays at 1.00 whatever the jitter.

The Gazebo-parity alternative (timestamp = sim time, ``SitlBridge(timestamps="sim")``) is kept
for comparison; expect the firmware clock to drift with it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: Far from 0 so that it can never be mistaken for a boot-time value.
BASE_TIMESTAMP_S = 1024.0
#: Above the SITL's 20 ms estimator window, and exact in binary floating point.
FROZEN_STEP_S = 0.0625
#: The estimator's window: only pairs with 0 < Δtimestamp < this update simRate.
ESTIMATOR_WINDOW_S = 0.02
PRIMER_PACKETS = 3
#: Spacing of the primers.
PRIMER_SPACING_S = 0.01


@dataclass
class FrozenRateStamps:
    """Timestamps for the rate-frozen scheme; the caller owns sending and timing."""

    speed: float = 1.0
    timestamp_s: float = field(default=BASE_TIMESTAMP_S)

    def __post_init__(self) -> None:
        if not 0.01 <= self.speed <= 10.0:
            raise ValueError(f"speed {self.speed} outside 0.01..10")

    @property
    def needs_calibration(self) -> bool:
        """At speed 1 the SITL's initial simRate (1.0) is already right."""
        return self.speed != 1.0

    def primer(self) -> float:
        self.timestamp_s += FROZEN_STEP_S
        return self.timestamp_s

    def calibration_wall_s(self) -> float:
        """How long to wait (wall time) between the two packets of the calibration pair.

        As long as the estimator's window allows at this speed: the rate the SITL computes
        is off by (arrival jitter) / (this), so longer is better.
        """
        return 0.9 * ESTIMATOR_WINDOW_S / self.speed

    def calibration_second(self, first_timestamp_s: float, wall_elapsed_s: float) -> float:
        """Timestamp of the pair's second packet, given the wall time since the first.

        ``Δtimestamp / Δarrival = speed`` is what the SITL will compute; it must stay in
        the estimator's window, so a late second packet is clamped (a slightly wrong rate
        is then visible in the health check, never a frozen clock).
        """
        delta_s = min(self.speed * wall_elapsed_s, 0.95 * ESTIMATOR_WINDOW_S)
        self.timestamp_s = first_timestamp_s + delta_s
        return self.timestamp_s

    def next(self) -> float:
        """The timestamp of the next regular packet."""
        self.timestamp_s += FROZEN_STEP_S
        return self.timestamp_s
