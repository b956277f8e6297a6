"""The tutorial's altitude scripts, re-created as the baseline the cascade must beat.

:class:`TutorialPid` is the textbook single-loop altitude PID found in most "fly Betaflight SITL
from Python" tutorials: throttle = hover guess + P x error + I x integral + D x derivative, the
error in metres, the derivative by finite difference of the error, the integral clamped, the
output clamped.  It is kept faithful on purpose, weaknesses included: a fixed hover guess that
only the integral can correct, a derivative of a lagged and 8 cm-quantised barometric altitude
(throttle kicks whenever the reading steps), and no limit on how fast it climbs.

:class:`OpenLoopTakeoff` is the tutorial's other script: a throttle schedule over time that
never looks at a measurement.  It shows why closed loop is needed: the vehicle ends wherever
the hover guess's error takes it.
"""

from __future__ import annotations

from dataclasses import dataclass

from bfsitl.control.base import (
    THROTTLE_MIN_US,
    AltitudeInput,
    check_gains,
    clamp,
    require,
    throttle_range_ok,
)


@dataclass(frozen=True, slots=True)
class TutorialPidGains:
    """Tutorial-style numbers: a round hover guess and gains per metre of error.

    Chosen so that it does fly the 0 -> 2 m step on the IRIS (hover ~1541 us): the P term
    climbs, the I term finds the missing ~40 us of hover within a few seconds, the D term
    damps the climb enough not to overshoot wildly.
    """

    hover_base_us: float = 1500.0
    kp: float = 100.0  # us per m of altitude error
    ki: float = 20.0  # us per (m s) of integrated error
    kd: float = 60.0  # us per (m/s) of error derivative
    integral_limit: float = 5.0  # m s: the integral is clamped to +- this
    throttle_min_us: float = 1100.0
    throttle_max_us: float = 1800.0

    def __post_init__(self) -> None:
        check_gains(self)
        require(
            self.kp >= 0 and self.ki >= 0 and self.kd >= 0,
            self,
            "kp, ki and kd must be >= 0 (a negative gain pushes the wrong way)",
        )
        require(self.integral_limit >= 0, self, "integral_limit must be >= 0")
        throttle_range_ok(self, self.throttle_min_us, self.throttle_max_us)
        require(
            self.throttle_min_us <= self.hover_base_us <= self.throttle_max_us,
            self,
            "hover_base_us must lie between throttle_min_us and throttle_max_us",
        )


class TutorialPid:
    """``throttle = hover_base + kp e + ki integral(e) + kd de/dt``, ``e = target - altitude``."""

    name = "tutorial-pid"

    def __init__(self, gains: TutorialPidGains | None = None) -> None:
        self.gains = gains or TutorialPidGains()
        self.reset(0.0)

    def reset(self, time_s: float) -> None:
        self.integral = 0.0
        self._prev_error: float | None = None
        self._prev_time_s = time_s
        self._derivative = 0.0

    def update(self, sample: AltitudeInput) -> float:
        g = self.gains
        error = sample.target_alt_m - sample.altitude_m
        dt_s = sample.time_s - self._prev_time_s
        if dt_s > 0:
            self.integral = clamp(self.integral + error * dt_s, -g.integral_limit, g.integral_limit)
            if self._prev_error is not None:
                self._derivative = (error - self._prev_error) / dt_s
            self._prev_error = error
            self._prev_time_s = sample.time_s
        elif self._prev_error is None:
            self._prev_error = error  # the very first sample, at the reset time
        throttle = g.hover_base_us + g.kp * error + g.ki * self.integral + g.kd * self._derivative
        return clamp(throttle, g.throttle_min_us, g.throttle_max_us)


@dataclass(frozen=True, slots=True)
class OpenLoopGains:
    """The schedule: ramp to ``climb_us``, hold it, then sit at the hover guess."""

    ramp_s: float = 1.0
    climb_us: float = 1600.0
    climb_s: float = 1.5
    hover_us: float = 1500.0

    def __post_init__(self) -> None:
        check_gains(self)
        require(self.ramp_s >= 0 and self.climb_s >= 0, self, "ramp_s and climb_s must be >= 0")
        throttle_range_ok(self, THROTTLE_MIN_US, max(self.climb_us, self.hover_us))
        require(
            self.climb_us > THROTTLE_MIN_US and self.hover_us > THROTTLE_MIN_US,
            self,
            f"climb_us and hover_us must be above {THROTTLE_MIN_US:.0f} us",
        )


class OpenLoopTakeoff:
    """Throttle by the clock since reset; the measurements are ignored entirely."""

    name = "open-loop"

    def __init__(self, gains: OpenLoopGains | None = None) -> None:
        self.gains = gains or OpenLoopGains()
        self.reset(0.0)

    def reset(self, time_s: float) -> None:
        self._start_s = time_s

    def update(self, sample: AltitudeInput) -> float:
        g = self.gains
        elapsed_s = sample.time_s - self._start_s
        if elapsed_s < g.ramp_s:
            share = max(0.0, elapsed_s) / g.ramp_s
            return THROTTLE_MIN_US + (g.climb_us - THROTTLE_MIN_US) * share
        if elapsed_s < g.ramp_s + g.climb_s:
            return g.climb_us
        return g.hover_us
