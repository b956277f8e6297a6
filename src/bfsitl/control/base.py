"""The contract between a mission and an altitude controller.

A mission samples the flight controller at its control rate (about 50 Hz of simulation time),
hands the controller what a real board reports, and sends the returned throttle over RC.  The
controller sees only the FC's view: the barometric altitude (``MSP_ALTITUDE``, zeroed at arming,
quantised to ~8 cm and low-pass filtered by the firmware, so it lags the truth), a climb rate
derived from it, and the vertical acceleration from the FC's accelerometer (``MSP_RAW_IMU``).
It never sees the simulated truth: that is kept to judge it.

Besides ``reset`` and ``update`` a controller may have ``observe_ground(sample)``: the mission
then hands it the samples of its ground phase (armed at idle before the take-off) instead of
resetting it when the take-off begins; and ``observe_flight(sample, throttle_us)``: the
mission hands it the samples of a flight another pilot has the sticks of.

Everything here is plain data and a :class:`typing.Protocol`, so controllers can be tested
offline (``tests/support/altitude_plant.py``) exactly as the mission runner calls them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Protocol, runtime_checkable

from bfsitl.errors import (
    ControllerConfigError,
)

#: RC throttle range the controllers speak, microseconds (the RC link clamps to it as well).
THROTTLE_MIN_US = 1000.0
THROTTLE_MAX_US = 2000.0


@dataclass(frozen=True, slots=True)
class AltitudeInput:
    """One control step's measurements, in the FC's frame (up positive, metres, seconds)."""

    time_s: float  # mission clock in seconds (simulation time), strictly increasing
    altitude_m: float  # measured altitude relative to the arming point (MSP_ALTITUDE / 100)
    climb_rate_m_s: float  # measured vertical speed, up positive
    target_alt_m: float  # wanted altitude, same reference
    #: Vertical acceleration, up positive, gravity removed, from the FC's accelerometer
    #: (MSP_RAW_IMU) and attitude; None when the source has none.  Unlike the barometric
    #: altitude it is not late, so a controller can fuse the two (:mod:`.altitude_estimator`).
    accel_up_m_s2: float | None = None


@runtime_checkable
class AltitudeController(Protocol):
    """What a mission calls: ``reset`` once after arming, then ``update`` every control step."""

    name: str

    def reset(self, time_s: float) -> None:
        """Forget the past: called right after arming, with the throttle at minimum."""
        ...

    def update(self, sample: AltitudeInput) -> float:
        """Return the RC throttle in microseconds (1000..2000) for this step."""
        ...


@runtime_checkable
class EstimatesAltitude(Protocol):
    """A controller that keeps its own estimate of the true altitude (the fused one).

    The FC's reading carries a zero error of its own, different in every flight (a few cm on
    4.6.0; up to ~8 cm on master, whose altitude also takes the virtual GPS's, zeroed on one
    noisy sample); a mission judges "reached" on this estimate when a controller has one.
    """

    @property
    def altitude_estimate_m(self) -> float | None:
        """The estimated altitude above the take-off point, or None before it is known."""
        ...


@runtime_checkable
class ObservesGround(Protocol):
    """A controller that learns from the armed vehicle at rest before the take-off (the
    fused one learns the barometer's zero error there); the mission feeds it every sample
    of the ground phase instead of asking it for throttle."""

    def observe_ground(self, sample: AltitudeInput) -> None: ...


@runtime_checkable
class ObservesFlight(Protocol):
    """A controller that keeps its state current while another pilot flies (the mission's
    ``fly_sticks``): each of those steps it sees the sample and the throttle the pilot sent,
    so that when the sticks come back it starts from where the vehicle is, not from where it
    was handed over (the fused and cascaded controllers' references)."""

    def observe_flight(self, sample: AltitudeInput, throttle_us: float) -> None: ...


@runtime_checkable
class KnowsHover(Protocol):
    """A controller that estimates the hover throttle (us): the landing starts from it."""

    hover_throttle_us: float


@runtime_checkable
class TakesHoverEstimate(Protocol):
    """A controller (the landing one) that can start from another's hover estimate."""

    def set_hover_estimate(self, hover_us: float) -> None: ...


@runtime_checkable
class DetectsTouchdown(Protocol):
    """A landing controller: it says when the vehicle is down, and the mission disarms."""

    @property
    def touched_down(self) -> bool: ...


def clamp(value: float, low: float, high: float) -> float:
    """``value`` limited to ``[low, high]`` (``low`` wins if the bounds cross)."""
    return low if value < low else (high if value > high else value)


def check_gains(gains: object) -> None:
    """Reject non-finite gain values early, with the gain's name in the message.

    Called from each gains dataclass's ``__post_init__``; the controller-specific range checks
    follow it there.
    """
    for field in fields(gains):  # type: ignore[arg-type]
        value = getattr(gains, field.name)
        if (
            not isinstance(value, (int, float))
            or isinstance(value, bool)
            or not math.isfinite(value)
        ):
            raise ControllerConfigError(
                f"{type(gains).__name__}: {field.name} must be a finite number, got {value!r}"
            )


def require(condition: bool, gains: object, message: str) -> None:
    """Raise :class:`ControllerConfigError` naming the gains class unless ``condition``."""
    if not condition:
        raise ControllerConfigError(f"{type(gains).__name__}: {message}")


def throttle_range_ok(gains: object, low_us: float, high_us: float) -> None:
    """The common throttle-limit check: inside the RC range and low below high."""
    require(
        THROTTLE_MIN_US <= low_us < high_us <= THROTTLE_MAX_US,
        gains,
        f"throttle limits must satisfy {THROTTLE_MIN_US:.0f} <= min < max <= "
        f"{THROTTLE_MAX_US:.0f} us, got {low_us:g}..{high_us:g}",
    )


class HoverLimits(Protocol):
    """Gains with a throttle range and hover bounds (the cascade's and the landing's)."""

    # Read-only properties: frozen dataclasses (the gains) satisfy them.
    @property
    def throttle_min_us(self) -> float: ...
    @property
    def hover_min_us(self) -> float: ...
    @property
    def hover_guess_us(self) -> float: ...
    @property
    def hover_max_us(self) -> float: ...
    @property
    def throttle_max_us(self) -> float: ...


def hover_range_ok(gains: HoverLimits) -> None:
    """The throttle limits, and the hover bounds and guess inside them, in that order."""
    throttle_range_ok(gains, gains.throttle_min_us, gains.throttle_max_us)
    require(
        gains.throttle_min_us
        <= gains.hover_min_us
        <= gains.hover_guess_us
        <= gains.hover_max_us
        <= gains.throttle_max_us,
        gains,
        "need throttle_min_us <= hover_min_us <= hover_guess_us <= hover_max_us <= throttle_max_us",
    )


class WholeMicroseconds:
    """Rounds a throttle to whole microseconds (what the RC link sends), carrying the
    remainder to the next step so the fraction is kept on average: 1 us is ~4 cm/s of drift
    on the IRIS, so a hover between two whole values must alternate, not stick to one."""

    __slots__ = ("carry_us",)

    def __init__(self) -> None:
        self.carry_us = 0.0

    def __call__(self, throttle_us: float) -> float:
        whole = float(round(throttle_us + self.carry_us))
        self.carry_us = clamp(self.carry_us + throttle_us - whole, -0.5, 0.5)
        return whole
