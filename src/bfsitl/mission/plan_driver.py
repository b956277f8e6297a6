"""Flying a plan: :func:`fly_plan` drives a :class:`~bfsitl.mission.loop.Mission` through a
:class:`~bfsitl.mission.plan.MissionPlan` (``bfsitl fly``, the Autopilot and scenarios all use
it), and :func:`fly_mission` (:func:`run_mission` on a new mission) turns every way a flight
can end into an :class:`~bfsitl.mission.results.Outcome` with a reason, so callers get data,
not exceptions.
"""

from __future__ import annotations

from collections.abc import Callable

from bfsitl.control.base import AltitudeController
from bfsitl.errors import (
    ArmingBlockedError,
    BfsitlError,
    CrashDetectedError,
    MissionError,
    MissionTimeoutError,
    SitlExitedError,
)
from bfsitl.mission.flight_metrics import attitude_tracking, hold_stats, takeoff_metrics
from bfsitl.mission.flight_row import RowWriter
from bfsitl.mission.hooks import EventCallback, RowCallback
from bfsitl.mission.loop import DEFAULT_RATE_HZ, Mission
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan import MissionPlan, Waypoint
from bfsitl.mission.results import MissionResult, Outcome
from bfsitl.mission.vehicle import Vehicle

#: The take-off's step response is judged over this much hold after it (metrics.py).
STEP_STEADY_WINDOW_S = 5.0


def fly_plan(mission: Mission, plan: MissionPlan, *, arm: bool = True,
             time_left_s: Callable[[], float] | None = None,
             after_step: Callable[[Phase], None] | None = None) -> None:
    """Arm, take off, hold, fly the waypoints, land: ``plan`` on ``mission``, raising on
    trouble (:func:`run_mission` turns that into an outcome).

    ``arm=False`` when the caller has armed already; ``time_left_s`` (what the caller's run
    has left) cuts the hold short so that it does not outlast the run; ``after_step`` is
    told each step that ended (TAKEOFF, HOLD, GOTO for each waypoint, LANDED).  Once the
    mission's stop condition has ended the flying, the rest of the plan is not flown.
    """
    done = after_step or (lambda _step: None)
    if arm:
        mission.arm()
    if plan.ground_s > 0:
        mission.wait_on_ground(plan.ground_s)
    position = plan.needs_position or (plan.hold_position and mission.session.has_gps)
    mission.takeoff(plan.target_alt_m, timeout_s=plan.takeoff_timeout_s,
                    hold_position=position)
    if mission.stopped:
        return
    done(Phase.TAKEOFF)
    hold_s = plan.hold_s if time_left_s is None else min(plan.hold_s, max(0.0, time_left_s()))
    if hold_s > 0:
        if position:
            mission.hold_position(hold_s)
        else:
            mission.hold(hold_s)
        if mission.stopped:
            return
        done(Phase.HOLD)
    for number, waypoint in enumerate(plan.waypoints, start=1):
        fly_waypoint(mission, waypoint, number, plan.speed_m_s)
        if mission.stopped:
            return
        done(Phase.GOTO)
    if plan.land:
        mission.land(timeout_s=plan.land_timeout_s)
        if mission.stopped:
            return
        done(Phase.LANDED)


def fly_waypoint(mission: Mission, waypoint: Waypoint, number: int, speed_m_s: float) -> None:
    """The leg to ``waypoint``, the turn to its heading, its hold."""
    mission.fly_to(waypoint.north_m, waypoint.east_m, waypoint.alt_m, speed_m_s=speed_m_s,
                   waypoint=number)
    if waypoint.heading_deg is not None:
        mission.yaw_to(waypoint.heading_deg)
    if waypoint.hold_s > 0:
        mission.hold_position(waypoint.hold_s, waypoint=number)


