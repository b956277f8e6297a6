"""Fly one scenario on one firmware: provision, fly, inject, watch, judge.

The order of a run:

1. the firmware is found and its profile read from the binary: a fault it cannot express,
   or a GPS scenario on a build without GPS, is *skipped* with the reason before anything
   starts;
2. a session starts in its own run directory with the scenario's CLI lines, the FC's
   blackbox on (``blackbox_device = VIRTUAL``) and ``debug_mode = FAILSAFE`` (the failsafe
   phase is read live from MSP_DEBUG), plus the FAILSAFE switch on AUX3 if a fault uses it;
3. bfsitl's autopilot flies the ``[flight]`` table; each control step the faults due are
   injected (and those that ended undone) and a trace row is taken;
4. once a fault takes the sticks away (RC lost), or the autopilot's flight ends (landed,
   disarmed by the FC, crashed), the runner only watches, until ``duration_s`` or until the
   FC is disarmed and the vehicle at rest for ``settle_s``;
5. the session closes (the FC's blackbox file is complete), the blackbox is copied out and
   decoded, the expectations are judged, and the plot and a JSON summary are written.

A ``[replay]`` scenario (:mod:`bfsitl.scenario.replay_run`) flies its log's sticks again in
steps 2 to 5 instead, and is judged the same way.

Every way a run can end becomes a :class:`~bfsitl.scenario.result.ScenarioResult`; only
Ctrl-C propagates (after the session has stopped).
"""

from __future__ import annotations

import contextlib
import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.analysis import FlightWatch, analyse, combine, track_from_blackbox
from bfsitl.analysis.track import stick_share
from bfsitl.atomic_file import write_atomically
from bfsitl.backend.options import Timing, World
from bfsitl.control import DEFAULT_CONTROLLER, make_controller
from bfsitl.errors import (
    ArmingBlockedError,
    BfsitlError,
    CrashDetectedError,
    FaultNotSupportedError,
    MissionError,
    MissionTimeoutError,
)
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.hooks import FlightHooks
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan_driver import fly_steps
from bfsitl.mission.session import (
    FcSetup,
    FlightSession,
    SessionConfig,
    SitlLaunch,
)
from bfsitl.mission.vehicle import FlightSample
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import FirmwareProfile, with_rc_link
from bfsitl.records.outputs import FlightOutputs, OutputOptions
from bfsitl.scenario.build_fit import missing_features_reason, unfit_reason
from bfsitl.scenario.expectations import settle_verdict
from bfsitl.scenario.faults import Fault, Undo, make_faults
from bfsitl.scenario.metrics import run_metrics
from bfsitl.scenario.prepared_fc import fresh_run_dir
from bfsitl.scenario.replay_run import fly_replay_scenario
from bfsitl.scenario.result import PlotWhen, ScenarioResult, TimedEvent, Verdict, wants_plot
from bfsitl.scenario.setup_lines import (
    failsafe_phase_unread,
    mode_range_lines,
    provisioned_settings,
    scenario_profile,
)
from bfsitl.scenario.spec import Scenario
from bfsitl.scenario.timings import Stopwatch
from bfsitl.scenario.trace import Trace, TraceRow, phase_name, write_trace_csv
from bfsitl.sitl.firmware import find_firmware

#: debug[] index of the failsafe phase with ``debug_mode = FAILSAFE`` (flight/failsafe.c).
FAILSAFE_PHASE_DEBUG_INDEX = 3


