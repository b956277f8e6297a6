"""Missions: arm, take off, hold, go to an altitude, land, each a closed loop over a session.

A :class:`Mission` is the scriptable form (one method per manoeuvre, raising on trouble);
:func:`run_mission` flies the default plan and turns every way a flight can end into an
:class:`Outcome` with a reason, so callers get data, not exceptions.

The loop (``rate_hz`` in simulation time): sample the FC and the truth, estimate the climb
rate from the FC's altitude, ask the controller for a throttle, send it, record a row.  The
controllers see only what a real board would report (FC altitude, not the simulated truth);
the truth is recorded next to it to judge them.
"""

from __future__ import annotations

import enum
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

from bfsitl.control.angle_sticks import AngleStickMap
from bfsitl.control.base import (
    THROTTLE_MIN_US,
    AltitudeController,
    AltitudeInput,
    DetectsTouchdown,
    EstimatesAltitude,
    KnowsHover,
    ObservesGround,
    TakesHoverEstimate,
)
from bfsitl.control.heading import HeadingController, heading_error_deg
from bfsitl.control.horizontal_estimator import (
    HorizontalEstimator,
    specific_force_north_east,
)
from bfsitl.control.position import PositionController, PositionGains, PositionInput
from bfsitl.errors import (
    ArmingBlockedError,
    BfsitlError,
    CrashDetectedError,
    MissionError,
    MissionTimeoutError,
    MspErrorReply,
    SitlExitedError,
)
from bfsitl.fc.rc_link import RC_MID_US, RC_MIN_US
from bfsitl.mission.climb_rate import ClimbRateEstimator
from bfsitl.mission.flight_log import CsvFlightLog, FlightRow
from bfsitl.mission.legs import LegPoint, LegReference, LegStats, leg_stats
from bfsitl.mission.phase import FLOWN, Phase
from bfsitl.mission.plan import MissionPlan, Waypoint
from bfsitl.mission.vehicle import (
    SWITCH_OFF_US,
    SWITCH_ON_US,
    FlightSample,
    GpsPosition,
    SessionClock,
    Vehicle,
)
from bfsitl.protocol import msp_messages as msg

DEFAULT_RATE_HZ = 50.0
#: "Reached" means within this band of the target, nearly still, for REACHED_HOLD_S.
REACHED_BAND_M = 0.05
REACHED_CLIMB_M_S = 0.10
REACHED_HOLD_S = 0.5
#: After this long trying, "reached" takes twice the band and the climb rate: in gusts the
#: height wanders by more than 5 cm, and a take-off that is there must not time out for it.
REACHED_PATIENCE_S = 8.0
#: The take-off's step response is judged over this much hold after it (metrics.py).
STEP_STEADY_WINDOW_S = 5.0
#: Tilt beyond which the vehicle is taken as crashed (ANGLE mode limits it to about 55 deg).
CRASH_TILT_DEG = 70.0
#: Hitting the ground faster than this is a crash, not a landing.
CRASH_TOUCHDOWN_M_S = 2.5


class Outcome(enum.Enum):
    LANDED = "landed"
    COMPLETED = "completed"       # a plan with land = false: ended in the air
    ARMING_BLOCKED = "arming-blocked"
    SITL_EXITED = "sitl-exited"
    TIMEOUT = "timeout"
    CRASHED = "crashed"
    INTERRUPTED = "interrupted"
    ERROR = "error"

    @property
    def succeeded(self) -> bool:
        return self in (Outcome.LANDED, Outcome.COMPLETED)


@dataclass(frozen=True, slots=True)
class HoldStats:
    """Simulated truth against the target while holding."""

    rms_error_m: float
    max_abs_error_m: float
    mean_error_m: float
    samples: int


@dataclass
class MissionResult:
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
            if self.rows else None,
            **plain(self.extra),
        }


RowCallback = Callable[[FlightRow, FlightSample], None]
#: Time since the manoeuvre began -> where the position and altitude targets are.
PositionTarget = Callable[[float], LegPoint]
EventCallback = Callable[[str], None]


