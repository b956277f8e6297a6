"""The firmware's failsafe phases, as its blackbox log and the analysers number them.

One enum for every reader: the blackbox decoder, the analysers that name the phase a flight
ended in, the scenario trace and the plots; it is the firmware's table, so it lives with the
other firmware tables (arming flags, boxes) at the bottom of the stack.
"""

from __future__ import annotations

import enum


class FailsafePhase(enum.IntEnum):
    """``failsafePhase_e`` (``[4.6] src/main/flight/failsafe.h:47-55``); AUTOPILOT is
    master's (``[M] src/main/flight/failsafe.h:55``)."""

    IDLE = 0
    RX_LOSS_DETECTED = 1
    LANDING = 2
    LANDED = 3
    RX_LOSS_MONITORING = 4
    RX_LOSS_RECOVERED = 5
    GPS_RESCUE = 6
    AUTOPILOT = 7
