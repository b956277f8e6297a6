"""What a flown mission comes to: how it ended (:class:`Outcome`) and its figures
(:class:`MissionResult`), JSON-ready through :meth:`MissionResult.summary`."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field
from typing import Any

from bfsitl.mission.flight_metrics import (
    AttitudeTracking,
    HoldStats,
    cross_track_rms,
    landed_from_start_m,
)
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.legs import LegStats
from bfsitl.mission.plan import MissionPlan


class Outcome(enum.Enum):
    """How a mission ended; :attr:`succeeded` for the first two.

    Attributes:
        LANDED: Flown to its end, landed and disarmed.
        COMPLETED: Flown to its end in the air (a plan with ``land = false``).
        ARMING_BLOCKED: The FC would not arm; :attr:`MissionResult.blockers` says why.
        SITL_EXITED: The SITL process ended during the flight.
        TIMEOUT: A phase did not finish within its time limit.
        CRASHED: The vehicle tipped over or hit the ground too fast.
        INTERRUPTED: Ctrl-C, SIGTERM or SIGHUP stopped it.
        ERROR: Any other bfsitl error; :attr:`MissionResult.reason` says which.
    """

    LANDED = "landed"
    COMPLETED = "completed"  # a plan with land = false: ended in the air
    ARMING_BLOCKED = "arming-blocked"
    SITL_EXITED = "sitl-exited"
    TIMEOUT = "timeout"
    CRASHED = "crashed"
    INTERRUPTED = "interrupted"
    ERROR = "error"

    @property
    def succeeded(self) -> bool:
        return self in (Outcome.LANDED, Outcome.COMPLETED)


@dataclass
class MissionResult:
    """What a flown mission comes to: how it ended, why, and its figures.

    Attributes:
        outcome: How it ended.
        reason: One line saying why ("landed and disarmed", the error's first line).
        controller: The altitude controller's name.
        plan: The plan flown.
        rows: One row per control step, in order.
        blockers: The FC's arming blockers, when it would not arm.
        armed_after_s: Wall seconds from the vehicle's creation to the FC reporting armed;
            None if it never armed.
        hold: How well the altitude was held (the truth against the target), or None.
        attitude: How well the FC's roll and pitch followed the truth in the air, or None.
        metrics: The take-off's step response (a
            :class:`~bfsitl.control.metrics.StepMetrics`), when the plan holds long enough
            after it to judge one; else None.
        legs: One entry per waypoint reached: arrival error and cross-track.
        extra: Anything else worth keeping, by name: ``firmware`` (version and
            conventions), ``rc_link`` and ``physics`` (how the links kept up).
    """

    outcome: Outcome
    reason: str
    controller: str
    plan: MissionPlan
    rows: list[FlightRow] = field(default_factory=list)
    blockers: tuple[str, ...] = ()
    armed_after_s: float | None = None
    hold: HoldStats | None = None
    attitude: AttitudeTracking | None = None  # FC roll/pitch vs the truth in the air
    metrics: Any = None  # bfsitl.control.metrics.StepMetrics of the take-off step
    legs: list[LegStats] = field(default_factory=list)  # one per waypoint reached
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def succeeded(self) -> bool:
        return self.outcome.succeeded

    def summary(self) -> dict[str, Any]:
        """Everything worth keeping, JSON-ready."""

        def plain(value: Any) -> Any:
            if value is None:
                return None
            if hasattr(value, "__dataclass_fields__"):
                return {name: plain(getattr(value, name)) for name in value.__dataclass_fields__}
            if isinstance(value, float):
                return round(value, 4) if math.isfinite(value) else None
            if isinstance(value, (list, tuple)):
                return [plain(v) for v in value]
            if isinstance(value, dict):
                return {k: plain(v) for k, v in value.items()}
            return value

        return {
            "outcome": self.outcome.value,
            "succeeded": self.succeeded,
            "reason": self.reason,
            "controller": self.controller,
            "plan": plain(self.plan),
            "blockers": list(self.blockers),
            "armed_after_s": plain(self.armed_after_s),
            "hold": plain(self.hold),
            "attitude": plain(self.attitude),
            "step_response": plain(self.metrics),
            "waypoints": plain(self.legs),
            "cross_track_rms_m": plain(cross_track_rms(self.legs)),
            "landed_from_start_m": plain(landed_from_start_m(self.rows)),
            "rows": len(self.rows),
            "flight_time_s": plain(self.rows[-1].time_s - self.rows[0].time_s)
            if self.rows
            else None,
            **plain(self.extra),
        }
