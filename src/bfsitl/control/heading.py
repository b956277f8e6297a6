"""Heading control through the yaw stick: a target heading in, a yaw rate out.

In ANGLE mode the yaw stick stays a rate command (the FC levels roll and pitch only), so
turning to a heading is a loop closed here: the heading error (the short way round) times
``kp_per_s`` gives a yaw rate, limited to ``max_rate_deg_s``; the FC's own yaw-rate PID
makes that rate, so a proportional loop here is enough.  Which stick asks for it is
:class:`~bfsitl.control.angle_sticks.AngleStickMap`'s business.

Sans-I/O, like the other controllers: no clock, no socket.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import ControllerConfigError


def heading_error_deg(target_deg: float, heading_deg: float) -> float:
    """``target - heading`` the short way round, in -180..180 (positive: turn clockwise)."""
    return (target_deg - heading_deg + 180.0) % 360.0 - 180.0


@dataclass(frozen=True, slots=True)
class HeadingGains:
    kp_per_s: float = 2.0
    max_rate_deg_s: float = 90.0

    def __post_init__(self) -> None:
        for name in ("kp_per_s", "max_rate_deg_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ControllerConfigError(f"heading gain {name} must be > 0, got {value}")


class HeadingController:
    """Yaw rate (deg/s, positive clockwise) that turns ``heading_deg`` to the target."""

    def __init__(self, gains: HeadingGains | None = None) -> None:
        self.gains = gains or HeadingGains()

    def rate_deg_s(self, heading_deg: float, target_deg: float) -> float:
        g = self.gains
        rate = g.kp_per_s * heading_error_deg(target_deg, heading_deg)
        return max(-g.max_rate_deg_s, min(g.max_rate_deg_s, rate))
