"""A scenario run flown end to end without a SITL: what it provisions and starts, the faults
applied and undone at their times after arming, the autopilot stopping when a fault takes
its sticks, the watch to the end (or to rest), and the verdict, events and files that come
out of it.

``run_scenario`` makes its session with ``RunOptions.session_factory`` (the fake's here) and
its controller by name (``RunOptions.controller``); a name cannot be a test's P controller,
so the tests replace ``make_controller`` in :mod:`bfsitl.scenario.run`.  The session is
test_mission_runner's point mass with an FC failsafe added (the FAILSAFE switch on AUX3
lands it at 1 m/s and disarms it on the ground, the phase read over MSP_DEBUG from the fake
FC of tests/support/fake_fc.py); the controller is that file's P controller (the fused one needs a
real FC's altitude filter to fly).  The firmware is test_scenario_run's file that passes for
a stock 4.6.0 SITL.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
from support.fake_fc import FakeFcLink
from support.fake_vehicles import HOVER_US, FakeVehicle, PController
from support.scenario_files import V46, fake_binary, scenario

from bfsitl.analysis import Finding, Severity
from bfsitl.backend.embedded import RealTimeBackend
from bfsitl.control import DEFAULT_CONTROLLER
from bfsitl.errors import ArmingBlockedError, SitlExitedError
from bfsitl.fc.msp_client import MspClient
from bfsitl.mission.session import FAST_SERIAL_LINE, FLY_PROFILE, SessionConfig
from bfsitl.mission.vehicle import FlightSample
from bfsitl.physics import IRIS, Simulator
from bfsitl.physics.wind import Wind
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import BoxId
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame
from bfsitl.records.csv_log import read_flight_log
from bfsitl.scenario import run
from bfsitl.scenario.faults import make_faults, read_fault_spec
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.run import RunOptions
from bfsitl.scenario.setup_lines import blackbox_cli, hover_throttle_line, scenario_profile
from bfsitl.scenario.trace import read_trace_csv

#: The fake's clock reads this at arming (a SITL boots first): times "from arming" differ
#: from the session's own.
BOOT_S = 3.0
IDLE, RX_LOSS_DETECTED, LANDING, LANDED = 0, 1, 2, 3
RC_LOST_AT_8 = {"kind": "rc_loss", "at_s": 8.0}  # on 4.6.0: the FAILSAFE switch, AUX3
FLIGHT = {"takeoff_alt_m": 2.0, "hold_s": 30.0, "ground_s": 0.5}


class FailsafeSession(FakeVehicle):
    """The session a scenario run starts, made from the run's :class:`SessionConfig`: the
    runner tests' point mass whose FC lands it when the FAILSAFE switch (AUX3) is on, as
    4.6.0's failsafe does: RX_LOSS_DETECTED, then LANDING at 1 m/s whatever the throttle,
    LANDED and disarmed on the ground.  MSP_DEBUG answers the phase (``debug[3]``)."""

    def __init__(
        self,
        config: SessionConfig,
        *,
        progress: Any = None,
        failsafe_lands: bool = True,
        firmware: Any = None,
        sitl: Any = None,
        embedded: bool = False,
        **fake: Any,
    ) -> None:
        super().__init__(**fake)
        self.session_config = config
        self.progress = progress
        self.time_s = BOOT_S
        self.failsafe_lands = failsafe_lands
        self._firmware = firmware
        self.sitl = sitl
        self.phase = IDLE
        self.closed = False
        self.on_close(self._close)
        #: (time from boot, the wind the physics blows) at each sample.
        self.winds: list[tuple[float, Wind | None]] = []
        if embedded:  # faults on the physics act through its disturbance surface
            self.backend = RealTimeBackend(Simulator(IRIS), speed=1.0, progress=lambda _l: None)
        self.fc_link = FakeFcLink({MspCommand.DEBUG: self._debug})
        self._client = MspClient(self.fc_link, timeout_s=0.5)

    def _close(self) -> None:
        self.closed = True

    def _debug(self, _request: MspFrame) -> bytes:
        return msg.Debug((0, 0, 0, self.phase, 0, 0, 0, 0)).encode()

    @property
    def client(self) -> MspClient:  # type: ignore[override]
        return self._client

    @property
    def firmware(self) -> Any:  # type: ignore[override]
        return self._firmware

    def sample(self) -> FlightSample:
        switch = len(self.command.aux_us) > 2 and self.command.aux_us[2] >= 1700
        failsafe = self.armed and switch and self.failsafe_lands
        if failsafe:
            self.phase = RX_LOSS_DETECTED if self.phase == IDLE else LANDING
            flown = self.command
            self.command = replace(flown, throttle_us=HOVER_US - 200.0)  # 1 m/s down
            try:
                sample = super().sample()
            finally:
                self.command = flown
        else:
            sample = super().sample()
        if self.simulator is not None:
            self.winds.append((self.time_s, self.simulator.wind))
        modes = ("ANGLE", "FAILSAFE") if failsafe else ("ANGLE",)
        if failsafe and self.phase == LANDING and sample.on_ground:
            self.phase, self.armed = LANDED, False
        return replace(sample, armed=self.armed, flight_modes=modes if self.armed else ())

    @property
    def simulator(self) -> Simulator | None:
        return self.backend.simulator


class Sessions:
    """The run's ``session_factory``: makes the fake, keeps it."""

    control_rate_hz = FailsafeSession.control_rate_hz

    def __init__(self, **options: Any) -> None:
        self.options = options
        self.made: list[FailsafeSession] = []

    def __call__(self, config: SessionConfig, *, progress: Any = None) -> FailsafeSession:
        session = FailsafeSession(config, progress=progress, **self.options)
        self.made.append(session)
        return session

    @property
    def one(self) -> FailsafeSession:
        (session,) = self.made
        return session