class Mission:
    """Closed-loop manoeuvres on a started vehicle: a simulated :class:`FlightSession` or a
    board (:class:`~bfsitl.mission.board.BoardVehicle`).

    >>> mission = Mission(session, CascadedAltitudeController())   # doctest: +SKIP
    >>> mission.arm(); mission.takeoff(2.0); mission.hold(10); mission.land()
    """

    def __init__(
        self,
        session: Vehicle,
        controller: AltitudeController,
        *,
        landing: AltitudeController | None = None,
        rate_hz: float = DEFAULT_RATE_HZ,
        log: CsvFlightLog | None = None,
        on_row: RowCallback | None = None,
        on_event: EventCallback | None = None,
    ) -> None:
        if not 1.0 <= rate_hz <= 200.0:
            raise MissionError(f"control rate {rate_hz} Hz is outside 1..200 Hz")
        self.session = session
        self.controller = controller
        if landing is None:
            from bfsitl.control.landing import LandingController

            landing = LandingController()
        self.landing = landing
        self.rate_hz = rate_hz
        self.log = log
        self.rows: list[FlightRow] = []
        self.target_alt_m = 0.0
        self.phase = Phase.ARMING
        self.last_sample: FlightSample | None = None
        self._on_row = on_row
        self._on_event = on_event or (lambda _message: None)
        self._climb = ClimbRateEstimator()
        self._started_wall_s = time.monotonic()
        self.position = PositionController(PositionGains.for_loop_rate(rate_hz))
        #: Fuses the FC's accelerometer with its GPS for the position loop (None: the GPS
        #: alone, extrapolated by the gains' lead).
        self.horizontal: HorizontalEstimator | None = None
        #: The FC's ANGLE-mode stick curve, read from it at the first position manoeuvre.
        self.sticks: AngleStickMap | None = None
        #: The FC's GPS and the target of the step being recorded (position control only).
        self._position_columns: dict[str, float] = {}
        self.last_gps: GpsPosition | None = None
        self.heading = HeadingController()
        #: The heading held during position control and turned to by :meth:`yaw_to`.
        self.target_heading_deg: float | None = None
        #: The last position target (north, east): where the next leg starts.
        self._target_ne: tuple[float, float] | None = None
        #: One entry per leg flown by :meth:`fly_to`.
        self.legs: list[LegStats] = []
        self._waypoint = 0  # the waypoint being flown to or held (a log column)

    # -- manoeuvres ------------------------------------------------------------------------
    def arm(self) -> None:
        self.phase = Phase.ARMING
        self._on_event("arming: waiting for the FC's blockers to clear")
        self.session.arm()
        self._climb.reset()
        self.position.reset(self.session.time_s)  # nothing learnt of the wind yet
        if self.horizontal is not None:
            self.horizontal.started = False
        self.controller.reset(self.session.time_s)
        self._on_event(f"armed {self.session.armed_after_s:.1f} s after start")

    def wait_on_ground(self, seconds: float) -> None:
        """Stay armed at idle for ``seconds``: the FC's altitude filter, which restarts from
        zero at arming, settles, and a controller with ``observe_ground`` (the fused one) learns
        the barometer's zero error from the vehicle at rest, where the truth is known."""
        self._on_event(f"on the ground for {seconds:g} s (the barometer settles)")
        end_s = self.session.time_s + seconds
        self._fly(Phase.GROUND, 0.0, lambda s: s.time_s >= end_s, timeout_s=seconds + 5,
                  controller=_GroundObserver(self.controller))
        if not isinstance(self.controller, ObservesGround):
            # It saw nothing of the wait: start its clock now, as if it had just been armed
            # (a PID would otherwise integrate the whole wait in its first step).
            self.controller.reset(self.session.time_s)

    def takeoff(self, altitude_m: float, *, timeout_s: float = 20.0,
                hold_position: bool = False) -> float:
        """Climb to ``altitude_m`` above the take-off point; returns the sim time it took.

        ``hold_position`` (GPS builds) holds the take-off point on the way up: without it,
        wind carries the vehicle off while it climbs."""
        self._on_event(f"take-off to {altitude_m:.2f} m"
                       + (", holding the take-off point" if hold_position else ""))
        if not hold_position:
            return self._reach(Phase.TAKEOFF, altitude_m, timeout_s)
        here = self._position_target(0.0, 0.0)
        self._target_ne = here
        steer = self._position_steer(self._fixed(here, alt_m=altitude_m), 0)
        self.position.resume(self.session.time_s)
        try:
            return self._reach(Phase.TAKEOFF, altitude_m, timeout_s, steer=steer)
        finally:
            self._end_position_control()

    def goto(self, altitude_m: float, *, timeout_s: float = 20.0) -> float:
        self._on_event(f"go to {altitude_m:.2f} m")
        return self._reach(Phase.GOTO, altitude_m, timeout_s)

    def hold(self, seconds: float, *, roll_us: float = RC_MID_US, pitch_us: float = RC_MID_US,
             yaw_us: float = RC_MID_US) -> None:
        """Hold the altitude for ``seconds`` of simulation time.

        Off-centre ``roll_us`` / ``pitch_us`` / ``yaw_us`` are held for the whole time (a stick
        step: in ANGLE mode roll and pitch set an angle, yaw a rate) and centred again at the
        end; the altitude controller keeps working throughout.
        """
        sticks = (roll_us, pitch_us, yaw_us)
        stepped = any(value != RC_MID_US for value in sticks)
        what = (f" with sticks roll {roll_us:.0f}, pitch {pitch_us:.0f}, yaw {yaw_us:.0f} us"
                if stepped else "")
        self._on_event(f"hold {self.target_alt_m:.2f} m for {seconds:g} s{what}")
        end_s = self.session.time_s + seconds
        self.session.set_rc(replace(self.session.rc_command, roll_us=roll_us,
                                    pitch_us=pitch_us, yaw_us=yaw_us))
        try:
            self._fly(Phase.HOLD, self.target_alt_m, lambda s: s.time_s >= end_s,
                      timeout_s=seconds + 5)
        finally:
            if stepped:
                self.session.set_rc(replace(self.session.rc_command, roll_us=RC_MID_US,
                                            pitch_us=RC_MID_US, yaw_us=RC_MID_US))

    # -- position and heading ----------------------------------------------------------------
    def hold_position(self, seconds: float, north_m: float | None = None,
                      east_m: float | None = None, *, waypoint: int = 0) -> None:
        """Hold the altitude and a position (metres from the take-off point; default: the
        last position target, else where the FC's GPS is now) for ``seconds``, steering
        through ANGLE mode and holding the heading."""
        target = self._position_target(north_m, east_m)
        self._on_event(f"hold {target[0]:+.1f} m N {target[1]:+.1f} m E, "
                       f"{self.target_alt_m:.2f} m up, for {seconds:g} s")
        end_s = self.session.time_s + seconds
        self._fly_position(Phase.HOLD, self._fixed(target), lambda s: s.time_s >= end_s,
                           seconds + 5, waypoint=waypoint)

    def fly_to(self, north_m: float, east_m: float, alt_m: float | None = None, *,
               speed_m_s: float | None = None, tolerance_m: float = 0.15,
               timeout_s: float | None = None, waypoint: int = 0) -> float:
        """Fly a straight leg to a position (metres from the take-off point) and altitude
        (default: the one held), at ``speed_m_s`` (default: the position gains' top speed).

        The leg starts at the last position target (where the previous leg ended) or, before
        any, where the FC's GPS is.  It is reached once the travelling reference has stopped
        at the end and the FC's GPS puts the vehicle within ``tolerance_m`` of it, slower than
        0.3 m/s (tight, because the GPS's own error adds to it).  Returns the simulation time
        it took; the leg's figures (arrival error and cross-track, from the truth) are
        appended to :attr:`legs`.
        """
        start = self._position_target(None, None)
        start_alt_m = self.target_alt_m
        end = (north_m, east_m, start_alt_m if alt_m is None else alt_m)
        speed = self.position.gains.max_speed_m_s if speed_m_s is None else speed_m_s
        reference = LegReference((start[0], start[1], start_alt_m), end, speed)
        if timeout_s is None:
            timeout_s = 20.0 + 3.0 * reference.duration_s
        label = f"waypoint {waypoint}: " if waypoint else ""
        self._on_event(f"{label}fly to {north_m:+.1f} m N {east_m:+.1f} m E, {end[2]:.2f} m "
                       f"up ({reference.length_m:.1f} m at {speed:g} m/s)")
        started_s = self.session.time_s
        first_row = len(self.rows)
        finished = [False]

        def target(elapsed_s: float) -> LegPoint:
            point = reference.at(elapsed_s)
            finished[0] = point.finished
            return point

        def arrived(_sample: FlightSample) -> bool:
            gps = self.last_gps
            return finished[0] and gps is not None and math.hypot(
                gps.north_m - north_m, gps.east_m - east_m) <= tolerance_m \
                and math.hypot(gps.v_north_m_s, gps.v_east_m_s) < 0.3

        self._fly_position(Phase.GOTO, target, arrived, timeout_s, waypoint=waypoint)
        self._target_ne = (north_m, east_m)
        took_s = self.session.time_s - started_s
        self.legs.append(leg_stats(waypoint or len(self.legs) + 1, start, end,
                                   [_judged_position(r) for r in self.rows[first_row:]], took_s))
        return took_s

    def yaw_to(self, heading_deg: float, *, tolerance_deg: float = 2.0,
               timeout_s: float = 30.0) -> float:
        """Turn to ``heading_deg`` (clockwise from north), holding the altitude, and the
        position on a GPS build; reached when the FC's heading stays within ``tolerance_deg``
        for half a second.  Returns the simulation time it took."""
        target_deg = heading_deg % 360.0
        self._on_event(f"turn to heading {target_deg:.0f} deg")
        self.target_heading_deg = target_deg
        started_s = self.session.time_s
        within_since: list[float] = []

        def turned(sample: FlightSample) -> bool:
            if abs(heading_error_deg(target_deg, sample.yaw_deg)) > tolerance_deg:
                within_since.clear()
                return False
            if not within_since:
                within_since.append(sample.time_s)
            return sample.time_s - within_since[0] >= REACHED_HOLD_S

        if self.session.has_gps:
            here = self._position_target(None, None)
            self._fly_position(Phase.YAW, self._fixed(here), turned, timeout_s)
        else:
            self._fly(Phase.YAW, self.target_alt_m, turned, timeout_s=timeout_s,
                      steer=self._steer_heading)
            self._set_sticks(yaw_us=RC_MID_US)
        return self.session.time_s - started_s

    def _fixed(self, north_east: tuple[float, float], *, alt_m: float | None = None
               ) -> PositionTarget:
        """A position target that stays put, at ``alt_m`` (default: the altitude held)."""
        point = LegPoint(north_east[0], north_east[1],
                         self.target_alt_m if alt_m is None else alt_m, 0.0, 0.0, 0.0, 0.0, True)
        return lambda _elapsed_s: point

    def _position_target(self, north_m: float | None, east_m: float | None
                         ) -> tuple[float, float]:
        """The given coordinates, else the last target, else where the FC's GPS is now."""
        if self._target_ne is None:
            gps = self._gps()
            self._target_ne = (gps.north_m, gps.east_m)
        return (self._target_ne[0] if north_m is None else north_m,
                self._target_ne[1] if east_m is None else east_m)

    def _gps(self) -> GpsPosition:
        try:
            gps = self.session.gps_position()
        except MspErrorReply as exc:
            raise MissionError(
                "position control needs the FC's GPS, and this firmware has none (it refused "
                "MSP_RAW_GPS): fly a GPS build (`bfsitl firmware build --gps`, add --lockstep "
                "for lockstep; master always has it)") from exc
        if not gps.has_fix:
            raise MissionError(f"the FC's GPS has no fix ({gps.satellites} satellites): "
                               f"position control needs one")
        self.last_gps = gps
        return gps

    def _stick_map(self) -> AngleStickMap:
        if self.sticks is None:
            client = self.session.client
            self.sticks = AngleStickMap.from_replies(client.get(msg.RcTuning),
                                                     client.get(msg.PidAdvanced))
        return self.sticks

    def _set_sticks(self, *, roll_us: float | None = None, pitch_us: float | None = None,
                    yaw_us: float | None = None) -> None:
        rc = self.session.rc_command
        self.session.set_rc(replace(
            rc, roll_us=rc.roll_us if roll_us is None else roll_us,
            pitch_us=rc.pitch_us if pitch_us is None else pitch_us,
            yaw_us=rc.yaw_us if yaw_us is None else yaw_us))

    def _steer_heading(self, sample: FlightSample) -> None:
        """Yaw towards :attr:`target_heading_deg` (set to the heading now if there is none)."""
        if self.target_heading_deg is None:
            self.target_heading_deg = sample.yaw_deg % 360.0
        rate = self.heading.rate_deg_s(sample.yaw_deg, self.target_heading_deg)
        self._set_sticks(yaw_us=self._stick_map().yaw_stick_us(rate))
        self._position_columns["target_heading_deg"] = self.target_heading_deg

    def _fly_position(self, phase: Phase, target: PositionTarget,
                      done: Callable[[FlightSample], bool], timeout_s: float, *,
                      waypoint: int = 0, controller: AltitudeController | None = None) -> None:
        steer = self._position_steer(target, waypoint)
        self.position.resume(self.session.time_s)
        try:
            self._fly(phase, target(0.0).alt_m, done, timeout_s=timeout_s, steer=steer,
                      controller=controller)
        finally:
            self._end_position_control()

    def _position_steer(self, target: PositionTarget, waypoint: int
                        ) -> Callable[[FlightSample], float | None]:
        """One step of position and heading control towards ``target``: sets the roll,
        pitch and yaw sticks, returns the altitude target."""
        sticks = self._stick_map()
        started_s = self.session.time_s

        def steer(sample: FlightSample) -> float | None:
            gps = self._gps()
            point = target(sample.time_s - started_s)
            north, east = point.north_m, point.east_m
            here = (gps.north_m, gps.east_m, gps.v_north_m_s, gps.v_east_m_s)
            if self.horizontal is not None and all(map(math.isfinite,
                                                       sample.fc_accel_flu_m_s2)):
                a_north, a_east = specific_force_north_east(
                    sample.fc_accel_flu_m_s2, sample.roll_deg, sample.pitch_deg,
                    sample.yaw_deg)
                fused = self.horizontal.update(sample.time_s, a_north, a_east, here)
                here = (fused.north_m, fused.east_m, fused.v_north_m_s, fused.v_east_m_s)
            tilt = self.position.update(PositionInput(
                sample.time_s, *here, sample.yaw_deg, north, east, point.v_north_m_s,
                point.v_east_m_s, point.a_north_m_s2, point.a_east_m_s2))
            self._set_sticks(roll_us=sticks.stick_us("roll", tilt.roll_deg),
                             pitch_us=sticks.stick_us("pitch", tilt.pitch_deg))
            self._position_columns = {
                "fc_north_m": gps.north_m, "fc_east_m": gps.east_m,
                "target_north_m": north, "target_east_m": east}
            self._waypoint = waypoint
            self._steer_heading(sample)
            return point.alt_m

        return steer

    def _end_position_control(self) -> None:
        self._position_columns, self._waypoint = {}, 0
        self._set_sticks(roll_us=RC_MID_US, pitch_us=RC_MID_US, yaw_us=RC_MID_US)

    def hand_over(self, seconds: float, *, switches: tuple[int, ...], throttle_us: float,
                  phase: Phase = Phase.FC_MODE) -> None:
        """Give the flight to the firmware's own modes for ``seconds``: the AUX channels
        ``switches`` (0-based: 2 is AUX3) on, roll, pitch and yaw centred, the throttle held
        at ``throttle_us`` (ALTHOLD reads it as a climb-rate stick around its hover value).
        Rows are recorded as usual; the switches go off again at the end.  For comparing
        bfsitl's control with the firmware's ALTHOLD / POSHOLD on the same vehicle."""
        self._on_event(f"handing over to the FC's modes (AUX "
                       f"{', '.join(str(i + 1) for i in switches)}) for {seconds:g} s")
        self._set_sticks(roll_us=RC_MID_US, pitch_us=RC_MID_US, yaw_us=RC_MID_US)
        command = self.session.rc_command
        for index in switches:
            command = command.with_aux(index, SWITCH_ON_US)
        self.session.set_rc(command)
        end_s = self.session.time_s + seconds
        try:
            self._fly(phase, self.target_alt_m, lambda s: s.time_s >= end_s,
                      timeout_s=seconds + 5, controller=_FixedThrottle(throttle_us))
        finally:
            command = self.session.rc_command
            for index in switches:
                command = command.with_aux(index, SWITCH_OFF_US)
            self.session.set_rc(command)

    def observe(self, done: Callable[[FlightSample], bool], *, timeout_s: float,
                phase: Phase = Phase.OBSERVE) -> None:
        """Record rows without flying: the sticks stay as they are, because something else
        has the vehicle (an injected RC fault, the FC's failsafe).  Nothing is judged here (a
        disarm or a crash is what a scenario watches for); ends when ``done`` says so or
        after ``timeout_s`` of simulation time."""
        self.phase = phase
        clock = self.session.clock
        period_s = 1.0 / self.rate_hz
        deadline_s = self.session.time_s + timeout_s
        next_s = clock.now_s()
        while True:
            sample = self.session.sample()
            climb_m_s = self._climb.update(sample.time_s, sample.fc_alt_m)
            self._record(phase, self.target_alt_m, sample, climb_m_s)
            if done(sample) or sample.time_s >= deadline_s:
                return
            next_s = _next_step(clock, next_s, period_s)

    def land(self, *, timeout_s: float = 30.0) -> None:
        """Descend, touch down, cut the throttle, disarm."""
        self._on_event("landing")
        landing = self.landing
        if not isinstance(landing, DetectsTouchdown):
            raise MissionError("the landing controller has no touched_down property "
                               "(bfsitl.control.base.DetectsTouchdown)")
        # Start the descent from the flying controller's hover estimate, not a guess.
        if isinstance(self.controller, KnowsHover) and isinstance(landing, TakesHoverEstimate):
            landing.set_hover_estimate(self.controller.hover_throttle_us)
        landing.reset(self.session.time_s)

        def touched_down(_sample: FlightSample) -> bool:
            return bool(landing.touched_down)

        if self._target_ne is not None:
            # After position control the descent holds the position too: wind would
            # otherwise carry the vehicle off while it sinks.
            self._fly_position(Phase.LAND, self._fixed(self._target_ne, alt_m=0.0), touched_down,
                               timeout_s, controller=self.landing)
        else:
            self._fly(Phase.LAND, 0.0, touched_down, timeout_s=timeout_s, controller=self.landing)
        self._on_event("touched down; disarming")
        self.phase = Phase.LANDED
        if not self.session.disarm():
            raise MissionError("the FC did not disarm after touch-down")
        sample = self.session.sample()
        self._record(Phase.LANDED, 0.0, sample, self._climb.update(sample.time_s, sample.fc_alt_m))
        self._on_event("disarmed")

    # -- the loop --------------------------------------------------------------------------
    def _reach(self, phase: Phase, altitude_m: float, timeout_s: float, *,
               steer: Callable[[FlightSample], float | None] | None = None) -> float:
        start_s = self.session.time_s
        settled_since: list[float] = []

        def reached(sample: FlightSample) -> bool:
            # The FC's reading, or the controller's own estimate when it keeps one (it knows
            # the FC's zero error, which on master can exceed the band).
            estimate = self.controller.altitude_estimate_m \
                if isinstance(self.controller, EstimatesAltitude) else None
            widen = 2.0 if sample.time_s - start_s >= REACHED_PATIENCE_S else 1.0
            band_m = REACHED_BAND_M * widen
            within = abs(sample.fc_alt_m - altitude_m) <= band_m or (
                estimate is not None and abs(estimate - altitude_m) <= band_m)
            near = within and \
                abs(self._climb.rate_m_s) <= REACHED_CLIMB_M_S * widen
            if not near:
                settled_since.clear()
                return False
            if not settled_since:
                settled_since.append(sample.time_s)
            return sample.time_s - settled_since[0] >= REACHED_HOLD_S

        self._fly(phase, altitude_m, reached, timeout_s=timeout_s, steer=steer)
        took_s = self.session.time_s - start_s
        self._on_event(f"reached {altitude_m:.2f} m after {took_s:.1f} s")
        return took_s

    def _fly(
        self, phase: Phase, target_alt_m: float, done: Callable[[FlightSample], bool], *,
        timeout_s: float, controller: AltitudeController | None = None,
        steer: Callable[[FlightSample], float | None] | None = None,
    ) -> None:
        controller = controller or self.controller
        self.phase, self.target_alt_m = phase, target_alt_m
        clock = self.session.clock
        period_s = 1.0 / self.rate_hz  # in simulation time, whatever the pace
        deadline_s = self.session.time_s + timeout_s
        next_s = clock.now_s()
        while True:
            sample = self.session.sample()
            climb_m_s = self._climb.update(sample.time_s, sample.fc_alt_m)
            self._check(sample)
            if steer is not None:
                moved_alt_m = steer(sample)  # sticks, and a moving altitude target on legs
                if moved_alt_m is not None:
                    target_alt_m = self.target_alt_m = moved_alt_m
            throttle_us = controller.update(
                AltitudeInput(sample.time_s, sample.fc_alt_m, climb_m_s, target_alt_m,
                              accel_up_m_s2=sample.fc_accel_up_m_s2))
            if not math.isfinite(throttle_us):
                raise MissionError(f"controller {getattr(controller, 'name', controller)} "
                                   f"returned throttle {throttle_us}")
            self.session.set_throttle(throttle_us)
            self._record(phase, target_alt_m, sample, climb_m_s)
            if done(sample):
                return
            if sample.time_s >= deadline_s:
                raise MissionTimeoutError(
                    f"{phase} did not finish within {timeout_s:.0f} s of simulation time "
                    f"(FC altitude {sample.fc_alt_m:.2f} m, target {target_alt_m:.2f} m)")
            next_s = _next_step(clock, next_s, period_s)

    def _check(self, sample: FlightSample) -> None:
        # The truth when the physics is ours; the FC's attitude otherwise (Gazebo).
        tilt_deg = sample.sim_tilt_deg if math.isfinite(sample.sim_tilt_deg) else \
            max(abs(sample.roll_deg), abs(sample.pitch_deg))
        if tilt_deg > CRASH_TILT_DEG:
            raise CrashDetectedError(f"the vehicle tipped over ({tilt_deg:.0f} deg "
                                     f"from level at t={sample.time_s:.1f} s)")
        if sample.on_ground and sample.sim_climb_m_s < -CRASH_TOUCHDOWN_M_S:
            raise CrashDetectedError(f"hit the ground at {-sample.sim_climb_m_s:.1f} m/s")
        if not sample.armed:
            names = ", ".join(sample.arming_blockers) or "no blocker reported"
            raise MissionError(f"the FC disarmed during {self.phase} ({names})")

    def _record(self, phase: str, target_alt_m: float, sample: FlightSample,
                climb_m_s: float) -> FlightRow:
        """One row of the log; ``phase`` is a :class:`Phase`, or an :class:`Outcome`'s value
        for the last row of a flight that did not land."""
        rc = self.session.rc_command  # what goes out from this step on
        aux = tuple(rc.aux_us) + (SWITCH_OFF_US, SWITCH_OFF_US)
        row = FlightRow(
            time_s=sample.time_s, phase=phase, target_alt_m=target_alt_m,
            sim_alt_m=sample.sim_alt_m, fc_alt_m=sample.fc_alt_m, climb_m_s=climb_m_s,
            sim_climb_m_s=sample.sim_climb_m_s, fc_accel_up_m_s2=sample.fc_accel_up_m_s2,
            roll_deg=sample.roll_deg, pitch_deg=sample.pitch_deg, yaw_deg=sample.yaw_deg,
            sim_tilt_deg=sample.sim_tilt_deg, sim_roll_deg=sample.sim_roll_deg,
            sim_pitch_deg=sample.sim_pitch_deg, sim_yaw_deg=sample.sim_yaw_deg,
            rc_roll_us=round(rc.roll_us), rc_pitch_us=round(rc.pitch_us),
            rc_throttle_us=round(rc.throttle_us), rc_yaw_us=round(rc.yaw_us),
            rc_aux1_us=round(aux[0]), rc_aux2_us=round(aux[1]),
            motor1=sample.motors[0], motor2=sample.motors[1], motor3=sample.motors[2],
            motor4=sample.motors[3], armed=sample.armed,
            wall_s=sample.wall_s - self._started_wall_s,
            sim_north_m=sample.sim_north_m, sim_east_m=sample.sim_east_m,
            waypoint=self._waypoint, **self._position_columns,
        )
        self.rows.append(row)
        self.last_sample = sample
        if self.log is not None:
            self.log.write(row)
        if self._on_row is not None:
            self._on_row(row, sample)
        return row

    def abort(self, ending: Outcome) -> None:
        """Sticks to disarm now (the RC link repeats it on close) and record the final row."""
        session = self.session
        if session.rc is None:
            return
        safe = replace(session.rc_command, throttle_us=RC_MIN_US,
                       aux_us=(SWITCH_OFF_US, SWITCH_OFF_US))
        session.set_rc(safe)
        if self.last_sample is not None:
            self._record(ending.value, self.target_alt_m, self.last_sample,
                         self._climb.rate_m_s)


