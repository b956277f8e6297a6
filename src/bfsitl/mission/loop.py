"""The flight loop: :class:`FlightLoop`, closed-loop manoeuvres over a started vehicle.

The loop (``rate_hz`` in simulation time): sample the FC and the truth, estimate the climb
rate from the FC's altitude, ask the controller for a throttle (and, in position control, the
position loop for the sticks), send it, record a row, call the hooks
(:class:`~bfsitl.mission.hooks.FlightHooks`).  The controllers see only what a real board
would report (FC altitude, not the simulated truth); the truth is recorded next to it to
judge them.  Manoeuvres raise on trouble (a crash, a disarm, a timeout);
:func:`~bfsitl.mission.plan_driver.fly` turns that into an outcome.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace

from bfsitl.backend.base import SessionClock
from bfsitl.control.base import (
    AltitudeController,
    AltitudeInput,
    DetectsTouchdown,
    EstimatesAltitude,
    KnowsHover,
    ObservesFlight,
    ObservesGround,
    TakesHoverEstimate,
)
from bfsitl.errors import MissionError, MissionTimeoutError
from bfsitl.fc.rc_link import RC_MID_US, RC_MIN_US
from bfsitl.mission.climb_rate import ClimbRateEstimator
from bfsitl.mission.crash_check import check_flying
from bfsitl.mission.flight_row import FlightRow, RowWriter
from bfsitl.mission.hooks import EventCallback, FlightHooks, RowCallback
from bfsitl.mission.legs import LegStats
from bfsitl.mission.phase import Phase
from bfsitl.mission.position_manoeuvres import PositionManoeuvres
from bfsitl.mission.position_steering import PositionSteering
from bfsitl.mission.results import Outcome
from bfsitl.mission.stick_pilot import StickPilot
from bfsitl.mission.throttle_sources import FixedThrottle, GroundObserver
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US, FlightSample, Vehicle

DEFAULT_RATE_HZ = 50.0
#: "Reached" means within this band of the target, nearly still, for REACHED_HOLD_S.
REACHED_BAND_M = 0.05
REACHED_CLIMB_M_S = 0.10
REACHED_HOLD_S = 0.5
#: After this long trying, "reached" takes twice the band and the climb rate: in gusts the
#: height wanders by more than 5 cm, and a take-off that is there must not time out for it.
REACHED_PATIENCE_S = 8.0


class FlightLoop(PositionManoeuvres):
    """Closed-loop manoeuvres on a started vehicle: a simulated :class:`FlightSession` or a
    board (:class:`~bfsitl.mission.board.BoardVehicle`).

    >>> loop = FlightLoop(vehicle, CascadedAltitudeController())   # doctest: +SKIP
    >>> loop.arm(); loop.takeoff(2.0); loop.hold(10); loop.land()

    Making one raises :class:`MissionError` for a rate outside 1 to 200 Hz.  Manoeuvres raise
    :class:`CrashDetectedError`, :class:`MissionTimeoutError`, :class:`SitlExitedError`, and
    :class:`MissionError` when the FC disarms (or, after a landing, does not).

    Args:
        vehicle: A started vehicle: a :class:`FlightSession` or a board's.
        controller: The altitude controller of every manoeuvre but the landing.
        landing: The landing's controller; None is the usual ``LandingController``.
        rate_hz: Control steps per second of the vehicle's clock, 1 to 200.
        log: Where each row is written as it is recorded; None writes none.
        on_row: Called with each row and its sample; short for ``hooks`` with ``on_step``.
        on_event: Called with each line of progress; short for ``hooks`` with ``on_event``.
        hooks: Every hook, the stop condition included; the two above fill its gaps.
    """

    def __init__(
        self,
        vehicle: Vehicle,
        controller: AltitudeController,
        *,
        landing: AltitudeController | None = None,
        rate_hz: float = DEFAULT_RATE_HZ,
        log: RowWriter | None = None,
        on_row: RowCallback | None = None,
        on_event: EventCallback | None = None,
        hooks: FlightHooks | None = None,
    ) -> None:
        if not 1.0 <= rate_hz <= 200.0:
            raise MissionError(f"control rate {rate_hz} Hz is outside 1..200 Hz")
        self.vehicle = vehicle
        self.controller = controller
        if landing is None:
            from bfsitl.control import make_landing

            landing = make_landing(vehicle.quad)
        self.landing = landing
        self.rate_hz = rate_hz
        self.log = log
        self.rows: list[FlightRow] = []
        hooks = hooks or FlightHooks()
        self.hooks = replace(
            hooks, on_step=hooks.on_step or on_row, on_event=hooks.on_event or on_event
        )
        self.target_alt_m = 0.0
        self._phase = Phase.ARMING
        #: Why the stop condition ended the flying (None while it flies on).
        self.stopped: str | None = None
        self.last_sample: FlightSample | None = None
        self._on_row = self.hooks.on_step
        self._on_event = self.hooks.on_event or (lambda _message: None)
        self._climb = ClimbRateEstimator()
        self._started_wall_s = time.monotonic()
        #: Position and heading control (GPS builds): the loop asks it for the sticks.
        self.steering = PositionSteering(vehicle, rate_hz)
        #: One entry per leg flown by :meth:`fly_to`.
        self.legs: list[LegStats] = []

    @property
    def phase(self) -> Phase:
        """What the flight is doing now."""
        return self._phase

    @phase.setter
    def phase(self, phase: Phase) -> None:
        if phase != self._phase and self.hooks.on_phase is not None:
            self.hooks.on_phase(phase)
        self._phase = phase

    # -- manoeuvres ------------------------------------------------------------------------
    def arm(self) -> None:
        self.phase = Phase.ARMING
        self._on_event("arming: waiting for the FC's blockers to clear")
        self.vehicle.arm()
        self._climb.reset()
        self.steering.reset(self.vehicle.time_s)
        self.controller.reset(self.vehicle.time_s)
        self._on_event(f"armed {self.vehicle.armed_after_s:.1f} s after start")

    def wait_on_ground(self, seconds: float) -> None:
        """Stay armed at idle for ``seconds``: the FC's altitude filter, which restarts from
        zero at arming, settles, and a controller with ``observe_ground`` (the fused one) learns
        the barometer's zero error from the vehicle at rest, where the truth is known.

        Args:
            seconds: Seconds of the vehicle's clock.
        """
        if self.stopped:
            return
        self._on_event(f"on the ground for {seconds:g} s (the barometer settles)")
        end_s = self.vehicle.time_s + seconds
        self._fly(
            Phase.GROUND,
            0.0,
            lambda s: s.time_s >= end_s,
            timeout_s=seconds + 5,
            controller=GroundObserver(self.controller),
        )
        if not isinstance(self.controller, ObservesGround):
            # It saw nothing of the wait: start its clock now, as if it had just been armed
            # (a PID would otherwise integrate the whole wait in its first step).
            self.controller.reset(self.vehicle.time_s)

    def takeoff(
        self, altitude_m: float, *, timeout_s: float = 20.0, hold_position: bool = False
    ) -> float:
        """Climb to ``altitude_m`` above the take-off point; returns the sim time it took.

        Args:
            altitude_m: Metres above the take-off point.
            timeout_s: Seconds of simulation time to reach the height and settle there.
            hold_position: (GPS builds) Hold the take-off point on the way up: without it,
                wind carries the vehicle off while it climbs.

        Returns:
            Seconds of simulation time the climb took.
        """
        if self.stopped:
            return 0.0
        self._on_event(
            f"take-off to {altitude_m:.2f} m"
            + (", holding the take-off point" if hold_position else "")
        )
        if not hold_position:
            return self._reach(Phase.TAKEOFF, altitude_m, timeout_s)
        here = self.steering.position_target(0.0, 0.0)
        self.steering.target_ne = here
        steer = self.steering.steer_to(self.steering.fixed(here, altitude_m), 0)
        try:
            return self._reach(Phase.TAKEOFF, altitude_m, timeout_s, steer=steer)
        finally:
            self.steering.end()

    def climb_to(self, altitude_m: float, *, timeout_s: float = 20.0) -> float:
        """Climb or descend to ``altitude_m`` where the vehicle is (an altitude step; a leg
        to a position is :meth:`fly_to`).  Logged as a :attr:`Phase.GOTO`, as before.

        Args:
            altitude_m: Metres above the take-off point.
            timeout_s: Seconds of simulation time to reach the height and settle there.

        Returns:
            Seconds of simulation time the step took.
        """
        if self.stopped:
            return 0.0
        self._on_event(f"go to {altitude_m:.2f} m")
        return self._reach(Phase.GOTO, altitude_m, timeout_s)

    def hold(
        self,
        seconds: float,
        *,
        roll_us: float = RC_MID_US,
        pitch_us: float = RC_MID_US,
        yaw_us: float = RC_MID_US,
    ) -> None:
        """Hold the altitude for ``seconds`` of simulation time.

        Off-centre ``roll_us`` / ``pitch_us`` / ``yaw_us`` are held for the whole time (a stick
        step: in ANGLE mode roll and pitch set an angle, yaw a rate) and centred again at the
        end; the altitude controller keeps working throughout.

        Args:
            seconds: Seconds of simulation time.
            roll_us: The roll stick, microseconds of pulse width (1500 is centred).
            pitch_us: The pitch stick, microseconds of pulse width (1500 is centred).
            yaw_us: The yaw stick, microseconds of pulse width (1500 is centred).
        """
        if self.stopped:
            return
        sticks = (roll_us, pitch_us, yaw_us)
        stepped = any(value != RC_MID_US for value in sticks)
        what = (
            f" with sticks roll {roll_us:.0f}, pitch {pitch_us:.0f}, yaw {yaw_us:.0f} us"
            if stepped
            else ""
        )
        self._on_event(f"hold {self.target_alt_m:.2f} m for {seconds:g} s{what}")
        end_s = self.vehicle.time_s + seconds
        self.vehicle.set_rc(
            replace(self.vehicle.rc_command, roll_us=roll_us, pitch_us=pitch_us, yaw_us=yaw_us)
        )
        try:
            self._fly(
                Phase.HOLD, self.target_alt_m, lambda s: s.time_s >= end_s, timeout_s=seconds + 5
            )
        finally:
            if stepped:
                self._centre_sticks()

    def hand_over(
        self,
        seconds: float,
        *,
        switches: tuple[int, ...],
        throttle_us: float,
        phase: Phase = Phase.FC_MODE,
    ) -> None:
        """Give the flight to the firmware's own modes for ``seconds``: the AUX channels
        ``switches`` (0-based: 2 is AUX3) on, roll, pitch and yaw centred, the throttle held
        at ``throttle_us`` (ALTHOLD reads it as a climb-rate stick around its hover value).
        Rows are recorded as usual; the switches go off again at the end.  For comparing
        bfsitl's control with the firmware's ALTHOLD / POSHOLD on the same vehicle.

        Args:
            seconds: Seconds of simulation time.
            switches: The AUX channels to switch on, 0-based (2 is AUX3).
            throttle_us: The throttle held meanwhile, microseconds of pulse width.
            phase: The phase the rows are recorded under.
        """
        if self.stopped:
            return
        self._on_event(
            f"handing over to the FC's modes (AUX "
            f"{', '.join(str(i + 1) for i in switches)}) for {seconds:g} s"
        )
        self.steering.set_sticks(roll_us=RC_MID_US, pitch_us=RC_MID_US, yaw_us=RC_MID_US)
        command = self.vehicle.rc_command
        for index in switches:
            command = command.with_aux(index, SWITCH_ON_US)
        self.vehicle.set_rc(command)
        end_s = self.vehicle.time_s + seconds
        try:
            self._fly(
                phase,
                self.target_alt_m,
                lambda s: s.time_s >= end_s,
                timeout_s=seconds + 5,
                controller=FixedThrottle(throttle_us),
            )
        finally:
            command = self.vehicle.rc_command
            for index in switches:
                command = command.with_aux(index, SWITCH_OFF_US)
            self.vehicle.set_rc(command)

    def fly_sticks(self, seconds: float, pilot: StickPilot, *, phase: Phase = Phase.POLICY) -> None:
        """Give every stick to ``pilot`` (:class:`~bfsitl.mission.stick_pilot.StickPilot`,
        a trained policy) for ``seconds``: each step its command goes out, and the loop
        samples, checks, records and calls the hooks as in every manoeuvre.  At the end roll,
        pitch and yaw are centred and the switches are as they were; the throttle stays
        where the pilot left it for the next manoeuvre to take over, which starts where the
        pilot left the vehicle (the altitude, and on a GPS build the position, it is at).

        Args:
            seconds: Seconds of the vehicle's clock.
            pilot: What turns each sample into the RC command.
            phase: The phase the rows are recorded under.

        Raises:
            MissionError: The pilot must be asked at another rate than the loop's.
        """
        if self.stopped:
            return
        if pilot.rate_hz is not None and not math.isclose(pilot.rate_hz, self.rate_hz):
            raise MissionError(
                f"the pilot flies at {pilot.rate_hz:g} Hz and this loop at {self.rate_hz:g} "
                f"Hz: make the loop at the pilot's rate (rate_hz={pilot.rate_hz:g})"
            )
        self._on_event(f"{getattr(pilot, 'name', 'the pilot')} has the sticks for {seconds:g} s")
        before = self.vehicle.rc_command
        target_alt_m = self.target_alt_m if pilot.target_alt_m is None else pilot.target_alt_m
        self.phase, self.target_alt_m = phase, target_alt_m
        clock = self.vehicle.clock
        period_s = 1.0 / self.rate_hz
        end_s = self.vehicle.time_s + seconds
        next_s = clock.now_s()
        try:
            while True:
                sample = self.vehicle.sample()
                climb_m_s = self._climb.update(sample.time_s, sample.fc_alt_m)
                check_flying(sample, self.phase)
                self.vehicle.set_rc(pilot.sticks(sample, self.vehicle.rc_command))
                if isinstance(self.controller, ObservesFlight):
                    self.controller.observe_flight(
                        _altitude_input(sample, climb_m_s, target_alt_m),
                        self.vehicle.rc_command.throttle_us,
                    )
                self._record(phase, target_alt_m, sample, climb_m_s)
                if self._stop_asked(sample) or sample.time_s >= end_s:
                    break
                next_s = next_step(clock, next_s, period_s)
        finally:
            self._centre_sticks(aux_us=before.aux_us)
        last = self.last_sample
        if last is not None:
            # What comes next holds here, not where the vehicle was before the pilot.
            self.target_alt_m = last.fc_alt_m
        if self.steering.target_ne is not None:
            self.steering.target_ne = None
            self.steering.position_target(None, None)

    def observe(
        self,
        done: Callable[[FlightSample], bool],
        *,
        timeout_s: float,
        phase: Phase = Phase.OBSERVE,
    ) -> None:
        """Record rows without flying: the sticks stay as they are, because something else
        has the vehicle (an injected RC fault, the FC's failsafe).  Nothing is judged here (a
        disarm or a crash is what a scenario watches for).

        Args:
            done: Asked with each sample; True ends the watch.
            timeout_s: Seconds of simulation time at most; reaching it is no error.
            phase: The phase the rows are recorded under.
        """
        self.phase = phase
        clock = self.vehicle.clock
        period_s = 1.0 / self.rate_hz
        deadline_s = self.vehicle.time_s + timeout_s
        next_s = clock.now_s()
        while True:
            sample = self.vehicle.sample()
            climb_m_s = self._climb.update(sample.time_s, sample.fc_alt_m)
            self._record(phase, self.target_alt_m, sample, climb_m_s)
            if done(sample) or sample.time_s >= deadline_s:
                return
            next_s = next_step(clock, next_s, period_s)

    def land(self, *, timeout_s: float = 30.0) -> None:
        """Descend, touch down, cut the throttle, disarm.

        Args:
            timeout_s: Seconds of simulation time to touch down.
        """
        if self.stopped:
            return
        self._on_event("landing")
        landing = self.landing
        if not isinstance(landing, DetectsTouchdown):
            raise MissionError(
                "the landing controller has no touched_down property "
                "(bfsitl.control.base.DetectsTouchdown)"
            )
        # Start the descent from the flying controller's hover estimate, not a guess.
        if isinstance(self.controller, KnowsHover) and isinstance(landing, TakesHoverEstimate):
            landing.set_hover_estimate(self.controller.hover_throttle_us)
        landing.reset(self.vehicle.time_s)

        def touched_down(_sample: FlightSample) -> bool:
            return bool(landing.touched_down)

        if self.steering.target_ne is not None:
            # After position control the descent holds the position too: wind would
            # otherwise carry the vehicle off while it sinks.
            self._fly_position(
                Phase.LAND,
                self.steering.fixed(self.steering.target_ne, 0.0),
                touched_down,
                timeout_s,
                controller=self.landing,
            )
        else:
            self._fly(Phase.LAND, 0.0, touched_down, timeout_s=timeout_s, controller=self.landing)
        if self.stopped:
            return  # the sticks are not ours to disarm with
        self._on_event("touched down; disarming")
        self.phase = Phase.LANDED
        if not self.vehicle.disarm():
            raise MissionError("the FC did not disarm after touch-down")
        sample = self.vehicle.sample()
        self._record(Phase.LANDED, 0.0, sample, self._climb.update(sample.time_s, sample.fc_alt_m))
        self._on_event("disarmed")

    # -- the loop --------------------------------------------------------------------------
    def _reach(
        self,
        phase: Phase,
        altitude_m: float,
        timeout_s: float,
        *,
        steer: Callable[[FlightSample], float | None] | None = None,
    ) -> float:
        start_s = self.vehicle.time_s
        settled_since: list[float] = []
        # Asked once: isinstance of a runtime protocol walks its members every time.
        estimator = self.controller if isinstance(self.controller, EstimatesAltitude) else None

        def reached(sample: FlightSample) -> bool:
            # The FC's reading, or the controller's own estimate when it keeps one (it knows
            # the FC's zero error, which on master can exceed the band).
            estimate = estimator.altitude_estimate_m if estimator is not None else None
            widen = 2.0 if sample.time_s - start_s >= REACHED_PATIENCE_S else 1.0
            band_m = REACHED_BAND_M * widen
            within = abs(sample.fc_alt_m - altitude_m) <= band_m or (
                estimate is not None and abs(estimate - altitude_m) <= band_m
            )
            near = within and abs(self._climb.rate_m_s) <= REACHED_CLIMB_M_S * widen
            if not near:
                settled_since.clear()
                return False
            if not settled_since:
                settled_since.append(sample.time_s)
            return sample.time_s - settled_since[0] >= REACHED_HOLD_S

        self._fly(phase, altitude_m, reached, timeout_s=timeout_s, steer=steer)
        took_s = self.vehicle.time_s - start_s
        if self.stopped:
            return took_s
        self._on_event(f"reached {altitude_m:.2f} m after {took_s:.1f} s")
        return took_s

    def _fly(
        self,
        phase: Phase,
        target_alt_m: float,
        done: Callable[[FlightSample], bool],
        *,
        timeout_s: float,
        controller: AltitudeController | None = None,
        steer: Callable[[FlightSample], float | None] | None = None,
    ) -> None:
        if self.stopped:
            return
        controller = controller or self.controller
        self.phase, self.target_alt_m = phase, target_alt_m
        clock = self.vehicle.clock
        period_s = 1.0 / self.rate_hz  # in simulation time, whatever the pace
        deadline_s = self.vehicle.time_s + timeout_s
        next_s = clock.now_s()
        while True:
            sample = self.vehicle.sample()
            climb_m_s = self._climb.update(sample.time_s, sample.fc_alt_m)
            check_flying(sample, self.phase)
            if steer is not None:
                moved_alt_m = steer(sample)  # sticks, and a moving altitude target on legs
                if moved_alt_m is not None:
                    target_alt_m = self.target_alt_m = moved_alt_m
            throttle_us = controller.update(_altitude_input(sample, climb_m_s, target_alt_m))
            if not math.isfinite(throttle_us):
                raise MissionError(
                    f"controller {getattr(controller, 'name', controller)} "
                    f"returned throttle {throttle_us}"
                )
            self.vehicle.set_throttle(throttle_us)
            self._record(phase, target_alt_m, sample, climb_m_s)
            if self._stop_asked(sample) or done(sample):
                return
            if sample.time_s >= deadline_s:
                raise MissionTimeoutError(
                    f"{phase} did not finish within {timeout_s:.0f} s of simulation time "
                    f"(FC altitude {sample.fc_alt_m:.2f} m, target {target_alt_m:.2f} m)"
                )
            next_s = next_step(clock, next_s, period_s)

    def _centre_sticks(self, *, aux_us: tuple[float, ...] | None = None) -> None:
        """Roll, pitch and yaw centred (and the switches ``aux_us``, when given); the
        throttle stays."""
        command = self.vehicle.rc_command
        self.vehicle.set_rc(
            replace(
                command,
                roll_us=RC_MID_US,
                pitch_us=RC_MID_US,
                yaw_us=RC_MID_US,
                aux_us=command.aux_us if aux_us is None else aux_us,
            )
        )

    def _stop_asked(self, sample: FlightSample) -> bool:
        """Whether the stop condition ends the flying here (the reason is kept)."""
        if self.hooks.stop is None:
            return False
        reason = self.hooks.stop(sample)
        if reason is None:
            return False
        self.stopped = reason
        self._on_event(f"stopped flying: {reason}")
        return True

    def _record(
        self, phase: str, target_alt_m: float, sample: FlightSample, climb_m_s: float
    ) -> FlightRow:
        """One row of the log; ``phase`` is a :class:`Phase`, or an :class:`Outcome`'s value
        for the last row of a flight that did not land."""
        rc = self.vehicle.rc_command  # what goes out from this step on
        aux = tuple(rc.aux_us) + (SWITCH_OFF_US, SWITCH_OFF_US)
        row = FlightRow(
            time_s=sample.time_s,
            phase=phase,
            target_alt_m=target_alt_m,
            sim_alt_m=sample.sim_alt_m,
            fc_alt_m=sample.fc_alt_m,
            climb_m_s=climb_m_s,
            sim_climb_m_s=sample.sim_climb_m_s,
            fc_accel_up_m_s2=sample.fc_accel_up_m_s2,
            roll_deg=sample.roll_deg,
            pitch_deg=sample.pitch_deg,
            yaw_deg=sample.yaw_deg,
            sim_tilt_deg=sample.sim_tilt_deg,
            sim_roll_deg=sample.sim_roll_deg,
            sim_pitch_deg=sample.sim_pitch_deg,
            sim_yaw_deg=sample.sim_yaw_deg,
            rc_roll_us=round(rc.roll_us),
            rc_pitch_us=round(rc.pitch_us),
            rc_throttle_us=round(rc.throttle_us),
            rc_yaw_us=round(rc.yaw_us),
            rc_aux1_us=round(aux[0]),
            rc_aux2_us=round(aux[1]),
            motor1=sample.motors[0],
            motor2=sample.motors[1],
            motor3=sample.motors[2],
            motor4=sample.motors[3],
            armed=sample.armed,
            wall_s=sample.wall_s - self._started_wall_s,
            sim_north_m=sample.sim_north_m,
            sim_east_m=sample.sim_east_m,
            waypoint=self.steering.waypoint,
            **self.steering.row_columns,
        )
        self.rows.append(row)
        self.last_sample = sample
        if self.log is not None:
            self.log.write(row, sample)
        if self._on_row is not None:
            self._on_row(row, sample)
        return row

    def abort(self, ending: Outcome) -> None:
        """Sticks to disarm now (the RC link repeats it on close) and record the final row.

        Args:
            ending: How the flight ended; the final row's phase carries its value.
        """
        vehicle = self.vehicle
        if vehicle.rc is None:
            return
        safe = replace(
            vehicle.rc_command, throttle_us=RC_MIN_US, aux_us=(SWITCH_OFF_US, SWITCH_OFF_US)
        )
        vehicle.set_rc(safe)
        if self.last_sample is not None:
            self._record(ending.value, self.target_alt_m, self.last_sample, self._climb.rate_m_s)


def next_step(clock: SessionClock, next_s: float, period_s: float) -> float:
    """Let simulation time pass to the next control step; its time.  A late step is taken at
    once and the schedule restarts from it: no burst of steps to catch up."""
    next_s += period_s
    delay_s = next_s - clock.now_s()
    if delay_s > 0:
        clock.sleep_s(delay_s)
        return next_s
    return clock.now_s()


def _altitude_input(sample: FlightSample, climb_m_s: float, target_alt_m: float) -> AltitudeInput:
    """What an altitude controller is given of a step: the FC's view, never the truth."""
    return AltitudeInput(
        sample.time_s,
        sample.fc_alt_m,
        climb_m_s,
        target_alt_m,
        accel_up_m_s2=sample.fc_accel_up_m_s2,
    )