@pytest.fixture
def fly(monkeypatch: pytest.MonkeyPatch, tmp_path: Path):  # type: ignore[no-untyped-def]
    """``fly(scenario, **session_options)``: run it on the fake with the P controller;
    returns the result and the fake session."""
    binary = fake_binary(tmp_path)
    asked: list[str] = []

    def controller(name: str, *, quad: Any = None) -> PController:
        asked.append(name)
        return PController()

    monkeypatch.setattr(run, "make_controller", controller)

    def flown(
        spec: Any, *, options: RunOptions | None = None, **session_options: Any
    ) -> tuple[ScenarioResult, FailsafeSession]:
        sessions = Sessions(**session_options)
        options = dataclasses.replace(
            options or RunOptions(tmp_path / "out", plot=False),
            session_factory=sessions,
            prepared_fc=False,  # the fake FC keeps no configuration to prepare
        )
        result = run.run_scenario(spec, str(binary), options)
        assert asked[-1] == DEFAULT_CONTROLLER
        return result, sessions.one

    return flown


def texts(result: ScenarioResult) -> list[str]:
    return [event.text for event in result.events]


def at(result: ScenarioResult, text: str) -> float:
    return next(e.time_s for e in result.events if e.text == text)


# -- what a run provisions ------------------------------------------------------------------
def test_a_run_provisions_the_fly_profile_then_the_blackbox_the_hover_and_its_own_lines() -> None:
    plain = scenario(cli=["set failsafe_procedure = DROP", "set failsafe_delay = 5"])
    profile = scenario_profile(plain, V46, ())
    assert profile.mode_ranges == FLY_PROFILE.mode_ranges  # ARM on AUX1, ANGLE on AUX2
    lines = profile.cli_lines
    assert lines.count(FAST_SERIAL_LINE) == 1 and lines[0] == FAST_SERIAL_LINE
    blackbox = list(blackbox_cli(V46))
    assert lines[1 : 1 + len(blackbox)] == tuple(blackbox)
    assert lines[-3:] == (
        hover_throttle_line(IRIS),
        "set failsafe_procedure = DROP",
        "set failsafe_delay = 5",
    )


def test_the_failsafe_switch_is_provisioned_once_on_aux3_only_when_a_fault_uses_it() -> None:
    def faults(*tables: dict) -> tuple:
        specs = tuple(
            read_fault_spec(t, where="t", number=n, run_s=20.0) for n, t in enumerate(tables, 1)
        )
        return make_faults(specs, V46)

    plain = scenario()
    two_switches = scenario_profile(
        plain, V46, faults(RC_LOST_AT_8, {**RC_LOST_AT_8, "at_s": 12.0})
    )
    failsafe = [r for r in two_switches.mode_ranges if r.box_id == BoxId.FAILSAFE]
    assert len(failsafe) == 1 and two_switches.mode_ranges[:2] == FLY_PROFILE.mode_ranges
    assert (failsafe[0].aux_channel_index, failsafe[0].start_us, failsafe[0].end_us) == (
        2,
        1700,
        2100,
    )
    wind_only = scenario_profile(
        plain, V46, faults({"kind": "wind", "at_s": 1.0, "north_m_s": 3.0})
    )
    assert wind_only.mode_ranges == FLY_PROFILE.mode_ranges


