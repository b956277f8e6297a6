"""What a caller hangs on a flight loop: on each step, on a phase change, on each line of
progress, and a stop condition.

Missions, the :class:`~bfsitl.autopilot.Autopilot`, scenarios and tests all drive the same
:class:`~bfsitl.mission.loop.FlightLoop`; what they add goes in here instead of into copies of
the loop.  A stop condition ends the flying (the manoeuvre under way returns, the ones after
it do nothing, :attr:`FlightLoop.stopped` says why) without an exception: a scenario uses it
when a fault has taken the autopilot's sticks, and then only watches.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.phase import Phase
from bfsitl.mission.vehicle import FlightSample

#: Every row recorded, with the sample it was made from (outputs, a scenario's trace).
RowCallback = Callable[[FlightRow, FlightSample], None]
#: A line of progress ("take-off to 2.00 m").
EventCallback = Callable[[str], None]
#: A reason to stop flying now (None: fly on); asked after each recorded step.
StopCondition = Callable[[FlightSample], str | None]


@dataclass(frozen=True, slots=True)
class FlightHooks:
    """See the module docstring; every hook is optional."""

    on_step: RowCallback | None = None
    on_phase: Callable[[Phase], None] | None = None
    on_event: EventCallback | None = None
    stop: StopCondition | None = None