#: A vehicle at rest: slower than this vertically.
AT_REST_M_S = 0.05

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class RunOptions:
    """How to run (not what: that is the scenario).

    Attributes:
        out_dir: This run's directory: its CSV, plot, summary, blackbox and the SITL's run
            directory.  Made if missing.
        speed: Simulation speed as a multiple of real time; None: as fast as it goes on a
            lockstep build, real time otherwise.
        plot: Draw the flight and the FC's log to PNGs: True always, False never,
            "failed" only when the run failed or errored.
        mcap: Write the flight as MCAP too (Foxglove's schemas, ``flight.mcap``; needs the
            foxglove extra).
        shares_cores: Other runs share this machine's cores: no busy-waiting in lockstep
            (see ``Timing.lockstep_spin``).
        session_factory: Makes the flight's vehicle from its configuration (``progress=``
            too); a fake in unit tests.  Picklable as it is, for Ray.
        controller: The autopilot's altitude controller, by name (see ``bfsitl fly
            --list-gains``).
        prepared_fc: Start the FC configured, from a state prepared once per build and
            configuration (:mod:`bfsitl.scenario.prepared_fc`); False: configure it in the
            run and reboot (a fake session keeps no state).
    """

    #: This run's directory: its CSV, plot, summary, blackbox and the SITL's run directory.
    out_dir: Path
    #: x real time; None: as fast as it goes on a lockstep build, real time otherwise.
    speed: float | None = None
    #: Draw the plots: True always, False never, "failed" only when it failed or errored.
    plot: PlotWhen = True
    #: Write the flight as MCAP too (Foxglove's schemas, ``flight.mcap``; the foxglove extra).
    mcap: bool = False
    #: Other runs share this machine's cores: no busy-waiting in lockstep (see
    #: Timing.lockstep_spin).
    shares_cores: bool = False
    #: Makes the flight's vehicle from its configuration (``progress=`` too); a fake in unit
    #: tests.  Picklable as it is, for Ray.
    session_factory: Callable[..., FlightSession] = FlightSession
    #: The autopilot's altitude controller, by name (see ``bfsitl fly --list-gains``).
    controller: str = DEFAULT_CONTROLLER
    #: Start the FC configured: from the saved state of a SITL of the same build given the
    #: same configuration, prepared once and cached (bfsitl.scenario.prepared_fc); False:
    #: from the firmware's defaults, configured and rebooted in the run (a fake session in
    #: unit tests keeps no state).
    prepared_fc: bool = True


class _Injector:
    """Injects each fault when it is due and undoes it when it ends; keeps the trace."""

    def __init__(
        self,
        vehicle: FlightSession,
        faults: tuple[Fault, ...],
        trace: Trace,
        events: list[TimedEvent],
        progress: Progress,
        record: Progress,
        watch: FlightWatch | None = None,
        reads_phase: bool = True,
    ) -> None:
        self.vehicle = vehicle
        #: The FC's debug[] holds its failsafe phase: read it with every row.
        self.reads_phase = reads_phase
        #: The analysers' record of the run, on the trace's clock (seconds from arming).
        self.watch = watch or FlightWatch()
        #: Events go to the flight's outputs as well (the MCAP file's /events log).
        self.record = record
        self.pending = sorted(faults, key=lambda f: f.spec.at_s)
        self.active: list[tuple[float, Fault, Undo]] = []
        self.trace = trace
        self.events = events
        self.progress = progress
        self.armed_at_s: float | None = None
        self.sticks_taken = False

    def note(self, time_s: float, text: str) -> None:
        self.events.append(TimedEvent(round(time_s, 3), text))
        self.progress(f"t={time_s:6.2f} s  {text}")
        self.record(text)

    def since_arming(self, sample: FlightSample) -> float:
        return sample.time_s - (self.armed_at_s or 0.0)

    def on_row(self, row: FlightRow, sample: FlightSample) -> None:
        if self.armed_at_s is None:
            return
        t = self.since_arming(sample)
        for end_s, fault, undo in list(self.active):
            if t >= end_s:
                undo()
                self.active.remove((end_s, fault, undo))
                self.note(t, f"{fault.title}: over")
        while self.pending and t >= self.pending[0].spec.at_s:
            fault = self.pending.pop(0)
            undo = fault.apply(self.vehicle)
            lasts = fault.spec.duration_s
            self.active.append((t + lasts if lasts is not None else math.inf, fault, undo))
            self.trace.fault_times_s.append(round(t, 4))
            self.note(t, f"{fault.title}" + (f" for {lasts:g} s" if lasts is not None else ""))
            if fault.takes_sticks:
                self.sticks_taken = True
        self.trace.rows.append(self._row(t, sample, row))
        self.watch.add(
            row, sample, time_s=round(t, 4), failsafe_phase=self.trace.rows[-1].failsafe_phase
        )

    def stop(self, _sample: FlightSample) -> str | None:
        """The autopilot stops flying once a fault has taken its sticks (then it watches)."""
        return "a fault took the sticks" if self.sticks_taken else None

    def _row(self, t: float, sample: FlightSample, row: FlightRow) -> TraceRow:
        phase: int | None = None
        if self.reads_phase:
            try:
                debug = self.vehicle.reading(msg.Debug, sample).values
                if len(debug) > FAILSAFE_PHASE_DEBUG_INDEX:
                    phase = debug[FAILSAFE_PHASE_DEBUG_INDEX]
            except BfsitlError:
                pass
        if self.trace.rows:  # what changed since the last row
            last = self.trace.rows[-1]
            if phase is not None and phase != last.failsafe_phase:
                self.note(t, f"failsafe phase {phase_name(phase)}")
            if last.armed and not sample.armed:
                self.note(
                    t,
                    "the FC disarmed"
                    + (f" ({', '.join(sample.arming_blockers)})" if sample.arming_blockers else ""),
                )
            new_modes = set(sample.flight_modes) - set(last.modes)
            if new_modes:
                self.note(t, f"flight mode {', '.join(sorted(new_modes))} on")
        return TraceRow(
            round(t, 4),
            sample.sim_alt_m,
            sample.sim_north_m,
            sample.sim_east_m,
            sample.sim_climb_m_s,
            sample.sim_tilt_deg,
            sample.on_ground,
            sample.armed,
            sample.flight_modes,
            sample.arming_blockers,
            phase,
            sample.sim_yaw_deg,
            stick_share(row.rc_throttle_us),
            sum(sample.motors) / len(sample.motors),
            len(self.trace.fault_times_s),
        )


