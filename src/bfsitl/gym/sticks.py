"""Actions as sticks: four numbers in [-1, 1] become the RC channels the FC reads.

Roll, pitch and yaw map linearly onto 1000..2000 us around the 1500 us centre; throttle maps
-1..1 onto 1000..2000 us (-1 is the bottom of the stick: idle while armed).  What the sticks
mean is the FC's business: in ``angle`` mode roll and pitch ask for an angle (the FC's
``angle_limit``), in ``acro`` mode for a rate; yaw always asks for a rate.  ARM (AUX1) and
the ANGLE switch (AUX2) are the environment's, never the policy's.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

from bfsitl.fc.rc_link import RC_MAX_US, RC_MID_US, RC_MIN_US, RcCommand

#: The order of the action vector.
STICKS: tuple[str, ...] = ("roll", "pitch", "throttle", "yaw")
#: Half the stick travel, us.
_HALF_RANGE_US = (RC_MAX_US - RC_MIN_US) / 2.0


def _clip(value: float) -> float:
    return -1.0 if value < -1.0 else 1.0 if value > 1.0 else value


def stick_us(value: float) -> int:
    """One normalised stick (clipped to [-1, 1]; NaN is refused) as a pulse width."""
    if value != value:  # NaN
        raise ValueError("a stick of NaN: the policy's action has no number in it")
    return round(RC_MID_US + _HALF_RANGE_US * _clip(float(value)))


def sticks_to_rc(action: Sequence[float], base: RcCommand) -> RcCommand:
    """``action`` (roll, pitch, throttle, yaw in [-1, 1]) on top of ``base``'s switches."""
    roll, pitch, throttle, yaw = (stick_us(v) for v in action)
    return replace(base, roll_us=roll, pitch_us=pitch, throttle_us=throttle, yaw_us=yaw)


def rc_to_sticks(command: RcCommand) -> tuple[float, float, float, float]:
    """The inverse of :func:`sticks_to_rc` (for a hand-written policy and for tests)."""
    return tuple(  # type: ignore[return-value]
        (float(us) - RC_MID_US) / _HALF_RANGE_US
        for us in (command.roll_us, command.pitch_us, command.throttle_us, command.yaw_us)
    )