def _next_step(clock: SessionClock, next_s: float, period_s: float) -> float:
    """Let simulation time pass to the next control step; its time.  A late step is taken at
    once and the schedule restarts from it: no burst of steps to catch up."""
    next_s += period_s
    delay_s = next_s - clock.now_s()
    if delay_s > 0:
        clock.sleep_s(delay_s)
        return next_s
    return clock.now_s()


@dataclass(frozen=True, slots=True)
class AttitudeTracking:
    """How well the FC's attitude followed the simulated truth while airborne (degrees)."""

    samples: int
    roll_rms_error_deg: float
    pitch_rms_error_deg: float
    max_abs_error_deg: float      # roll or pitch, whichever is worse
    max_true_tilt_deg: float


def attitude_tracking(rows: list[FlightRow]) -> AttitudeTracking | None:
    """FC roll/pitch vs the truth over the rows flown above the ground (None without truth).

    MSP_ATTITUDE comes from the same round trip as the rest of the sample and the truth is
    read right after it, so the comparison carries at most one exchange of delay.
    """
    flown = [r for r in rows if r.armed and r.phase in FLOWN
             and math.isfinite(r.sim_roll_deg) and r.sim_alt_m > 0.2]
    if not flown:
        return None
    roll = [r.roll_deg - r.sim_roll_deg for r in flown]
    pitch = [r.pitch_deg - r.sim_pitch_deg for r in flown]

    def rms(errors: list[float]) -> float:
        return math.sqrt(sum(e * e for e in errors) / len(errors))

    return AttitudeTracking(len(flown), rms(roll), rms(pitch),
                            max(max(map(abs, roll)), max(map(abs, pitch))),
                            max(r.sim_tilt_deg for r in flown))