def run_scenario(
    scenario: Scenario, firmware: str, options: RunOptions, *, progress: Progress | None = None
) -> ScenarioResult:
    """Fly ``scenario`` on ``firmware`` (a cached build's name or a path); never raises for
    a failed flight (only for Ctrl-C).

    Args:
        scenario: What to fly, as :func:`~bfsitl.scenario.load.load_scenario` reads it.
        firmware: A cached build's name or a SITL binary's path.
        options: How to run: where the files go, the speed, the outputs.
        progress: Called with one line of text at each step of the run.

    Returns:
        The verdict, the checks behind it, the events and the files written.  A firmware
        that cannot fly it gives a skipped result, a flight that could not be flown an
        error result; neither raises.

    Raises:
        KeyboardInterrupt: Ctrl-C, SIGTERM or SIGHUP, after the session has stopped and the
            summary is written.
    """
    say = progress or (lambda _line: None)
    started = time.monotonic()
    result = ScenarioResult(
        scenario.name,
        firmware,
        Verdict.ERROR,
        "",
        source=scenario.source,
        description=scenario.description,
        vehicle=scenario.quad.name,
    )
    out = options.out_dir
    try:
        out.mkdir(parents=True, exist_ok=True)
        binary = find_firmware(firmware)
        profile = with_rc_link(profile_of_binary(binary.path), scenario.rc_rate_hz)
        result.firmware_version = profile.firmware_version
        reason = unfit_reason(scenario, profile, binary.path, firmware)
        faults = make_faults(scenario.faults, profile, where=scenario.where) if not reason else ()
        reason = reason or missing_features_reason(scenario, faults, binary.path, firmware, profile)
        if reason:
            result.verdict, result.reason = Verdict.SKIPPED, reason
            return result
        if scenario.replay is not None:
            timing = Timing(speed=options.speed, lockstep_spin=not options.shares_cores)
            fly_replay_scenario(
                scenario, binary.path, profile, out, result, say, plot=options.plot, timing=timing
            )
        else:
            result.settings = [
                (s.source, s.line, s.why)
                for s in (
                    *mode_range_lines(faults),
                    *provisioned_settings(scenario, profile, faults),
                )
            ]
            _fly(scenario, binary.path, profile, faults, options, result, say)
    except FaultNotSupportedError as exc:
        result.verdict, result.reason = Verdict.SKIPPED, str(exc)
    except BfsitlError as exc:
        result.verdict, result.reason = Verdict.ERROR, str(exc).splitlines()[0]
    finally:
        result.wall_time_s = round(time.monotonic() - started, 3)
        write_summary(result, out)
    return result


