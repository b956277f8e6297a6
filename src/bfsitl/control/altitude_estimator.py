"""Altitude and climb rate *now*, from a late barometer and an on-time accelerometer.

The FC's altitude is barometric only, low-pass filtered, and reaches a mission ~0.1-0.25 s
after the fact (the filter is designed for a 100 Hz task that the SITL runs at 35-50 Hz, so
the lag even changes from flight to flight).  Its accelerometer is filtered much less (25 Hz)
and is barely late.  This estimator integrates the vertical acceleration and lets the barometer
correct only what integration cannot know: the starting point and slow drift (an accelerometer
bias, on a real board).

How the barometer is compared: the estimate goes through a model of the FC's filter
(:class:`~bfsitl.control.cascade.SensorLag`) before it is subtracted from the reading, so a
vehicle that climbs is not pulled back by a reading that simply has not caught up yet.  What the
lag model gets wrong shows as an innovation proportional to the climb rate; the corrections are
therefore weakened while the vehicle moves fast (``fast_m_s``) and act fully in the hover, which
is where an altitude hold needs them.  A position correction moves the lag model's history too
(it says where the vehicle *was*), so it shows in the predicted reading at once and the
correction loop itself has no lag in it.

The FC zeroes its altitude at arming against a short average of the ground readings, so with
a noisy barometer every flight starts with its own zero error (a few centimetres, and it stays
for the whole flight).  While the vehicle still sits on the ground the truth is known (zero),
so the estimator averages the readings there instead of following them, and subtracts that
offset for the rest of the flight (after ``ground_settle_s``: the FC's filter starts from zero
at arming and needs that long to reach the ground reading).

Gains of a third-order complementary filter with all three poles at ``-bandwidth_rad_s``:
position 3w, velocity 3w^2, accelerometer bias w^3 (per second, per m of innovation).
"""

from __future__ import annotations

from dataclasses import dataclass

from bfsitl.control.cascade import SensorLag

#: Below this measured acceleration a vehicle that has not lifted off is resting (the SITL's
#: accelerometer steps are 0.038 m/s^2; a rising vehicle shows far more).
RESTING_ACCEL_M_S2 = 0.1


@dataclass(frozen=True, slots=True)
class AltitudeEstimate:
    alt_m: float  # estimated true altitude now (same zero as the FC's reading)
    climb_m_s: float  # estimated vertical speed now, up positive
    accel_bias_m_s2: float


