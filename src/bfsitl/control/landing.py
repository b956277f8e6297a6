"""Landing: descend at a commanded rate, slower near the ground, detect touchdown, cut.

The FC's altitude is the barometer's, zeroed at arming: near the ground it is good to a step
(~8 cm) and late by ~0.2 s, so the descent slows to ``slow_descent_m_s`` below
``slow_below_m`` and the touchdown is recognised from what the ground does to the loop rather
than from an exact height:

* the reading is near the arming point and the climb rate has stayed near zero for
  ``touchdown_hold_s`` although a descent is commanded; or
* the hover estimate (the integrator of the climb-rate loop) has wound down by
  ``ground_windup_us``: only the ground can keep a vehicle from descending with that much
  throttle taken away.

Then the throttle goes to minimum and stays there (:attr:`LandingController.touched_down`);
the mission disarms.  The hover estimate starts from the flying controller's when it is handed
over (``LandingController(hover_from=controller)`` or :meth:`~LandingController.
set_hover_estimate`), else from ``hover_guess_us``: then the descent starts with a dip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.control.base import (
    THROTTLE_MIN_US,
    AltitudeInput,
    check_gains,
    clamp,
    hover_range_ok,
    require,
)
from bfsitl.control.cascade import MAX_STEP_S
from bfsitl.errors import ControllerConfigError


@dataclass(frozen=True, slots=True)
class LandingGains:
    """Descent profile, climb-rate loop and touchdown detection (units in the names)."""

    descent_m_s: float = 0.6  # descent rate high up
    slow_descent_m_s: float = 0.25  # ... near the ground (touchdown speed)
    slow_below_m: float = 0.7  # where the slow-down ends (FC altitude)
    slow_over_m: float = 0.6  # and over how much height it blends in
    hover_guess_us: float = 1500.0  # used when no estimate is handed over
    hover_min_us: float = 1250.0
    hover_max_us: float = 1700.0
    rate_kp: float = 60.0  # us per m/s of climb-rate error
    rate_ki: float = 40.0  # us per m of integrated climb-rate error
    climb_ff_us: float = 24.0  # us per m/s (rotor-inflow damping)
    touchdown_alt_m: float = 0.3  # "near the arming point"
    touchdown_climb_m_s: float = 0.15  # "not moving" (the dithered baro wanders ~0.1 m/s)
    touchdown_hold_s: float = 0.8
    ground_windup_us: float = 80.0
    throttle_min_us: float = 1100.0  # in flight; after touchdown it is 1000
    throttle_max_us: float = 1750.0

    def __post_init__(self) -> None:
        check_gains(self)
        hover_range_ok(self)
        require(
            0 < self.slow_descent_m_s <= self.descent_m_s,
            self,
            "need 0 < slow_descent_m_s <= descent_m_s",
        )
        for name in (
            "slow_over_m",
            "touchdown_alt_m",
            "touchdown_climb_m_s",
            "touchdown_hold_s",
            "ground_windup_us",
        ):
            require(getattr(self, name) > 0, self, f"{name} must be > 0")
        for name in ("rate_kp", "rate_ki", "climb_ff_us", "slow_below_m"):
            require(getattr(self, name) >= 0, self, f"{name} must be >= 0")


class LandingController:
    """Descend, recognise the ground, cut the throttle; ``target_alt_m`` is ignored."""

    name = "landing"

    def __init__(
        self, gains: LandingGains | None = None, *, hover_from: object | None = None
    ) -> None:
        """``hover_from``: a flying controller whose ``hover_throttle_us`` (if it has one) is
        read at every :meth:`reset`, so the descent starts from what it learnt."""
        self.gains = gains or LandingGains()
        self._handed_over_us: float | None = None
        self._hover_from = hover_from
        self.reset(0.0)

    def set_hover_estimate(self, throttle_us: float) -> None:
        """Start the next :meth:`reset` from this hover throttle (the flying controller's)."""
        g = self.gains
        if not math.isfinite(throttle_us):
            raise ControllerConfigError(f"hover estimate must be finite, got {throttle_us!r}")
        self._handed_over_us = clamp(float(throttle_us), g.hover_min_us, g.hover_max_us)

    def reset(self, time_s: float) -> None:
        g = self.gains
        learnt = getattr(self._hover_from, "hover_throttle_us", None)
        if (
            isinstance(learnt, (int, float))
            and math.isfinite(learnt)
            and getattr(self._hover_from, "airborne", True)
        ):
            self.set_hover_estimate(learnt)
        start = self._handed_over_us if self._handed_over_us is not None else g.hover_guess_us
        self.hover_throttle_us = start
        self._start_hover_us = start
        self._prev_time_s = time_s
        self._still_since_s: float | None = None
        self._touched_down = False
        self._output_us = start

    @property
    def touched_down(self) -> bool:
        return self._touched_down

    def descent_rate_m_s(self, altitude_m: float) -> float:
        """Commanded descent (positive down) at an FC altitude: fast high up, slow low down."""
        g = self.gains
        share = clamp((altitude_m - g.slow_below_m) / g.slow_over_m, 0.0, 1.0)
        return g.slow_descent_m_s + (g.descent_m_s - g.slow_descent_m_s) * share

    def update(self, sample: AltitudeInput) -> float:
        g = self.gains
        if self._touched_down:
            return THROTTLE_MIN_US
        dt_s = sample.time_s - self._prev_time_s
        if dt_s <= 0:
            return self._output_us
        self._prev_time_s = sample.time_s
        dt_s = min(dt_s, MAX_STEP_S)
        if self._on_ground(sample):
            self._touched_down = True
            self._output_us = THROTTLE_MIN_US
            return self._output_us
        climb_sp = -self.descent_rate_m_s(sample.altitude_m)
        error = climb_sp - sample.climb_rate_m_s
        wanted = self.hover_throttle_us + g.climb_ff_us * climb_sp + g.rate_kp * error
        output = clamp(wanted, g.throttle_min_us, g.throttle_max_us)
        saturated = (wanted > g.throttle_max_us and error > 0) or (
            wanted < g.throttle_min_us and error < 0
        )
        if not saturated:
            self.hover_throttle_us = clamp(
                self.hover_throttle_us + g.rate_ki * error * dt_s, g.hover_min_us, g.hover_max_us
            )
        self._output_us = output
        return output

    def _on_ground(self, sample: AltitudeInput) -> bool:
        g = self.gains
        if self._start_hover_us - self.hover_throttle_us >= g.ground_windup_us:
            return True
        low_and_still = (
            sample.altitude_m <= g.touchdown_alt_m
            and abs(sample.climb_rate_m_s) <= g.touchdown_climb_m_s
        )
        if not low_and_still:
            self._still_since_s = None
            return False
        if self._still_since_s is None:
            self._still_since_s = sample.time_s
        return sample.time_s - self._still_since_s >= g.touchdown_hold_s