def test_a_gazebo_scenario_asks_for_gazebos_physics(fly) -> None:
    spec = scenario(flight=FLIGHT, physics="gazebo", expect={"disarmed": True})
    _result, session = fly(spec)
    assert session.session_config.world.physics == "gazebo"


def test_a_scenario_flies_its_rc_links_rate(fly) -> None:
    rates = []
    for table in ({}, {"rc": {"rate_hz": 100}}, {"rc": {"rate_hz": "packet"}}):
        _result, session = fly(scenario(flight=FLIGHT, expect={"disarmed": True}, **table))
        rates.append(session.session_config.fc.rc_rate_hz)
    assert rates == [250.0, 100.0, None]


def test_a_heavier_quad_gets_a_higher_hover_throttle_in_proportion() -> None:
    heavy = scenario(vehicle={"mass_kg": 2.5})
    value = int(hover_throttle_line(heavy.quad).rsplit(" ", 1)[1])
    scale = heavy.quad.hover_command / IRIS.hover_command
    assert scale > 1.0 and value == round(1000 + 545 * scale) > 1545
    assert hover_throttle_line(heavy.quad) in scenario_profile(heavy, V46, ()).cli_lines


# -- a flight ---------------------------------------------------------------------------------
def test_rc_lost_in_a_hover_the_fc_lands_disarms_and_the_run_passes(fly, tmp_path) -> None:
    spec = scenario(
        flight=FLIGHT,
        seed=7,
        wind={"north_m_s": 1.0},
        fault=[RC_LOST_AT_8],
        expect={
            "disarmed": True,
            "disarmed_within_s": 3.0,
            "failsafe_phase": ["RX_LOSS_DETECTED", "LANDING", "LANDED"],
            "failsafe_within_s": 0.1,
            "mode_seen": "FAILSAFE",
            "min_alt_m": 1.9,
            "max_touchdown_m_s": 1.5,
        },
    )
    result, session = fly(spec)
    assert result.verdict is Verdict.PASSED, result.reason
    assert result.reason == "all 6 expectations met" and all(c.passed for c in result.checks)
    # The session it started: this run's directory, the scenario's quad, wind and seed.
    config = session.session_config
    out = tmp_path / "out"
    world = config.world
    assert (config.sitl.workdir, world.seed, world.wind, world.quad) == (
        out / "sitl",
        7,
        spec.wind,
        spec.quad,
    )
    assert config.sitl.firmware == tmp_path / "betaflight_4.6.0_SITL"
    assert config.fc.profile == scenario_profile(spec, V46, make_faults(spec.faults, V46))
    assert config.timing.lockstep_spin and session.closed
    # The fault at 8 s after arming (not after boot), then the FC's own landing.
    fault_s = at(result, "RC lost (failsafe switch on AUX3)")
    assert 8.0 <= fault_s < 8.03
    events = texts(result)
    assert events[0] == "armed" and result.events[0].time_s == 0.0
    order = [
        "RC lost (failsafe switch on AUX3)",
        "the sticks are the FC's now: watching",
        "failsafe phase RX_LOSS_DETECTED",
        "flight mode FAILSAFE on",
        "failsafe phase LANDING",
        "failsafe phase LANDED",
        "the FC disarmed",
    ]
    assert [e for e in events if e in order] == order
    disarmed_s = at(result, "the FC disarmed")
    assert disarmed_s - fault_s == pytest.approx(2.0, abs=0.1)  # 2 m at 1 m/s
    # Disarmed at rest: the run ends settle_s (2 s) later, not at duration_s (20 s).
    assert result.sim_time_s == pytest.approx(disarmed_s + 2.0, abs=0.05)
    checks = {c.expectation.split(" =")[0]: c for c in result.checks}
    assert checks["disarmed_within_s"].measured == pytest.approx(2.0, abs=0.1)
    # RX_LOSS_DETECTED one control step after the switch went on (the FC's next look).
    assert checks["failsafe_phase"].measured == pytest.approx(0.02, abs=0.005)
    assert checks["failsafe_phase"].at_time_s == pytest.approx(fault_s + 0.02, abs=0.005)
    # The autopilot flew until the fault and only watched after it.
    rows = read_flight_log(result.artifacts["log"])
    phases = [row["phase"] for row in rows]
    assert phases.index("takeoff") < phases.index("hold") < phases.index("watch")
    assert "land" not in phases
    first_watch = next(float(r["time_s"]) for r in rows if r["phase"] == "watch")
    assert first_watch - BOOT_S == pytest.approx(fault_s, abs=0.03)
    summary = json.loads((out / "result.json").read_text())
    assert summary["verdict"] == "passed" and summary["sim_time_s"] == result.sim_time_s
    assert summary["vehicle"] == result.vehicle == "iris"  # which quad flew, IRIS by default
    assert [e["text"] for e in summary["events"]] == events
    assert set(summary["artifacts"]) == {"log", "trace"}  # no plot, no blackbox
    # Where its wall time went, each phase of the run timed (no plots asked for: none).
    assert set(summary["timings_s"]) == {
        "start-up", "arming", "flight", "stop", "blackbox", "analysers", "files"
    }  # fmt: skip
    assert summary["timings_s"]["flight"] > 0
    assert sum(summary["timings_s"].values()) <= result.wall_time_s + 0.01
    assert result.artifacts["summary"] == out / "result.json"
    # trace.csv holds the trace's rows (a comparison overlays two of them), and the run's
    # figures and behaviour are in result.json.
    again = read_trace_csv(out / "trace.csv")
    assert len(again.rows) > 100
    assert again.rows[-1].armed is False and again.rows[-1].on_ground is True
    assert summary["metrics"]["fault_to_disarm_s"] == pytest.approx(2.0, abs=0.1)
    assert summary["metrics"]["touchdown_m_s"] == pytest.approx(1.0)  # 2 m at 1 m/s
    assert summary["metrics"]["landed_distance_m"] is None  # this physics has no position
    assert summary["behaviour"]["ended"] == ["disarmed on the ground"]
    assert summary["behaviour"]["phases"][0] == "RX_LOSS_DETECTED"