def _judged_position(row: FlightRow) -> tuple[float, float, float]:
    """North, east, height: the truth, or the FC's view when the physics is external."""
    if math.isfinite(row.sim_north_m):
        return row.sim_north_m, row.sim_east_m, judged_alt_m(row)
    return row.fc_north_m, row.fc_east_m, judged_alt_m(row)


def cross_track_rms(legs: list[LegStats]) -> float | None:
    """The cross-track RMS over all legs, each step weighted alike."""
    samples = sum(leg.samples for leg in legs)
    if not samples:
        return None
    return math.sqrt(sum(leg.cross_track_rms_m ** 2 * leg.samples for leg in legs) / samples)


def landed_from_start_m(rows: list[FlightRow]) -> float | None:
    """How far from the take-off point (horizontally) the flight ended, if it landed."""
    if not rows or rows[-1].phase != Phase.LANDED:
        return None
    north, east, _alt = _judged_position(rows[-1])
    return math.hypot(north, east) if math.isfinite(north) else None


def judged_alt_m(row: FlightRow) -> float:
    """The simulated truth, or the FC's altitude when the physics is external (Gazebo)."""
    return row.sim_alt_m if math.isfinite(row.sim_alt_m) else row.fc_alt_m


def hold_stats(rows: list[FlightRow]) -> HoldStats | None:
    errors = [judged_alt_m(r) - r.target_alt_m for r in rows if r.phase == Phase.HOLD]
    if not errors:
        return None
    return HoldStats(
        rms_error_m=math.sqrt(sum(e * e for e in errors) / len(errors)),
        max_abs_error_m=max(abs(e) for e in errors),
        mean_error_m=sum(errors) / len(errors), samples=len(errors))