def _fly(
    scenario: Scenario,
    binary: Path,
    profile: FirmwareProfile,
    faults: tuple[Fault, ...],
    options: RunOptions,
    result: ScenarioResult,
    say: Progress,
) -> None:
    out = options.out_dir
    trace = Trace()
    config = SessionConfig.for_autopilot(
        control_rate_hz=FlightSession.control_rate_hz,
        sitl=SitlLaunch(firmware=binary, workdir=out / "sitl"),
        timing=Timing(speed=options.speed, lockstep_spin=not options.shares_cores),
        fc=FcSetup(
            profile=scenario_profile(scenario, profile, faults), rc_rate_hz=scenario.rc_rate_hz
        ),
        world=World(
            physics=scenario.physics,
            quad=scenario.quad,
            wind=scenario.wind,
            seed=scenario.seed,
            initial_heading_deg=scenario.initial_heading_deg,
        ),
    )
    # The analysers watch through the injector (on the trace's clock, with the failsafe
    # phase), so the outputs do not keep a second copy of every row for them.
    outputs = FlightOutputs(
        OutputOptions(
            csv_path=out / "flight.csv",
            mcap_path=out / "flight.mcap" if options.mcap else None,
            watch=False,
        )
    )
    watch = Stopwatch()
    with watch.span("prepare") if options.prepared_fc else contextlib.nullcontext():
        fresh_run_dir(config, options.prepared_fc, options.session_factory, say)
    session = options.session_factory(config, progress=lambda line: say(f"[sitl] {line}"))
    unread = failsafe_phase_unread(line for _source, line, _why in result.settings)
    injector = _Injector(
        session, faults, trace, result.events, say, outputs.on_event, reads_phase=unread is None
    )
    if unread is not None:
        injector.note(0.0, unread)
    planned = [(w.north_m, w.east_m) for w in scenario.fc_waypoints] + [
        (w.north_m, w.east_m) for w in scenario.plan.waypoints
    ]
    injector.watch.track.planned_reach_m = max((math.hypot(*p) for p in planned), default=0.0)

    def on_row(row: FlightRow, sample: FlightSample) -> None:
        outputs.on_row(row, sample)  # recorded first: the injector may end the flight
        injector.on_row(row, sample)

    # Opened only now, next to the block that closes them: preparing the FC or making the
    # session may raise.
    outputs.start()
    result.artifacts["log"] = out / "flight.csv"
    if options.mcap:
        result.artifacts["mcap"] = out / "flight.mcap"
    # The session is entered apart from its block, so its start-up and its stop (the SITL
    # stopped, its blackbox file complete) are timed on their own.
    stack = contextlib.ExitStack()
    try:
        try:
            # Entered inside the try: a Ctrl-C between the start and the block still closes
            # the session.
            with watch.span("start-up"):
                stack.enter_context(session)
            result.firmware_version = (
                session.firmware.firmware_version if session.firmware else result.firmware_version
            )
            if session.sitl is not None:
                result.artifacts["sitl_log"] = session.sitl.log_path
            if unread is None:
                # The failsafe phase (debug_mode = FAILSAFE) in each row's round trip.
                session.read_with_samples(msg.Debug)
            loop = FlightLoop(
                session,
                make_controller(options.controller, quad=scenario.quad),
                rate_hz=session.control_rate_hz,
                hooks=FlightHooks(on_step=on_row, stop=injector.stop),
            )
            try:
                with watch.span("arming"):
                    loop.arm()
            except ArmingBlockedError as exc:
                result.verdict, result.reason = Verdict.ERROR, str(exc)
                return
            injector.armed_at_s = session.time_s
            injector.note(0.0, "armed")
            with watch.span("flight"):
                _autopilot_flight(scenario, loop, injector, trace)
                _watch(scenario, loop, injector)
        finally:
            with watch.span("stop"):
                stack.close()
    finally:
        with watch.span("stop"):
            outputs.close()
        result.timings_s = dict(watch.spans_s)
    result.sim_time_s = round(trace.end_s, 3)
    with watch.span("blackbox"):
        _collect_blackbox(out, trace, result)
    with watch.span("analysers"):
        _analyse(injector.watch, trace, result)
        figures = run_metrics(injector.watch.track, trace, result.findings)
        result.metrics, result.behaviour = figures.values, figures.behaviour
    with watch.span("files"):
        if trace.rows:
            result.artifacts["trace"] = write_trace_csv(trace, out / "trace.csv")
    with watch.span("analysers"):
        settle_verdict(result, scenario, trace, profile.generation.value)
    if wants_plot(options.plot, result.verdict):
        with watch.span("plots"):
            _plot(scenario, trace, result, out)
    result.timings_s = dict(watch.spans_s)


def _plot(scenario: Scenario, trace: Trace, result: ScenarioResult, out: Path) -> None:
    """The flight's plot.png and the FC's log's blackbox.png."""
    title = f"{scenario.name} on {result.firmware}"
    if trace.rows:
        from bfsitl.scenario.plot import write_scenario_plot

        result.artifacts["plot"] = write_scenario_plot(trace, out / "plot.png", title=title)
    if trace.blackbox and trace.blackbox[0].frames:
        from bfsitl.blackbox.plot import write_blackbox_plot

        result.artifacts["blackbox_plot"] = write_blackbox_plot(
            trace.blackbox[0], out / "blackbox.png", title=title
        )