def test_an_fc_that_never_disarms_fails_the_run_after_its_whole_duration(fly) -> None:
    spec = scenario(
        flight=FLIGHT,
        fault=[RC_LOST_AT_8],
        expect={"disarmed_within_s": 3.0, "disarmed": True, "mode_never": "ANGLE"},
    )
    result, session = fly(spec, failsafe_lands=False)
    assert result.verdict is Verdict.FAILED
    assert result.reason.startswith("disarmed_within_s = 3: still armed 12.0")
    assert [c.passed for c in result.checks] == [False, False, False]
    assert result.sim_time_s == pytest.approx(20.0, abs=0.03)  # watched to the end
    assert "the FC disarmed" not in texts(result) and session.closed


def test_a_timed_fault_is_undone_when_it_ends_and_the_autopilot_flies_through_it(fly) -> None:
    spec = scenario(
        flight={**FLIGHT, "hold_s": 6.0},
        duration_s=16.0,
        fault=[{"kind": "wind", "at_s": 4.0, "duration_s": 2.0, "north_m_s": 5.0}],
        expect={"disarmed": True, "max_alt_m": 2.3},
    )
    result, session = fly(spec, embedded=True)
    assert result.verdict is Verdict.PASSED, result.reason
    start_s = at(result, "wind to 5 m/s north, 0 m/s east (gusts 0 m/s) for 2 s")
    over_s = at(result, "wind to 5 m/s north, 0 m/s east (gusts 0 m/s): over")
    assert 4.0 <= start_s < 4.03 and over_s - start_s == pytest.approx(2.0, abs=0.025)
    # The physics felt it from the step after it was set to the step it was undone on.
    blowing = [t - BOOT_S for t, wind in session.winds if wind is not None]
    assert min(blowing) == pytest.approx(start_s + 0.02, abs=1e-3)
    assert max(blowing) == pytest.approx(over_s, abs=1e-3)
    assert session.simulator is not None and session.simulator.wind is None
    assert "the autopilot landed" in texts(result)  # the plan went on
    assert not any("watching" in text for text in texts(result))


