"""ANGLE mode's stick -> angle curve, and its inverse: which stick holds a wanted tilt.

In ANGLE mode the FC levels to ``angle_limit x setpoint(stick) / setpoint(full stick)``
(4.6.0 and master ``pid.c``: ``angleTarget = angleLimit * currentPidSetpoint *
maxSetpointRateInv``), so the angle follows the *rate curve's* shape.  With the default Actual
rates (centre 70 deg/s, max 670 deg/s, no expo) that shape is far from a line: a third of the
stick gives 6.7 deg, not 20 (``fc/rc.c`` ``applyActualRates``:
``x * centre + max(0, max - centre) * |x| * (x^5 * expo + x * (1 - expo))``).  A controller
that assumed a line would be three times too weak near the centre, where it works.

The rates and the angle limit are read from the FC (MSP_RC_TUNING, MSP_PID_ADVANCED), so the
map follows whatever the FC is configured with; only Actual rates are supported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bfsitl.errors import UnsupportedFirmwareError
from bfsitl.fc.rc_link import RC_MAX_US, RC_MID_US
from bfsitl.protocol import messages as msg

#: Full deflection, either way from the middle.
RC_HALF_RANGE_US = float(RC_MAX_US - RC_MID_US)
#: Newton steps at most; the curve's inverse takes a few.
_NEWTON_STEPS = 60


@dataclass(frozen=True, slots=True)
class ActualRates:
    """One axis of Actual rates, in the firmware's units (10 deg/s, percent)."""

    rc_rate: int  # centre sensitivity / 10 deg/s
    rate: int  # max rate / 10 deg/s
    expo: int  # percent
    #: setpoint(1.0), the full-stick rate (deg/s): kept, as a position step asks for it
    #: several times.
    full_deg_s: float = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "full_deg_s", self.setpoint(1.0))

    def setpoint(self, deflection: float) -> float:
        """The rate setpoint (deg/s) for a stick deflection -1..1 (``applyActualRates``)."""
        x = max(-1.0, min(1.0, deflection))
        e = self.expo / 100.0
        shaped = abs(x) * (x**5 * e + x * (1.0 - e))
        centre = self.rc_rate * 10.0
        return x * centre + max(0.0, self.rate * 10.0 - centre) * shaped

    def share(self, deflection: float) -> float:
        """setpoint(deflection) / setpoint(full stick): what ANGLE mode scales its limit by."""
        full = self.full_deg_s
        return self.setpoint(deflection) / full if full > 0 else 0.0

    def deflection_for(self, rate_deg_s: float) -> float:
        """The stick deflection -1..1 that asks for ``rate_deg_s`` (clamped to the curve)."""
        full = self.full_deg_s
        if full <= 0:
            return 0.0
        wanted = max(-1.0, min(1.0, rate_deg_s / full))
        sign = 1.0 if wanted >= 0 else -1.0
        wanted = abs(wanted)
        # Newton's method on setpoint(x) / full = wanted.  With the Actual curve's
        # non-negative coefficients the curve rises and bends upwards on 0..1, so from the
        # right of the root every step lands between the root and the last point: the steps
        # shrink to nothing and stop when a step no longer moves left.  The start is where
        # the centre sensitivity alone would reach the rate (the other terms only add, so it
        # is right of the root), or full stick.  (A bisection to the same precision took 40
        # evaluations; a position-controlled flight inverts the curve several times every
        # control step.)
        e = self.expo / 100.0
        keep = 1.0 - e
        centre = self.rc_rate * 10.0
        span = max(0.0, self.rate * 10.0 - centre)
        if e == 0.0 and centre > 0:
            # No expo (the firmware's default): centre x + span x^2, a quadratic's root
            # (in the form that loses no digits when span x is small beside the centre).
            target = wanted * full
            return sign * min(
                1.0, 2.0 * target / (centre + math.sqrt(centre**2 + 4 * span * target))
            )
        x = min(1.0, wanted * full / centre) if centre > 0 else 1.0
        for _ in range(_NEWTON_STEPS):
            x5 = x**5
            value = (x * centre + span * x * (x5 * e + x * keep)) / full - wanted
            slope = (centre + span * (6.0 * e * x5 + 2.0 * keep * x)) / full
            if value <= 0.0 or slope <= 0.0:
                break
            step = value / slope
            if x - step >= x:
                break
            x = max(0.0, x - step)
        return sign * x


#: Yaw rates of a map built by hand (:meth:`AngleStickMap.linear`): a straight line.
_LINEAR_YAW = ActualRates(rc_rate=67, rate=67, expo=0)


@dataclass(frozen=True, slots=True)
class AngleStickMap:
    """Stick <-> angle for roll and pitch in ANGLE mode, stick <-> rate for yaw (ANGLE mode
    levels roll and pitch only; yaw stays a rate command)."""

    roll: ActualRates
    pitch: ActualRates
    angle_limit_deg: float
    yaw: ActualRates = _LINEAR_YAW

    @classmethod
    def linear(cls, angle_limit_deg: float = 60.0) -> AngleStickMap:
        """A straight line (centre sensitivity = max rate): for tests and hand checks."""
        line = ActualRates(rc_rate=67, rate=67, expo=0)
        return cls(line, line, angle_limit_deg)

    @classmethod
    def from_replies(cls, tuning: msg.RcTuning, advanced: msg.PidAdvanced) -> AngleStickMap:
        if tuning.rates_type not in (None, msg.RcTuning.ACTUAL):
            raise UnsupportedFirmwareError(
                f"position control reads the FC's rate curve and knows Actual rates only; this "
                f"FC uses rates_type {tuning.rates_type}: `set rates_type = ACTUAL` (and set "
                f"the rates again) for autonomous flight"
            )
        return cls(
            ActualRates(tuning.roll_rc_rate, tuning.roll_rate, tuning.roll_expo),
            ActualRates(tuning.pitch_rc_rate, tuning.pitch_rate, tuning.pitch_expo),
            float(advanced.angle_limit_deg),
            ActualRates(tuning.yaw_rc_rate, tuning.yaw_rate, tuning.yaw_expo),
        )

    def angle_deg(self, axis: str, stick_us: float) -> float:
        """The angle the FC holds for ``stick_us`` on ``axis`` ("roll" or "pitch")."""
        rates = self.roll if axis == "roll" else self.pitch
        return self.angle_limit_deg * rates.share((stick_us - RC_MID_US) / RC_HALF_RANGE_US)

    def stick_us(self, axis: str, angle_deg: float) -> float:
        """The stick that makes the FC hold ``angle_deg`` (clamped to the angle limit)."""
        rates = self.roll if axis == "roll" else self.pitch
        wanted = max(-1.0, min(1.0, angle_deg / self.angle_limit_deg))
        # share(x) = setpoint(x) / setpoint(1): the deflection for a share is the one for
        # that fraction of the full-stick rate.
        deflection = rates.deflection_for(wanted * rates.full_deg_s)
        return RC_MID_US + deflection * RC_HALF_RANGE_US

    def yaw_stick_us(self, rate_deg_s: float) -> float:
        """The yaw stick that asks for ``rate_deg_s`` (positive: nose right, clockwise seen
        from above, the heading growing)."""
        return RC_MID_US + self.yaw.deflection_for(rate_deg_s) * RC_HALF_RANGE_US