def takeoff_metrics(rows: list[FlightRow], target_alt_m: float) -> Any:
    """Step-response figures of the take-off and hold, from the simulated truth."""
    from bfsitl.control.metrics import step_response

    flown = []
    for row in rows:  # the take-off and the hold after it, up to whatever comes next
        if row.phase in (Phase.TAKEOFF, Phase.HOLD):
            flown.append(row)
        elif flown:
            break
    if len(flown) < 10:
        return None
    return step_response(
        [r.time_s for r in flown], [judged_alt_m(r) for r in flown], target_m=target_alt_m,
        start_m=0.0, roll_deg=[r.roll_deg for r in flown],
        pitch_deg=[r.pitch_deg for r in flown])


class _FixedThrottle:
    """One throttle, whatever the altitude: the stick a firmware mode reads."""

    def __init__(self, throttle_us: float) -> None:
        self.name = "fixed throttle"
        self.throttle_us = throttle_us

    def reset(self, time_s: float) -> None:
        pass

    def update(self, sample: AltitudeInput) -> float:
        return self.throttle_us


class _GroundObserver:
    """Idle throttle on the ground; the samples go to the controller's ``observe_ground``
    when it has one (an altitude controller's ``update`` would spool up or wind up)."""

    def __init__(self, controller: AltitudeController) -> None:
        self.name = getattr(controller, "name", "controller")
        self._observe = controller.observe_ground if isinstance(controller, ObservesGround) \
            else None

    def reset(self, time_s: float) -> None:
        pass

    def update(self, sample: AltitudeInput) -> float:
        if self._observe is not None:
            self._observe(sample)
        return THROTTLE_MIN_US