def run_mission(
    session: Vehicle,
    plan: MissionPlan,
    controller: AltitudeController,
    *,
    landing: AltitudeController | None = None,
    log: RowWriter | None = None,
    on_row: RowCallback | None = None,
    on_event: EventCallback | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
) -> MissionResult:
    """Fly ``plan`` on a started session; every ending becomes an :class:`Outcome`.

    Ctrl-C becomes :attr:`Outcome.INTERRUPTED` (the sticks go to disarm at once and a last
    row records them); the caller still closes the session.
    """
    mission = Mission(session, controller, landing=landing, rate_hz=rate_hz, log=log,
                      on_row=on_row, on_event=on_event)
    return fly_mission(mission, plan)


def fly_mission(mission: Mission, plan: MissionPlan, *,
                keep_flying: bool = False) -> MissionResult:
    """Fly ``plan`` from the ground on ``mission`` (a new one, or one that has flown and
    landed before: the :class:`~bfsitl.autopilot.Autopilot` flies on its own); every ending
    becomes an :class:`Outcome`, and the result covers the rows and legs of this plan only.

    A plan that does not land (``land = false``) ends with the sticks at disarm, as every
    other ending but a landing does, unless ``keep_flying``: then the mission is still
    flying it, and its next manoeuvre (``land()``) goes on from there."""
    session = mission.session
    first_row, first_leg = len(mission.rows), len(mission.legs)
    controller = mission.controller
    name = getattr(controller, "name", type(controller).__name__)
    outcome, reason = Outcome.LANDED, "landed and disarmed"
    blockers: tuple[str, ...] = ()
    try:
        if plan.needs_position and not session.has_gps:
            raise MissionError(
                "this mission has waypoints, flown from the FC's GPS, and this firmware has "
                "no GPS: fly a GPS build (`bfsitl firmware build --gps`, add --lockstep for "
                "lockstep; master always has it)")
        fly_plan(mission, plan)
        if not plan.land:
            outcome, reason = Outcome.COMPLETED, "mission completed in the air (land = false)"
    except KeyboardInterrupt:
        outcome, reason = Outcome.INTERRUPTED, "interrupted (Ctrl-C)"
    except ArmingBlockedError as exc:
        outcome, reason, blockers = Outcome.ARMING_BLOCKED, str(exc), exc.blockers
    except SitlExitedError as exc:
        outcome, reason = Outcome.SITL_EXITED, str(exc)
    except MissionTimeoutError as exc:
        outcome, reason = Outcome.TIMEOUT, str(exc)
    except CrashDetectedError as exc:
        outcome, reason = Outcome.CRASHED, str(exc)
    except BfsitlError as exc:
        outcome, reason = Outcome.ERROR, str(exc)
    if outcome is not Outcome.LANDED and not (keep_flying and outcome is Outcome.COMPLETED):
        try:
            mission.abort(outcome)
        except (BfsitlError, OSError):
            pass  # the session's close still sends disarm through the RC link
    if outcome is Outcome.ERROR and session.has_exited():
        outcome = Outcome.SITL_EXITED
    rows = mission.rows[first_row:]
    result = MissionResult(outcome, reason.splitlines()[0] if reason else "", name, plan,
                           rows, blockers, session.armed_after_s)
    result.hold = hold_stats(rows)
    result.legs = list(mission.legs[first_leg:])
    result.attitude = attitude_tracking(rows)
    profile = session.firmware
    if profile is not None:
        result.extra["firmware"] = {
            "version": profile.firmware_version, "api": profile.api_version,
            "conventions": profile.generation.value, "gps": profile.has_gps}
    if not plan.waypoints or plan.hold_s >= STEP_STEADY_WINDOW_S:
        # A step response needs the hold after it: straight into a leg, there is none.
        result.metrics = takeoff_metrics(rows, plan.target_alt_m)
    rc_stats, bridge_stats = session.rc_stats(), session.bridge_stats()
    if rc_stats is not None:
        result.extra["rc_link"] = rc_stats
    if bridge_stats is not None:
        result.extra["physics"] = {
            "answered_ratio": bridge_stats.answered_ratio, "speed": bridge_stats.speed,
            "steps": bridge_stats.steps, "lockstep": session.lockstep,
            "exchange": session.backend.exchange}
    return result