def test_a_landed_run_ends_once_at_rest_and_without_faults_nothing_is_injected(fly) -> None:
    spec = scenario(flight={**FLIGHT, "hold_s": 2.0}, expect={"disarmed": True})
    result, session = fly(spec)
    assert result.verdict is Verdict.PASSED
    landed_s = at(result, "the autopilot landed")
    assert result.sim_time_s == pytest.approx(landed_s + 2.0, abs=0.1) and result.sim_time_s < 20
    assert session.command.aux_us[:2] == (1000, 1000) and len(session.command.aux_us) == 2


def test_a_crash_is_judged_not_an_error(fly) -> None:
    spec = scenario(flight=FLIGHT, expect={"crashed": True})
    result, session = fly(spec, tilt_deg=85.0)
    assert result.verdict is Verdict.PASSED, result.reason
    crash = next(e for e in result.events if e.text.startswith("crash: the vehicle tipped over"))
    assert crash.time_s < 0.1 and session.closed


# -- runs that end early -------------------------------------------------------------------------
def test_arming_blocked_is_an_error_with_the_blockers_and_the_session_closed(fly) -> None:
    spec = scenario(flight=FLIGHT)
    result, session = fly(spec, arm_error=ArmingBlockedError("blocked by RXLOSS", ("RXLOSS",)))
    assert result.verdict is Verdict.ERROR and result.reason == "blocked by RXLOSS"
    assert result.checks == [] and session.closed and session.samples == 0
    summary = json.loads(result.artifacts["summary"].read_text())
    assert summary["verdict"] == "error" and summary["reason"] == "blocked by RXLOSS"


def test_a_sitl_that_exits_mid_flight_is_an_error_and_what_was_flown_is_kept(fly) -> None:
    spec = scenario(flight=FLIGHT)
    result, session = fly(
        spec,
        fail_after=120,
        failure=SitlExitedError("the SITL exited with code 139\nits last output: ..."),
    )
    assert result.verdict is Verdict.ERROR
    assert result.reason == "the SITL exited with code 139"  # the first line
    assert session.closed and len(read_flight_log(result.artifacts["log"])) == 120


def test_ctrl_c_propagates_after_the_session_closed_and_the_summary_is_written(
    fly, tmp_path
) -> None:
    with pytest.raises(KeyboardInterrupt):
        fly(scenario(flight=FLIGHT), fail_after=50, failure=KeyboardInterrupt())
    summary = json.loads((tmp_path / "out" / "result.json").read_text())
    assert summary["verdict"] == "error"
    assert len(read_flight_log(tmp_path / "out" / "flight.csv")) == 50


def test_the_firmware_version_is_the_one_the_running_fc_reports(fly) -> None:
    reported = replace(V46, firmware_version="4.6.1")
    result, _session = fly(scenario(flight={**FLIGHT, "hold_s": 1.0}), firmware=reported)
    assert result.firmware_version == "4.6.1"
    result, _session = fly(scenario(flight={**FLIGHT, "hold_s": 1.0}))
    assert result.firmware_version == "4.6.0"  # the binary's, unasked


# -- the files ----------------------------------------------------------------------------------
def test_the_files_of_a_run_blackbox_sitl_log_plot_and_mcap(fly, tmp_path) -> None:
    """A blackbox file the decoder cannot read is copied, listed and told as an event; the
    expectation on it fails with why.  The SITL's log, the plot and the MCAP are listed."""
    out = tmp_path / "out"
    (out / "sitl").mkdir(parents=True)
    (out / "sitl" / "LOG00001.BFL").write_bytes(b"not a log")
    spec = scenario(
        flight={**FLIGHT, "hold_s": 1.0},
        expect={"disarmed": True, "blackbox_disarm_reason": "SWITCH"},
    )
    sitl = SimpleNamespace(log_path=out / "sitl" / "sitl.log")
    result, _session = fly(
        spec, sitl=sitl, options=RunOptions(out, plot=True, mcap=True, shares_cores=True)
    )
    assert result.verdict is Verdict.FAILED
    assert result.reason == "blackbox_disarm_reason = 'SWITCH': no disarm event in the blackbox"
    assert result.artifacts["blackbox"] == out / "blackbox" / "LOG00001.BFL"
    assert result.artifacts["blackbox"].read_bytes() == b"not a log"
    assert any(
        t.startswith("blackbox LOG00001.BFL: ") and "is not a blackbox log" in t
        for t in texts(result)
    )
    assert result.artifacts["sitl_log"] == sitl.log_path
    assert result.artifacts["plot"] == out / "plot.png" and (out / "plot.png").stat().st_size
    assert result.artifacts["mcap"] == out / "flight.mcap" and (out / "flight.mcap").stat().st_size
    assert "blackbox_plot" not in result.artifacts  # nothing decoded to plot
    summary = json.loads((out / "result.json").read_text())
    assert set(summary["artifacts"]) == {"log", "mcap", "sitl_log", "blackbox", "plot", "trace"}


