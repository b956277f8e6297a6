"""What the flight is doing: one name per phase, written into every row of the log.

A :class:`Phase` is a ``str`` (its value), so logs, CSV files and comparisons with the old
bare strings read as before; code compares members, never spelled-out strings.
"""

from __future__ import annotations

from enum import StrEnum


class Phase(StrEnum):
    """The mission's phase.  The last row of a flight that did not land carries how it ended
    instead (an :class:`~bfsitl.mission.results.Outcome`'s value, written by
    ``FlightLoop.abort``)."""

    ARMING = "arming"
    GROUND = "ground"  # armed on the ground while the barometer settles
    TAKEOFF = "takeoff"
    HOLD = "hold"
    GOTO = "goto"
    YAW = "yaw"
    LAND = "land"
    LANDED = "landed"
    FC_MODE = "fc-mode"  # the firmware's own mode flies (FlightLoop.hand_over)
    OBSERVE = "observe"  # nobody flies; the mission only watches
    WATCH = "watch"  # a scenario watches after a fault took the sticks
    POLICY = "policy"  # a pilot of the caller's has every stick (FlightLoop.fly_sticks)


#: The phases in which bfsitl flies (and a hold or a leg's error means something).
FLOWN = frozenset({Phase.TAKEOFF, Phase.HOLD, Phase.GOTO, Phase.YAW, Phase.LAND, Phase.POLICY})
