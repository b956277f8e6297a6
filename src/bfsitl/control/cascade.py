"""A cascaded altitude controller built for what the FC actually reports.

The FC's altitude comes from the barometer only: whole pascals (~8 cm steps), then the
firmware's PT2 low-pass, read over MSP; on the 4.6.0 SITL it trails the truth by ~0.2 s.  A
single PID on that signal (the tutorial's) starts with a guessed hover throttle, climbs as hard
as its P term says, sees the vehicle late and kicks the throttle at every 8 cm step.  This
controller splits the job:

1. **Spool-up and identification**: on the ground the throttle rises from a low hover guess
   at a fixed rate until the FC sees the vehicle leave the ground (altitude and climb rate both
   up, on two samples in a row).  Then the recorded spool-up is replayed through the vertical
   model and the FC's lag for every candidate hover throttle, and the best fit wins
   (:meth:`CascadedAltitudeController._identify_hover`): the hover estimate lands within a few
   microseconds of the truth without knowing it, and the replay's final state tells where the
   vehicle truly is, ahead of the lagging reading.  (A spool-up too short to fit falls back to
   taking back ``liftoff_delay_s`` of the ramp.)
2. **Reference profile**: the target is approached along a smooth path (acceleration and
   climb/descent rates limited, an exponential finish), so nothing is ever asked that the
   vehicle cannot do, and nothing winds up.
3. **Feedforward**: the profile's acceleration and climb rate go straight to the throttle
   (``accel_ff_us`` ~ 1/b, the IRIS's ~28 us per m/s^2; ``climb_ff_us`` ~ its rotor-inflow
   damping, 24 us per m/s).  The vehicle follows the profile without waiting for an error.
4. **Feedback in the measurement's own time**: before the profile is compared with the FC's
   altitude it goes through a model of the FC's lag (:class:`SensorLag`), so the loops correct
   real deviations, not the sensor's delay.  Outer loop: altitude error -> climb-rate
   correction (limited); inner loop: climb-rate error -> throttle, on a climb rate derived
   here from the altitude with a short filter (the mission's 0.25 s least-squares slope adds
   0.12 s of lag, which costs the inner loop its damping).  The hover estimate integrates the
   altitude error, bounded, frozen while the output is saturated the way the error pushes.
5. **Learning the hover throttle only when it can be learnt**: while the profile moves fast,
   the altitude error is mostly the lag model's own error (the FC's lag varies with its task
   rate), so the integrator waits until the profile slows below ``learn_below_m_s``.  A
   reference governor makes the profile brake when the vehicle lags it by more than
   ``MAX_LEAD_M``, and a "lift-off" after which the FC still reads the ground is taken back.
   ``hold_deadband_m`` (off by default) can make the integrator ignore errors smaller than a
   fraction of a barometer step once the profile has arrived.
6. **Whole microseconds**: the RC link sends integers; 1 us of throttle is ~4 cm/s of drift on
   the IRIS, so the output is rounded with error feedback (the fraction is kept on average).

What no altitude controller can do here: the reading that says 2.00 m covers true heights from
1.97 to 2.06 m at the default home (1 Pa = 8.3 cm, zeroed at a ground reading that itself sits
5.5 cm below its next step), and inside one step nothing tells where the vehicle is.  A hold
therefore drifts within a step until the reading changes; a +-5 cm settling band sits inside
that uncertainty.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.control.base import (
    THROTTLE_MIN_US,
    AltitudeInput,
    WholeMicroseconds,
    check_gains,
    clamp,
    hover_range_ok,
    require,
)

#: Longer gaps between samples are treated as this long (a stalled loop must not make the
#: integrator or the profile jump).
MAX_STEP_S = 0.1
#: A lift-off is taken back when the profile is this far up and the FC still reads the ground
#: (a real one moves the reading long before: the profile leads it by ~lag x climb rate).
FALSE_LIFTOFF_LEAD_M = 0.3
#: How far the (lag-matched) profile may run ahead of the FC's altitude before it waits.
MAX_LEAD_M = 0.25
#: Spool-up samples needed to identify the hover throttle (fewer: the ramp take-back).
MIN_IDENTIFY_SAMPLES = 12


@dataclass(frozen=True, slots=True)
class CascadeGains:
    """Gains and limits of :class:`CascadedAltitudeController` (units in the names)."""

    hover_guess_us: float = 1480.0  # start of the spool-up: below any sane hover
    hover_min_us: float = 1250.0  # bounds of the adapted hover estimate
    hover_max_us: float = 1800.0
    spool_rate_us_s: float = 100.0  # how fast the throttle rises on the ground
    liftoff_alt_m: float = 0.08  # FC altitude that means "off the ground" ...
    liftoff_climb_m_s: float = 0.20  # ... together with this climb rate
    liftoff_delay_s: float = 0.64  # true lift-off to the FC showing it, at that ramp
    max_climb_m_s: float = 3.0
    max_descent_m_s: float = 1.0
    max_accel_m_s2: float = 5.0
    approach_rate_hz: float = 3.0  # final approach: climb rate = this x distance
    alt_kp: float = 1.5  # 1/s: climb-rate correction per m of altitude error
    alt_ki: float = 30.0  # us per (m s): hover adaptation
    rate_kp: float = 50.0  # us per m/s of climb-rate error
    rate_filter_s: float = 0.08  # time constant of the climb rate derived here
    accel_ff_us: float = 28.0  # us per m/s^2 (1 / b, the vehicle's throttle gain)
    climb_ff_us: float = 24.0  # us per m/s (rotor-inflow damping, in throttle)
    lag_s: float = 0.22  # FC altitude behind the truth
    rate_lag_s: float = 0.30  # climb rate (from that altitude) behind the truth
    hold_deadband_m: float = 0.0  # optional; e.g. 0.02 (a quarter barometer step)
    learn_below_m_s: float = 0.3  # hover adaptation only while the profile is slower
    throttle_min_us: float = 1150.0
    throttle_max_us: float = 1850.0

    def __post_init__(self) -> None:
        check_gains(self)
        hover_range_ok(self)
        for name in (
            "spool_rate_us_s",
            "max_climb_m_s",
            "max_descent_m_s",
            "max_accel_m_s2",
            "approach_rate_hz",
            "liftoff_alt_m",
            "liftoff_climb_m_s",
            "accel_ff_us",
        ):
            require(getattr(self, name) > 0, self, f"{name} must be > 0")
        for name in (
            "alt_kp",
            "alt_ki",
            "rate_kp",
            "rate_filter_s",
            "climb_ff_us",
            "lag_s",
            "rate_lag_s",
            "liftoff_delay_s",
            "hold_deadband_m",
            "learn_below_m_s",
        ):
            require(getattr(self, name) >= 0, self, f"{name} must be >= 0")


class SensorLag:
    """Two equal first-order lags with ``delay_s`` in total: the FC's PT2, in sim time.

    Exact discretisation per step, so an irregular sample clock does not change it.
    """

    __slots__ = ("delay_s", "_a", "_b")

    def __init__(self, delay_s: float, value: float = 0.0) -> None:
        self.delay_s = delay_s
        self._a = self._b = value

    def reset(self, value: float) -> None:
        self._a = self._b = value

    @property
    def value(self) -> float:
        return self._b

    def shift(self, offset: float) -> None:
        """Move the filtered history by ``offset``: what a constant input offset would have
        done (a correction to where the vehicle was, not a change of where it goes)."""
        self._a += offset
        self._b += offset

    def step(self, value: float, dt_s: float) -> float:
        if self.delay_s <= 0:
            self._a = self._b = value
            return value
        k = -math.expm1(-dt_s / (0.5 * self.delay_s))
        self._a += k * (value - self._a)
        self._b += k * (self._a - self._b)
        return self._b


class ReferenceProfile:
    """Where the vehicle should be: a rate- and acceleration-limited path to the target.

    The wanted rate towards the target at distance d is ``sqrt(2 a d + (a/k)^2) - a/k``
    (a = 0.9 x the acceleration limit, k = ``approach_rate_hz``): like ``sqrt(2 a d)`` far
    away (braking at a constant rate), like ``k d`` close in (an exponential finish, no
    chattering), and the deceleration it asks for never exceeds a, so the rate-limited profile
    can always follow it and does not overshoot.
    """

    __slots__ = ("alt_m", "climb_m_s", "accel_m_s2", "_climb", "_descent", "_accel", "_k")

    def __init__(
        self,
        max_climb_m_s: float,
        max_descent_m_s: float,
        max_accel_m_s2: float,
        approach_rate_hz: float,
    ) -> None:
        self._climb, self._descent = max_climb_m_s, max_descent_m_s
        self._accel, self._k = max_accel_m_s2, approach_rate_hz
        self.reset(0.0)

    def reset(self, alt_m: float, climb_m_s: float = 0.0) -> None:
        self.alt_m, self.climb_m_s, self.accel_m_s2 = alt_m, climb_m_s, 0.0

    def copy(self) -> ReferenceProfile:
        twin = ReferenceProfile(self._climb, self._descent, self._accel, self._k)
        twin.alt_m, twin.climb_m_s, twin.accel_m_s2 = self.alt_m, self.climb_m_s, self.accel_m_s2
        return twin

    def arrived(self, target_m: float) -> bool:
        """At the target and (nearly) still: the profile has nothing left to do."""
        return abs(target_m - self.alt_m) < 0.005 and abs(self.climb_m_s) < 0.02

    def step(self, target_m: float, dt_s: float) -> None:
        distance = target_m - self.alt_m
        plan = 0.9 * self._accel
        soft = plan / self._k
        wanted = math.sqrt(2.0 * plan * abs(distance) + soft * soft) - soft
        wanted = min(wanted, self._climb) if distance > 0 else -min(wanted, self._descent)
        change = clamp(wanted - self.climb_m_s, -self._accel * dt_s, self._accel * dt_s)
        self.accel_m_s2 = change / dt_s
        self.alt_m += (self.climb_m_s + 0.5 * change) * dt_s
        self.climb_m_s += change


class CascadedAltitudeController:
    """Spool-up, reference profile, feedforward, lag-matched cascade (see the module doc).

    ``hover_throttle_us`` is the current hover estimate (hand it to the landing controller).
    """

    name = "cascade"

    def __init__(self, gains: CascadeGains | None = None) -> None:
        self.gains = gains or CascadeGains()
        g = self.gains
        self._profile = ReferenceProfile(
            g.max_climb_m_s, g.max_descent_m_s, g.max_accel_m_s2, g.approach_rate_hz
        )
        self._seen_alt = SensorLag(g.lag_s)
        self._seen_climb = SensorLag(g.rate_lag_s)
        self.reset(0.0)

    # -- state ------------------------------------------------------------------------------
    def reset(self, time_s: float) -> None:
        self.hover_throttle_us = self.gains.hover_guess_us
        self.airborne = False
        self._liftoff_votes = 0
        #: (time_s, FC altitude_m then, throttle_us sent from then on) during the spool-up.
        self._spool_log: list[tuple[float, float, float]] = []
        self._prev_time_s = time_s
        self._prev_alt_m: float | None = None
        self._climb_m_s = 0.0
        self._output_us = THROTTLE_MIN_US
        self._whole_us = WholeMicroseconds()
        self._profile.reset(0.0)
        self._seen_alt.reset(0.0)
        self._seen_climb.reset(0.0)

    @property
    def reference_alt_m(self) -> float:
        """Where the profile wants the vehicle now (true altitude, not the lagged reading)."""
        return self._profile.alt_m

    # -- the loop -------------------------------------------------------------------------------
    def update(self, sample: AltitudeInput) -> float:
        dt_s = sample.time_s - self._prev_time_s
        if dt_s <= 0:
            return self._output_us  # a repeated sample: nothing new to act on
        self._prev_time_s = sample.time_s
        dt_s = min(dt_s, MAX_STEP_S)
        climb = self._own_climb_rate(sample.altitude_m, dt_s)
        if not self.airborne:
            if not self._lifted_off(sample):
                self._output_us = self._spool(sample, dt_s)
                self._spool_log.append((sample.time_s, sample.altitude_m, self._output_us))
                return self._output_us
            self._spool_log.append((sample.time_s, sample.altitude_m, self._output_us))
            self._take_off(sample)
        elif self._still_on_ground(sample):
            self.airborne = False  # a false lift-off (a noisy reading): spool up again
            self._liftoff_votes = 0
            self._output_us = self._spool(sample, dt_s)
            return self._output_us
        self._output_us = self._whole_us(self._fly(sample, climb, dt_s))
        return self._output_us

    def observe_flight(self, sample: AltitudeInput, throttle_us: float) -> None:
        """Another pilot has the sticks (``throttle_us`` is what it sent): the climb rate
        follows the readings and the reference and its lag models stay on what the FC reads,
        so the sticks come back without a jump (left alone, the reference stayed where the
        pilot took over: docs/gym.md)."""
        dt_s = sample.time_s - self._prev_time_s
        if dt_s <= 0 or not self.airborne:
            return
        self._prev_time_s = sample.time_s
        climb_m_s = self._own_climb_rate(sample.altitude_m, min(dt_s, MAX_STEP_S))
        self._output_us = throttle_us
        self._profile.reset(sample.altitude_m, climb_m_s)
        self._seen_alt.reset(sample.altitude_m)
        self._seen_climb.reset(climb_m_s)

    def _still_on_ground(self, sample: AltitudeInput) -> bool:
        """The profile is well up but the FC still reads ground level: it never left."""
        g = self.gains
        return (
            sample.altitude_m < g.liftoff_alt_m
            and self._profile.alt_m - sample.altitude_m > FALSE_LIFTOFF_LEAD_M
        )

    def _own_climb_rate(self, altitude_m: float, dt_s: float) -> float:
        """Finite difference of the FC altitude through a short first-order filter."""
        if self._prev_alt_m is not None:
            raw = (altitude_m - self._prev_alt_m) / dt_s
            tau = self.gains.rate_filter_s
            share = 1.0 if tau <= 0 else -math.expm1(-dt_s / tau)
            self._climb_m_s += share * (raw - self._climb_m_s)
        self._prev_alt_m = altitude_m
        return self._climb_m_s

    def _lifted_off(self, sample: AltitudeInput) -> bool:
        """Altitude and climb rate both up, twice in a row (one noisy sample is not enough)."""
        g = self.gains
        up = sample.altitude_m >= g.liftoff_alt_m and sample.climb_rate_m_s >= g.liftoff_climb_m_s
        self._liftoff_votes = self._liftoff_votes + 1 if up else 0
        return self._liftoff_votes >= 2

    def _spool(self, sample: AltitudeInput, dt_s: float) -> float:
        """On the ground: raise the throttle until the FC sees the vehicle leave it."""
        g = self.gains
        if sample.target_alt_m < g.liftoff_alt_m:
            return THROTTLE_MIN_US  # nowhere to go: stay down, motors at idle
        self.hover_throttle_us = min(
            self.hover_throttle_us + g.spool_rate_us_s * dt_s, g.hover_max_us
        )
        return self.hover_throttle_us

    def _take_off(self, sample: AltitudeInput) -> None:
        """Find the hover throttle from the spool-up, and start the profile where the vehicle
        truly is by now.

        First choice: identify it (:meth:`_identify_hover`).  Fallback, when the spool-up was
        too short to tell: take back the last ``liftoff_delay_s`` of the ramp (with the
        throttle ramping at r above hover for T seconds the vehicle has climbed about
        r T^3 / 6 b at r T^2 / 2 b, 1 / b = ``accel_ff_us``)."""
        g = self.gains
        self.airborne = True
        identified = self._identify_hover()
        self._spool_log = []
        if identified is not None:
            hover_us, alt_m, climb_m_s = identified
            self.hover_throttle_us = hover_us
            self._profile.reset(alt_m, min(climb_m_s, g.max_climb_m_s))
            self._seen_alt.reset(sample.altitude_m)
            self._seen_climb.reset(sample.climb_rate_m_s)
            return
        delay_s = g.liftoff_delay_s
        self.hover_throttle_us = clamp(
            self.hover_throttle_us - g.spool_rate_us_s * delay_s, g.hover_min_us, g.hover_max_us
        )
        per_b = g.spool_rate_us_s / g.accel_ff_us
        climb = min(max(sample.climb_rate_m_s, per_b * delay_s**2 / 2.0), g.max_climb_m_s)
        alt = max(sample.altitude_m, per_b * delay_s**3 / 6.0)
        self._profile.reset(alt, climb)
        self._seen_alt.reset(sample.altitude_m)
        self._seen_climb.reset(sample.climb_rate_m_s)

    def _identify_hover(self) -> tuple[float, float, float] | None:
        """Least-squares hover throttle from the spool-up: (hover_us, altitude_m, climb_m_s).

        Every candidate hover throttle H (1 us apart, within the hover bounds) replays the
        throttle that was sent through the vertical model (acceleration (u - H) / b minus the
        inflow damping, resting on the ground while u < H) and through the FC's lag; the H
        whose lagged altitude best matches what the FC reported wins.  The lag is in the
        model, so the answer does not depend on when the lift-off was noticed, and the
        replay's final state is where the vehicle truly is now, ahead of the FC's reading.
        """
        g = self.gains
        log = self._spool_log
        if len(log) < MIN_IDENTIFY_SAMPLES:
            return None
        best: tuple[float, float, float, float] | None = None
        for hover_us in range(math.ceil(g.hover_min_us), math.floor(g.hover_max_us) + 1):
            cost, alt_m, climb_m_s = self._replay(float(hover_us), log)
            if best is None or cost < best[0]:
                best = (cost, float(hover_us), alt_m, climb_m_s)
        assert best is not None
        return best[1], best[2], best[3]

    def _replay(
        self,
        hover_us: float,
        log: list[tuple[float, float, float]],
    ) -> tuple[float, float, float]:
        g = self.gains
        lag = SensorLag(g.lag_s)
        alt_m = climb_m_s = cost = 0.0
        damping = g.climb_ff_us / g.accel_ff_us
        for (t0, _, throttle_us), (t1, seen_m, _) in zip(log, log[1:], strict=False):
            dt_s = min(t1 - t0, MAX_STEP_S)
            accel = (throttle_us - hover_us) / g.accel_ff_us - damping * climb_m_s
            if alt_m <= 0.0 and accel <= 0.0:
                climb_m_s = 0.0  # resting on the ground
            else:
                climb_m_s += accel * dt_s
                alt_m = max(0.0, alt_m + climb_m_s * dt_s)
            error = lag.step(alt_m, dt_s) - seen_m
            cost += error * error
        return cost, alt_m, climb_m_s

    def _fly(self, sample: AltitudeInput, climb_m_s: float, dt_s: float) -> float:
        g = self.gains
        profile = self._profile
        # Reference governor: while the vehicle lags the profile by more than MAX_LEAD_M (as
        # the FC sees it), the profile brakes instead of running away, so the error and the
        # integrator cannot grow without bound (a heavy vehicle, a hover guess far off).
        lead = self._seen_alt.value - sample.altitude_m
        toward = sample.target_alt_m - profile.alt_m
        governed = lead * toward > 0 and abs(lead) > MAX_LEAD_M
        profile.step(profile.alt_m if governed else sample.target_alt_m, dt_s)
        seen_alt = self._seen_alt.step(profile.alt_m, dt_s)
        seen_climb = self._seen_climb.step(profile.climb_m_s, dt_s)
        alt_error = seen_alt - sample.altitude_m
        band = g.hold_deadband_m if profile.arrived(sample.target_alt_m) else 0.0
        integrated_error = _deadband(alt_error, band)
        climb_sp = clamp(seen_climb + g.alt_kp * alt_error, -g.max_descent_m_s, g.max_climb_m_s)
        feedforward = g.accel_ff_us * profile.accel_m_s2 + g.climb_ff_us * profile.climb_m_s
        wanted = self.hover_throttle_us + feedforward + g.rate_kp * (climb_sp - climb_m_s)
        output = clamp(wanted, g.throttle_min_us, g.throttle_max_us)
        # Anti-windup: no integration that would push further into a saturated output.
        pushing_up_at_max = wanted > g.throttle_max_us and integrated_error > 0
        pushing_down_at_min = wanted < g.throttle_min_us and integrated_error < 0
        # During fast motion the altitude error is mostly the lag model's own error (the FC's
        # lag varies with its task rate): learning the hover throttle from it would wind up.
        slow = abs(profile.climb_m_s) <= g.learn_below_m_s
        if slow and not (pushing_up_at_max or pushing_down_at_min):
            self.hover_throttle_us = clamp(
                self.hover_throttle_us + g.alt_ki * integrated_error * dt_s,
                g.hover_min_us,
                g.hover_max_us,
            )
        return output


def _deadband(error: float, band: float) -> float:
    """``error`` shrunk towards zero by ``band``."""
    if error > band:
        return error - band
    if error < -band:
        return error + band
    return 0.0
