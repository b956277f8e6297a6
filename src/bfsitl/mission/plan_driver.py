"""Flying a plan, one verb at three depths:

* :func:`fly` (public): a plan on a started vehicle with a controller, in one call;
* :func:`fly_plan`: a plan on a :class:`~bfsitl.mission.loop.FlightLoop` the caller holds
  (the :class:`~bfsitl.autopilot.Autopilot` flies its own loop); both turn every way a
  flight can end into an :class:`~bfsitl.mission.results.Outcome` with a reason, so callers
  get data, not exceptions;
* :func:`fly_steps`: the plan's steps on the loop (arm, take off, hold, waypoints, land),
  raising on trouble, for a caller that handles the ending itself (a scenario watches on).
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
from bfsitl.mission.loop import DEFAULT_RATE_HZ, FlightLoop
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan import MissionPlan, Waypoint
from bfsitl.mission.results import MissionResult, Outcome
from bfsitl.mission.stick_pilot import StickPilot
from bfsitl.mission.vehicle import Vehicle
from bfsitl.stop_signals import how_stopped

#: The take-off's step response is judged over this much hold after it (metrics.py).
STEP_STEADY_WINDOW_S = 5.0


def fly_steps(
    loop: FlightLoop,
    plan: MissionPlan,
    *,
    arm: bool = True,
    time_left_s: Callable[[], float] | None = None,
    after_step: Callable[[Phase], None] | None = None,
    pilot: StickPilot | None = None,
) -> None:
    """Arm, take off, hold, fly the waypoints, land: ``plan`` on ``loop``, raising on
    trouble (:func:`fly_plan` turns that into an outcome).

    ``pilot`` (a trained policy) flies the hold instead of the autopilot
    (:meth:`~bfsitl.mission.loop.FlightLoop.fly_sticks`).
    ``arm=False`` when the caller has armed already; ``time_left_s`` (what the caller's run
    has left) cuts the hold short so that it does not outlast the run; ``after_step`` is
    told each step that ended (TAKEOFF, HOLD, GOTO for each waypoint, LANDED).  Once the
    loop's stop condition has ended the flying, the rest of the plan is not flown.
    """
    done = after_step or (lambda _step: None)
    if arm:
        loop.arm()
    if plan.ground_s > 0:
        loop.wait_on_ground(plan.ground_s)
    position = plan.needs_position or (plan.hold_position and loop.vehicle.has_gps)
    loop.takeoff(plan.target_alt_m, timeout_s=plan.takeoff_timeout_s, hold_position=position)
    if loop.stopped:
        return
    done(Phase.TAKEOFF)
    hold_s = plan.hold_s if time_left_s is None else min(plan.hold_s, max(0.0, time_left_s()))
    if hold_s > 0:
        if pilot is not None:
            loop.fly_sticks(hold_s, pilot)
        elif position:
            loop.hold_position(hold_s)
        else:
            loop.hold(hold_s)
        if loop.stopped:
            return
        done(Phase.HOLD)
    for number, waypoint in enumerate(plan.waypoints, start=1):
        fly_waypoint(loop, waypoint, number, plan.speed_m_s)
        if loop.stopped:
            return
        done(Phase.GOTO)
    if plan.land:
        loop.land(timeout_s=plan.land_timeout_s)
        if loop.stopped:
            return
        done(Phase.LANDED)


def fly_waypoint(loop: FlightLoop, waypoint: Waypoint, number: int, speed_m_s: float) -> None:
    """The leg to ``waypoint``, the turn to its heading, its hold."""
    loop.fly_to(
        waypoint.north_m, waypoint.east_m, waypoint.alt_m, speed_m_s=speed_m_s, waypoint=number
    )
    if waypoint.heading_deg is not None:
        loop.yaw_to(waypoint.heading_deg)
    if waypoint.hold_s > 0:
        loop.hold_position(waypoint.hold_s, waypoint=number)


def fly(
    vehicle: Vehicle,
    plan: MissionPlan,
    controller: AltitudeController,
    *,
    landing: AltitudeController | None = None,
    log: RowWriter | None = None,
    on_row: RowCallback | None = None,
    on_event: EventCallback | None = None,
    rate_hz: float = DEFAULT_RATE_HZ,
    pilot: StickPilot | None = None,
) -> MissionResult:
    """Fly ``plan`` on a started vehicle; every ending becomes an :class:`Outcome`.

    Ctrl-C becomes :attr:`Outcome.INTERRUPTED` (the sticks go to disarm at once and a last
    row records them); the caller still closes the vehicle.

    Args:
        vehicle: A started vehicle (a :class:`~bfsitl.mission.session.FlightSession` or a
            :class:`~bfsitl.mission.board.BoardVehicle`).
        plan: What to fly.
        controller: The altitude controller that flies it
            (:func:`~bfsitl.control.make_controller` makes one by name).
        landing: The controller of the landing; None is the usual one.
        log: Where each row is written as it is recorded; None writes none.
        on_row: Called with each row and the sample it was made from.
        on_event: Called with each line of progress.
        rate_hz: Control steps per second of simulation time (wall time on a board), 1 to
            200.
        pilot: Flies the hold instead of the autopilot (a trained policy; its rate must be
            ``rate_hz``).

    Returns:
        How it ended and its figures; a failed flight is an outcome, not an exception.

    Raises:
        MissionError: ``rate_hz`` is outside 1 to 200 (nothing has flown then).
    """
    loop = FlightLoop(
        vehicle,
        controller,
        landing=landing,
        rate_hz=rate_hz,
        log=log,
        on_row=on_row,
        on_event=on_event,
    )
    return fly_plan(loop, plan, pilot=pilot)


def fly_plan(
    loop: FlightLoop,
    plan: MissionPlan,
    *,
    keep_flying: bool = False,
    pilot: StickPilot | None = None,
) -> MissionResult:
    """Fly ``plan`` from the ground on ``loop`` (a new one, or one that has flown and
    landed before: the :class:`~bfsitl.autopilot.Autopilot` flies on its own); every ending
    becomes an :class:`Outcome`, and the result covers the rows and legs of this plan only.

    A plan that does not land (``land = false``) ends with the sticks at disarm, as every
    other ending but a landing does, unless ``keep_flying``: then the loop is still
    flying it, and its next manoeuvre (``land()``) goes on from there.  ``pilot`` flies the
    hold (see :func:`fly_steps`)."""
    vehicle = loop.vehicle
    first_row, first_leg = len(loop.rows), len(loop.legs)
    controller = loop.controller
    name = getattr(controller, "name", type(controller).__name__)
    outcome, reason = Outcome.LANDED, "landed and disarmed"
    blockers: tuple[str, ...] = ()
    try:
        if plan.needs_position and not vehicle.has_gps:
            raise MissionError(
                "this mission has waypoints, flown from the FC's GPS, and this firmware has "
                "no GPS: fly a GPS build (`bfsitl firmware build --gps`, add --lockstep for "
                "lockstep; master always has it)"
            )
        fly_steps(loop, plan, pilot=pilot)
        if not plan.land:
            outcome, reason = Outcome.COMPLETED, "mission completed in the air (land = false)"
    except KeyboardInterrupt as exc:
        outcome, reason = Outcome.INTERRUPTED, f"interrupted ({how_stopped(exc)})"
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
            loop.abort(outcome)
        except (BfsitlError, OSError):
            pass  # the vehicle's close still sends disarm through the RC link
    if outcome is Outcome.ERROR and vehicle.has_exited():
        outcome = Outcome.SITL_EXITED
    rows = loop.rows[first_row:]
    result = MissionResult(
        outcome,
        reason.splitlines()[0] if reason else "",
        name,
        plan,
        rows,
        blockers,
        vehicle.armed_after_s,
    )
    result.hold = hold_stats(rows)
    result.legs = list(loop.legs[first_leg:])
    result.attitude = attitude_tracking(rows)
    profile = vehicle.firmware
    if profile is not None:
        result.extra["firmware"] = {
            "version": profile.firmware_version,
            "api": profile.api_version,
            "conventions": profile.generation.value,
            "gps": profile.has_gps,
        }
    if pilot is None and (not plan.waypoints or plan.hold_s >= STEP_STEADY_WINDOW_S):
        # A step response needs the autopilot's hold after it: straight into a leg, or with
        # a pilot flying the hold, there is none.
        result.metrics = takeoff_metrics(rows, plan.target_alt_m)
    rc_stats, bridge_stats = vehicle.rc_stats(), vehicle.bridge_stats()
    if rc_stats is not None:
        result.extra["rc_link"] = rc_stats
    if bridge_stats is not None:
        result.extra["physics"] = {
            "answered_ratio": bridge_stats.answered_ratio,
            "speed": bridge_stats.speed,
            "steps": bridge_stats.steps,
            "lockstep": vehicle.lockstep,
            "exchange": vehicle.backend.exchange,
        }
    return result