@pytest.mark.parametrize(
    ("expect", "plot", "drawn"),
    [
        ({"disarmed": True}, "failed", False),  # passed: nobody looks, nothing drawn
        ({"disarmed": False}, "failed", True),  # failed: the plot to look at
        ({"disarmed": True}, True, True),
        ({"disarmed": False}, False, False),
    ],
)
def test_a_run_draws_its_plot_as_asked_and_by_default_only_when_it_did_not_pass(
    fly, tmp_path, expect, plot, drawn
) -> None:
    out = tmp_path / "out"
    spec = scenario(flight={**FLIGHT, "hold_s": 1.0}, expect=expect)
    result, _session = fly(spec, options=RunOptions(out, plot=plot))
    assert result.verdict is (Verdict.PASSED if expect["disarmed"] else Verdict.FAILED)
    assert ("plot" in result.artifacts) is drawn
    assert (out / "plot.png").exists() is drawn
    assert ("plots" in result.timings_s) is drawn
    assert (out / "trace.csv").stat().st_size  # every other file as before
    assert (out / "result.json").stat().st_size


def test_by_default_only_a_failed_or_errored_run_draws_plots() -> None:
    from bfsitl.scenario.result import wants_plot

    drawn = {v for v in Verdict if wants_plot("failed", v)}
    assert drawn == {Verdict.FAILED, Verdict.ERROR}  # a known failure is expected, as xfail
    assert all(wants_plot(True, v) and not wants_plot(False, v) for v in Verdict)


def test_runs_that_share_the_cores_do_not_spin(fly, tmp_path) -> None:
    spec = scenario(flight={**FLIGHT, "hold_s": 1.0})
    run_options = RunOptions(tmp_path / "out", plot=False, shares_cores=True, speed=3.0)
    _result, session = fly(spec, options=run_options)
    timing = session.session_config.timing
    assert not timing.lockstep_spin and timing.speed == 3.0


# -- known firmware defects ----------------------------------------------------------------------
KNOWN_CRASH = [{"finding": "crash", "why": "a known defect", "see": "firmware finding 9"}]


