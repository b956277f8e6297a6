"""A pilot that has every stick: what :meth:`FlightLoop.fly_sticks
<bfsitl.mission.loop.FlightLoop.fly_sticks>` hands the vehicle to (a trained policy:
:class:`bfsitl.gym.policy_pilot.PolicyPilot`).

The loop keeps what it always does (the sample, the crash checks, the record, the hooks, the
rate); the pilot only turns each sample into the RC command to send.  It sees the sample
(the FC's view over MSP, with the truth beside it where one is known: a pilot meant for a
board must not read the truth) and the command being sent; it returns the next one, switches
included (a policy trained in ACRO turns ANGLE off).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from bfsitl.fc.rc_link import RcCommand
from bfsitl.mission.vehicle import FlightSample


@runtime_checkable
class StickPilot(Protocol):
    """See the module docstring."""

    #: The rate it must be asked at, in steps per second of the vehicle's clock (a policy's
    #: training rate); None: any.
    rate_hz: float | None
    #: The altitude it flies to, metres above the take-off point, for the log's target
    #: column; None: it has none (the row keeps the loop's last target).
    target_alt_m: float | None

    def sticks(self, sample: FlightSample, command: RcCommand) -> RcCommand:
        """The command to send from this step on, given the sample and what is being sent."""
        ...
