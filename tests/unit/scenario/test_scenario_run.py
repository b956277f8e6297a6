"""The scenario runner's parts without a SITL: what a run provisions, the fault injector's
timing and trace, the watch's end, and the endings that skip or fail before a flight (each
still writes its result.json)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from support.flight_rows import make_row
from support.scenario_files import MASTER, V46, fake_binary, scenario

from bfsitl.backend.embedded import RealTimeBackend
from bfsitl.errors import MspTimeoutError
from bfsitl.fc.rc_link import RcCommand
from bfsitl.mission.vehicle import FlightSample
from bfsitl.physics import IRIS, Simulator
from bfsitl.protocol.boxes import BoxId
from bfsitl.protocol.firmware_profile import BuildOptions, profile_for
from bfsitl.scenario import run
from bfsitl.scenario.faults import make_faults, read_fault_spec
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.run import RunOptions, _Injector, run_scenario
from bfsitl.scenario.setup_lines import blackbox_cli, hover_throttle_line, scenario_profile
from bfsitl.scenario.trace import Trace


def test_a_run_provisions_the_blackbox_the_hover_throttle_and_the_scenarios_lines_last() -> None:
    plain = scenario(cli=["set failsafe_procedure = DROP"])
    profile = scenario_profile(plain, V46, ())
    lines = profile.cli_lines
    assert "set blackbox_device = VIRTUAL" in lines and "set debug_mode = FAILSAFE" in lines
    assert hover_throttle_line(IRIS) in lines and hover_throttle_line(IRIS).endswith("1545")
    assert lines[-1] == "set failsafe_procedure = DROP"  # the scenario's own lines win
    assert not any(r.box_id == BoxId.FAILSAFE for r in profile.mode_ranges)
    switch = make_faults(
        (read_fault_spec({"kind": "rc_loss", "at_s": 5.0}, where="t", number=1, run_s=20.0),), V46
    )
    with_switch = scenario_profile(plain, V46, switch)
    assert any(
        r.box_id == BoxId.FAILSAFE and r.aux_channel_index == 2 for r in with_switch.mode_ranges
    )
    assert "1/16" in " ".join(blackbox_cli(V46)) and "1/4" in " ".join(blackbox_cli(MASTER))
    # The fields nothing reads are left out: the decode is a run's largest cost after flying.
    assert "set blackbox_disable_pids = ON" in blackbox_cli(V46)
    assert "set blackbox_disable_gyrounfilt = ON" in blackbox_cli(MASTER)


class Client:
    def get(self, _message: object) -> object:
        raise MspTimeoutError("no debug here")


class Vehicle:
    """What the injector touches: the sticks, the disturbance surface, the MSP client."""

    def __init__(self) -> None:
        self.simulator = Simulator(IRIS)
        self.backend = RealTimeBackend(self.simulator, speed=1.0, progress=print)
        self.disturbances = self.backend.disturbances
        self.rc_command = RcCommand()
        self.client = Client()

    def set_rc(self, command: RcCommand) -> None:
        self.rc_command = command

    def reading(self, message_type: Any, sample: Any = None) -> Any:
        return self.client.get(message_type)


def sample(
    time_s: float, *, armed: bool = True, modes: tuple[str, ...] = ("ANGLE",)
) -> FlightSample:
    return FlightSample(
        time_s=time_s,
        wall_s=0.0,
        fc_alt_m=1.0,
        fc_climb_m_s=0.0,
        fc_accel_up_m_s2=0.0,
        roll_deg=0.0,
        pitch_deg=0.0,
        yaw_deg=0.0,
        sim_alt_m=1.0,
        sim_climb_m_s=0.0,
        sim_tilt_deg=0.0,
        sim_roll_deg=0.0,
        sim_pitch_deg=0.0,
        sim_yaw_deg=0.0,
        on_ground=False,
        armed=armed,
        arming_blockers=(),
        flight_modes=modes,
        motors=(0.5,) * 4,
        rc=RcCommand(),
    )


def test_the_injector_applies_each_fault_on_time_undoes_it_and_keeps_the_trace() -> None:
    specs = tuple(
        read_fault_spec(raw, where="t", number=n, run_s=20.0)
        for n, raw in (
            (
                1,
                {
                    "kind": "motor_thrust",
                    "motor": 2,
                    "fraction": 0.5,
                    "at_s": 1.0,
                    "duration_s": 1.0,
                },
            ),
            (2, {"kind": "rc_loss", "at_s": 3.0}),
        )
    )
    vehicle = Vehicle()
    trace, events, recorded = Trace(), [], []
    injector = _Injector(
        vehicle,
        make_faults(specs, V46),
        trace,
        events,  # type: ignore[arg-type]
        progress=lambda _line: None,
        record=recorded.append,
    )
    injector.on_row(make_row(0), sample(0.5))
    assert trace.rows == []  # not armed yet: nothing is watched
    injector.armed_at_s = 10.0
    thrust = []
    for step in range(1, 45):
        t = 10.0 + step * 0.1
        injector.on_row(
            make_row(step), sample(t, modes=("ANGLE",) if t < 13.5 else ("ANGLE", "FS"))
        )
        thrust.append(vehicle.simulator.motor_thrust[1])
        stop = injector.stop(sample(t))
        assert (stop is not None) == (t >= 13.0 - 1e-9)
    assert trace.fault_times_s == pytest.approx([1.0, 3.0])
    assert 0.5 in thrust and thrust[-1] == 1.0  # weak for a second, then recovered
    assert vehicle.rc_command.aux_us[2] == 1800  # the failsafe switch is on
    texts = [e.text for e in events]
    assert texts[0].startswith("motor 2 at 50 %") and "motor 2 at 50 % thrust: over" in texts
    assert "flight mode FS on" in texts and texts == recorded
    assert len(trace.rows) == 44 and trace.rows[0].failsafe_phase is None
    # The analysers watch the same steps, on the trace's clock (seconds from arming).
    points = injector.watch.track.points
    assert [p.time_s for p in points] == [r.time_s for r in trace.rows]
    assert points[0].time_s == pytest.approx(0.1) and points[-1].modes == ("ANGLE", "FS")


def test_a_scenario_that_needs_gps_skips_a_build_without_it(tmp_path: Path) -> None:
    binary = fake_binary(tmp_path)
    gps_only = scenario(requires_gps=True)
    result = run_scenario(gps_only, str(binary), RunOptions(tmp_path / "out"))
    assert result.verdict is Verdict.SKIPPED and "--gps" in result.reason
    summary = json.loads((tmp_path / "out" / "result.json").read_text())
    assert summary["verdict"] == "skipped" and summary["reason"] == result.reason


def test_a_fault_the_firmware_cannot_express_skips_before_anything_starts(tmp_path) -> None:
    binary = fake_binary(tmp_path)
    silence = scenario(fault=[{"kind": "rc_loss", "method": "silence", "at_s": 5.0}])
    result = run_scenario(silence, str(binary), RunOptions(tmp_path / "out"))
    assert result.verdict is Verdict.SKIPPED and "holds the last sticks" in result.reason
    assert not (tmp_path / "out" / "sitl").exists()  # no SITL was started


def test_without_an_rc_rate_a_build_counting_frames_takes_the_stock_receivers_faults(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    counting = profile_for("1.47", "4.6.0", BuildOptions(receiver_frames=True))
    monkeypatch.setattr(run, "profile_of_binary", lambda _path: counting)
    silence = [{"kind": "rc_loss", "method": "silence", "at_s": 5.0}]
    binary = str(fake_binary(tmp_path))
    per_packet = scenario(fault=silence, rc={"rate_hz": "packet"})
    result = run_scenario(per_packet, binary, RunOptions(tmp_path / "packet"))
    assert result.verdict is Verdict.SKIPPED and "holds the last sticks" in result.reason
    # At the default rate the same build loses the link on silence: the fault is made and
    # the run goes on to start the (fake, unstartable) firmware.
    at_rate = run_scenario(scenario(fault=silence), binary, RunOptions(tmp_path / "rate"))
    assert at_rate.verdict is Verdict.ERROR and "holds the last sticks" not in at_rate.reason


def test_a_missing_firmware_is_an_error_with_its_summary(tmp_path) -> None:
    result = run_scenario(scenario(), str(tmp_path / "nowhere"), RunOptions(tmp_path / "out"))
    assert result.verdict is Verdict.ERROR and result.reason
    assert json.loads((tmp_path / "out" / "result.json").read_text())["verdict"] == "error"
