"""Where a vehicle hovers on the throttle stick, and how hard the stick pushes it: what the
firmware's altitude modes (``ap_hover_throttle``) and bfsitl's altitude controllers start from.

IRIS hovers at 1545 us (measured: the autopilot's mean throttle in a hold, on 4.6.0 and master
alike) with a motor command of 0.5417.  The FC maps the stick onto the motor range linearly, so
another quad's hover stick is IRIS's scaled by the two hover commands.  Thrust grows with the
square of the rotor speed, and the speed with the command: at hover one microsecond of stick
adds ``2 g / (hover_us - 1000)`` of upward acceleration.
"""

from __future__ import annotations

from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import IRIS, QuadParams

#: IRIS's hover throttle, measured (see above).
IRIS_HOVER_THROTTLE_US = 1545.0
#: The bottom of the throttle stick.
THROTTLE_LOW_US = 1000.0


def hover_throttle_us(quad: QuadParams) -> float:
    """The throttle stick that holds ``quad`` in a hover, microseconds."""
    scale = quad.hover_command / IRIS.hover_command
    return THROTTLE_LOW_US + (IRIS_HOVER_THROTTLE_US - THROTTLE_LOW_US) * scale


def stick_per_acceleration_us(quad: QuadParams) -> float:
    """Microseconds of throttle stick per m/s^2 of upward acceleration near the hover (27.8
    for IRIS)."""
    return (hover_throttle_us(quad) - THROTTLE_LOW_US) / (2.0 * STANDARD_GRAVITY_M_S2)