class AltitudeEstimator:
    """Complementary filter: accelerometer integrated, barometer (through its lag) corrects."""

    def __init__(
        self,
        *,
        lag_s: float = 0.15,
        bandwidth_rad_s: float = 1.0,
        fast_m_s: float = 0.2,
        accel_delay_s: float = 0.02,
        ground_settle_s: float = 0.4,
        bias_share: float = 1.0,
        max_step_s: float = 0.5,
    ) -> None:
        if not (
            lag_s >= 0
            and bandwidth_rad_s > 0
            and fast_m_s > 0
            and accel_delay_s >= 0
            and bias_share >= 0
            and max_step_s > 0
        ):
            raise ValueError(
                "lag_s >= 0, bandwidth_rad_s > 0, fast_m_s > 0, "
                "accel_delay_s >= 0, bias_share >= 0, max_step_s > 0"
            )
        self.lag_s = lag_s
        self.bandwidth_rad_s = bandwidth_rad_s
        self.fast_m_s = fast_m_s
        self.accel_delay_s = accel_delay_s
        self.ground_settle_s = ground_settle_s
        self.bias_share = bias_share
        self.max_step_s = max_step_s
        self._seen = SensorLag(lag_s)
        self.reset()

    def reset(self, alt_m: float = 0.0, climb_m_s: float = 0.0) -> None:
        # The state integrates samples that are accel_delay_s old: it describes the vehicle
        # that long ago; ``estimate`` projects it to now.
        self._alt_m = alt_m
        self._climb_m_s = climb_m_s
        self._accel_m_s2 = 0.0
        self.accel_bias_m_s2 = 0.0
        self._prev_accel: float | None = None
        self._seen.reset(alt_m)
        #: What the FC reads when the vehicle is at zero (its zero error), from the ground.
        self.baro_offset_m = 0.0
        self._ground_s = 0.0
        self._ground_all = _Mean()
        self._ground_settled = _Mean()

    @property
    def estimate(self) -> AltitudeEstimate:
        d = self.accel_delay_s
        return AltitudeEstimate(
            self._alt_m + (self._climb_m_s + 0.5 * self._accel_m_s2 * d) * d,
            self._climb_m_s + self._accel_m_s2 * d,
            self.accel_bias_m_s2,
        )

    def update(
        self, dt_s: float, accel_up_m_s2: float, measured_alt_m: float, *, on_ground: bool = False
    ) -> AltitudeEstimate:
        """Advance by ``dt_s`` with this step's acceleration sample and barometric reading.

        ``on_ground``: the vehicle has not lifted off yet: while it also measures no upward
        acceleration it rests at zero and the barometer's zero error is learnt; rising, it
        cannot sink.  The accelerometer bias is learnt in the air only.
        """
        dt_s = min(dt_s, self.max_step_s)
        if dt_s <= 0:
            return self.estimate
        # Trapezoid between this sample and the last: the samples come every 20-30 ms and the
        # acceleration changes with every throttle step in between.
        previous = self._prev_accel if self._prev_accel is not None else accel_up_m_s2
        self._prev_accel = accel_up_m_s2
        accel = 0.5 * (previous + accel_up_m_s2) - self.accel_bias_m_s2
        self._accel_m_s2 = accel_up_m_s2 - self.accel_bias_m_s2
        self._alt_m += (self._climb_m_s + 0.5 * accel * dt_s) * dt_s
        self._climb_m_s += accel * dt_s
        if on_ground:
            if accel_up_m_s2 < RESTING_ACCEL_M_S2:
                self._learn_ground(dt_s, measured_alt_m)
                return self.estimate
            # Lifting already (noticed a few samples late by the caller): integrate, but
            # it cannot sink into the ground.
            self._climb_m_s = max(self._climb_m_s, 0.0)
        innovation = measured_alt_m - self.baro_offset_m - self._seen.step(self._alt_m, dt_s)
        w = self.bandwidth_rad_s
        # The lag model's own error grows with speed: trust the barometer less while moving.
        trust = 1.0 / (1.0 + (self._climb_m_s / self.fast_m_s) ** 2)
        correction = trust * innovation * dt_s
        self._alt_m += 3.0 * w * correction
        self._seen.shift(3.0 * w * correction)
        self._climb_m_s += 3.0 * w * w * correction
        if not on_ground:
            self.accel_bias_m_s2 -= self.bias_share * w**3 * correction
        return self.estimate

    def _learn_ground(self, dt_s: float, measured_alt_m: float) -> None:
        """Resting on the ground: the truth is zero, so the reading's mean is the zero error
        (the mean after ``ground_settle_s`` once there is one: the FC's transient left out)."""
        self._alt_m = self._climb_m_s = self._accel_m_s2 = 0.0
        self._seen.reset(0.0)
        settled = self._ground_s >= self.ground_settle_s
        self._ground_s += dt_s
        self._ground_all.add(measured_alt_m)
        if settled:
            self._ground_settled.add(measured_alt_m)
        self.baro_offset_m = (
            self._ground_settled if self._ground_settled.count else self._ground_all
        ).mean


class _Mean:
    __slots__ = ("count", "total")

    def __init__(self) -> None:
        self.count = 0
        self.total = 0.0

    def add(self, value: float) -> None:
        self.count += 1
        self.total += value

    @property
    def mean(self) -> float:
        return self.total / self.count if self.count else 0.0