def fly_plan(mission: Mission, plan: MissionPlan) -> None:
    """Arm, take off, hold, fly the waypoints, land: ``plan`` on ``mission``, raising on
    trouble (:func:`run_mission` turns that into an outcome)."""
    mission.arm()
    if plan.ground_s > 0:
        mission.wait_on_ground(plan.ground_s)
    position = plan.needs_position or (plan.hold_position and mission.session.has_gps)
    mission.takeoff(plan.target_alt_m, timeout_s=plan.takeoff_timeout_s,
                    hold_position=position)
    if plan.hold_s > 0:
        if position:
            mission.hold_position(plan.hold_s)
        else:
            mission.hold(plan.hold_s)
    for number, waypoint in enumerate(plan.waypoints, start=1):
        fly_waypoint(mission, waypoint, number, plan.speed_m_s)
    if plan.land:
        mission.land(timeout_s=plan.land_timeout_s)


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
    log: CsvFlightLog | None = None,
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
    if outcome is not Outcome.LANDED:
        try:
            mission.abort(outcome)
        except (BfsitlError, OSError):
            pass  # the session's close still sends disarm through the RC link
    if outcome is Outcome.ERROR and session.has_exited():
        outcome = Outcome.SITL_EXITED
    result = MissionResult(outcome, reason.splitlines()[0] if reason else "", name, plan,
                           mission.rows, blockers, session.armed_after_s)
    result.hold = hold_stats(mission.rows)
    result.legs = list(mission.legs)
    result.attitude = attitude_tracking(mission.rows)
    profile = session.firmware
    if profile is not None:
        result.extra["firmware"] = {
            "version": profile.firmware_version, "api": profile.api_version,
            "conventions": profile.generation.value, "gps": profile.has_gps}
    if not plan.waypoints or plan.hold_s >= STEP_STEADY_WINDOW_S:
        # A step response needs the hold after it: straight into a leg, there is none.
        result.metrics = takeoff_metrics(mission.rows, plan.target_alt_m)
    rc_stats, bridge_stats = session.rc_stats(), session.bridge_stats()
    if rc_stats is not None:
        result.extra["rc_link"] = rc_stats
    if bridge_stats is not None:
        result.extra["physics"] = {
            "answered_ratio": bridge_stats.answered_ratio, "speed": bridge_stats.speed,
            "steps": bridge_stats.steps, "lockstep": session.lockstep}
    return result