def _autopilot_flight(
    scenario: Scenario, loop: FlightLoop, injector: _Injector, trace: Trace
) -> None:
    """The ``[flight]`` table flown (the vehicle is armed) until it ends, a fault takes the
    sticks (the loop's stop condition), or it fails."""
    armed_at_s = injector.armed_at_s or 0.0

    def t() -> float:
        return loop.vehicle.time_s - armed_at_s

    def step_done(step: Phase) -> None:
        if step is Phase.TAKEOFF:
            trace.takeoff_done_s = round(t(), 3)
        elif step is Phase.LANDED:
            injector.note(t(), "the autopilot landed")

    try:
        fly_steps(
            loop,
            scenario.plan,
            arm=False,
            time_left_s=lambda: scenario.duration_s - t(),
            after_step=step_done,
        )
        if loop.stopped:
            injector.note(t(), "the sticks are the FC's now: watching")
    except CrashDetectedError as exc:
        trace.crash = (round(t(), 3), str(exc))
        injector.note(t(), f"crash: {exc}")
    except MissionTimeoutError as exc:
        injector.note(t(), f"the autopilot gave up: {exc}")
    except MissionError as exc:
        injector.note(t(), f"the autopilot stopped: {exc}")


def _watch(scenario: Scenario, loop: FlightLoop, injector: _Injector) -> None:
    """Record until ``duration_s``, or until disarmed and at rest for ``settle_s``."""
    vehicle = loop.vehicle
    resting_since: list[float] = []

    def done(sample: FlightSample) -> bool:
        t = injector.since_arming(sample)
        if t >= scenario.duration_s:
            return True
        if sample.armed or not sample.on_ground or abs(sample.sim_climb_m_s) > AT_REST_M_S:
            resting_since.clear()
            return False
        if not resting_since:
            resting_since.append(t)
        return t - resting_since[0] >= scenario.settle_s

    left_s = scenario.duration_s - (vehicle.time_s - (injector.armed_at_s or 0.0))
    if left_s > 0:
        loop.observe(done, timeout_s=left_s + 1.0, phase=Phase.WATCH)


def _analyse(watch: FlightWatch, trace: Trace, result: ScenarioResult) -> None:
    """Every analyser on the run (the trace's rows with the truth) and on the FC's own
    log(s): each analyser's worst finding, in the result and in the trace (expectations may
    ask about them)."""
    analysis = combine(
        watch.analysis(), *(analyse(track_from_blackbox(log)) for log in trace.blackbox)
    )
    trace.findings = analysis.findings
    trace.unwatched = analysis.skipped
    result.take_analysis(analysis)


def _collect_blackbox(out: Path, trace: Trace, result: ScenarioResult) -> None:
    """The FC's own log(s) copied out of the SITL's run directory and decoded; a log that
    cannot be read is an event, not a failed run (an expectation on it says so)."""
    from bfsitl.blackbox import collect_blackbox, decode_blackbox

    copies = collect_blackbox(out / "sitl", out / "blackbox")
    for index, path in enumerate(copies):
        result.artifacts["blackbox" if index == 0 else f"blackbox{index + 1}"] = path
        try:
            trace.blackbox.extend(decode_blackbox(path))
        except BfsitlError as exc:
            result.events.append(TimedEvent(trace.end_s, f"blackbox {path.name}: {exc}"))


def write_summary(result: ScenarioResult, out: Path) -> None:
    """The run's result.json in ``out`` (also rewritten on a Ray driver once the files are
    home: the names and paths there are the driver's)."""
    if not out.is_dir():
        return
    data = {
        "name": result.name,
        "firmware": result.firmware,
        "firmware_version": result.firmware_version,
        "vehicle": result.vehicle,
        "verdict": result.verdict.value,
        "reason": result.reason,
        "sim_time_s": result.sim_time_s,
        "wall_time_s": result.wall_time_s,
        "checks": [
            {
                "expectation": c.expectation,
                "passed": c.passed,
                "message": c.message,
                "measured": c.measured,
                "at_time_s": c.at_time_s,
            }
            for c in result.checks
        ],
        "events": [{"time_s": e.time_s, "text": e.text} for e in result.events],
        "artifacts": {k: str(v) for k, v in result.artifacts.items()},
        "retried": list(result.retried),
        "findings": [f.as_dict() for f in result.findings],
        "metrics": {k: (round(v, 4) if v is not None else None) for k, v in result.metrics.items()},
        "behaviour": result.behaviour,
        "settings": [
            {"from": source, "line": line, "why": why} for source, line, why in result.settings
        ],
        "timings_s": {phase: round(seconds, 4) for phase, seconds in result.timings_s.items()},
        "analysers": {"watched": result.watched, "skipped": result.unwatched},
    }
    path = out / "result.json"
    write_atomically(path, (json.dumps(data, indent=2) + "\n").encode("utf-8"))
    result.artifacts["summary"] = path