def test_a_declared_defect_that_happens_is_a_known_failure_not_a_pass(
    fly, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The crash analyser's finding, as a real fall gives it (the analysers have tests of
    # their own; here the verdict is judged).
    analysed = run._analyse

    def with_a_crash(watch: Any, trace: Any, result: Any) -> None:
        analysed(watch, trace, result)
        crash = Finding("crash", Severity.FAILURE, "hit the ground at 7 m/s", 1.0, 7.0, "m/s")
        result.findings = trace.findings = [crash, *result.findings]

    monkeypatch.setattr(run, "_analyse", with_a_crash)
    spec = scenario(flight=FLIGHT, expect={"crashed": True}, known_failure=KNOWN_CRASH)
    result, _session = fly(spec, tilt_deg=85.0)
    assert result.verdict is Verdict.KNOWN
    assert result.reason == "known failure: a known defect (firmware finding 9)"
    (known,) = [c for c in result.checks if c.expectation.startswith("known_failure")]
    assert known.passed and "crash found failure" in known.message


def test_a_declared_defect_that_does_not_happen_fails_saying_it_may_be_fixed(fly) -> None:
    spec = scenario(flight=FLIGHT, known_failure=KNOWN_CRASH)
    result, _session = fly(spec)
    assert result.verdict is Verdict.FAILED
    assert "the known failure did not happen (crash found nothing): fixed?" in result.reason


def test_a_defect_of_the_other_generation_is_not_expected(fly) -> None:
    only_master = [{**KNOWN_CRASH[0], "generation": "master"}]
    result, _session = fly(scenario(flight=FLIGHT, known_failure=only_master))
    assert result.verdict is Verdict.PASSED  # the fake is a 4.6.0


def test_ctrl_c_as_the_start_up_ends_still_closes_the_session(
    fly, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The session's close is registered as it is entered, inside the block that closes it:
    a Ctrl-C arriving just after the start-up (here: as its timing ends) stops the SITL."""
    from bfsitl.scenario.timings import Stopwatch

    class InterruptedStartUp(Stopwatch):
        @contextlib.contextmanager
        def span(self, phase: str):  # type: ignore[no-untyped-def]
            with super().span(phase):
                yield
            if phase == "start-up":
                raise KeyboardInterrupt

    monkeypatch.setattr(run, "Stopwatch", InterruptedStartUp)
    closed: list[bool] = []
    monkeypatch.setattr(FailsafeSession, "close", lambda self: closed.append(True))
    with pytest.raises(KeyboardInterrupt):
        fly(scenario(flight=FLIGHT, fault=[RC_LOST_AT_8], expect={"disarmed": True}))
    assert closed == [True]


def test_a_session_that_cannot_be_made_leaves_no_flight_log_open(tmp_path: Path) -> None:
    """Preparing the FC or making the session may raise: the flight's files are opened only
    after, next to the block that closes them (they were left open before)."""
    from bfsitl.errors import SitlError

    open_then: list[str] = []

    def no_session(*_args: Any, **_kwargs: Any) -> FailsafeSession:
        open_then.extend(name for name in _open_files() if name.endswith("flight.csv"))
        raise SitlError("no SITL here")

    options = RunOptions(tmp_path / "out", plot=False, session_factory=no_session)
    options = dataclasses.replace(options, prepared_fc=False)
    result = run.run_scenario(scenario(flight=FLIGHT), str(fake_binary(tmp_path)), options)
    assert result.verdict is Verdict.ERROR and "no SITL here" in result.reason
    assert open_then == []  # nothing was open when it raised, so nothing waits to be closed


def _open_files() -> list[str]:
    names = []
    for fd in os.listdir("/proc/self/fd"):
        with contextlib.suppress(OSError):  # the listing's own descriptor is gone by now
            names.append(os.readlink(f"/proc/self/fd/{fd}"))
    return names


def test_a_scenarios_own_debug_mode_is_not_read_as_failsafe_phases(fly) -> None:
    # debug[3] holds the phase only with debug_mode = FAILSAFE: under another mode the
    # runner would read whatever that mode puts there as phases (RC_SMOOTHING's sample state
    # flips each frame: thousands of "phase" changes).  Here the fake FC still answers the
    # phase in debug[3], so reading it anyway would show.
    spec = scenario(
        flight=FLIGHT,
        cli=["set debug_mode = gyro_scaled"],
        fault=[RC_LOST_AT_8],
        expect={"disarmed": True, "failsafe_phase": ["RX_LOSS_DETECTED"]},
    )
    result, session = fly(spec)
    events = texts(result)
    assert events[0].startswith("debug_mode = GYRO_SCALED: the FC's failsafe phase is not read")
    assert not [e for e in events if e.startswith("failsafe phase")]
    assert "the FC disarmed" in events  # the flight itself as before
    assert MspCommand.DEBUG not in session.fc_link.sent_commands  # nor asked for
    check = next(c for c in result.checks if c.expectation.startswith("failsafe_phase"))
    assert not check.passed and "never read" in check.message
    assert result.verdict is Verdict.FAILED


def test_the_last_debug_mode_line_decides_and_failsafe_is_read() -> None:
    from bfsitl.scenario.setup_lines import failsafe_phase_unread, setting_in_force

    lines = ["set debug_mode = FAILSAFE", "set  DEBUG_MODE=rc_smoothing", "save"]
    assert setting_in_force(lines, "debug_mode") == "RC_SMOOTHING"
    assert setting_in_force([*lines, "set debug_mode = failsafe"], "debug_mode") == "FAILSAFE"
    assert setting_in_force(["set debug_mode_x = A", "get debug_mode"], "debug_mode") is None
    assert failsafe_phase_unread([*lines, "set debug_mode = failsafe"]) is None
    assert failsafe_phase_unread(["feature GPS"]) is None
    assert "RC_SMOOTHING" in (failsafe_phase_unread(lines) or "")
