"""A real flight's replay as a scenario (``[replay]``): the file read and checked, the run's
figures and expectations from the two logs, and the A/B verdict they give.  The "quads" are
first-order lags from setpoint to gyro (tests/support/synthetic_log.py), so the right answer
is known; the real firmware's side is tests/integration/test_log_replay_sitl.py."""

from __future__ import annotations

import dataclasses
import importlib
import math
from pathlib import Path
from typing import Any

import pytest

from bfsitl.backend.options import Timing
from bfsitl.errors import ScenarioError
from bfsitl.physics.wind import Wind
from bfsitl.replay.compare import compare_logs
from bfsitl.replay.flight import ReplayedFlight
from bfsitl.replay.header_settings import header_settings
from bfsitl.replay.replay_log import Replay
from bfsitl.replay.sticks import stick_stream
from bfsitl.scenario import expect_replay
from bfsitl.scenario.compare import (
    Change,
    RcRate,
    Side,
    compare_results,
    plan_comparison,
    seeds_for,
)
from bfsitl.scenario.expectations import check_expectations, judge
from bfsitl.scenario.load import load_scenario
from bfsitl.scenario.metrics import replay_metrics
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.spec import scenario_from_dict
from bfsitl.scenario.trace import Trace
from tests.support.scenario_files import V46
from tests.support.synthetic_log import lagged_log, pilot_sticks


def _replay_file(tmp_path: Path, body: str) -> Path:
    (tmp_path / "flights").mkdir(exist_ok=True)
    (tmp_path / "flights" / "LOG00007.BFL").write_bytes(b"H Product:Blackbox\n")
    path = tmp_path / "my-flight.toml"
    path.write_text(body)
    return path


REPLAY = '[replay]\nlog = "flights/LOG00007.BFL"\n'
FLIGHT = {"takeoff_alt_m": 2.0}


def test_a_replay_scenario_reads_its_log_beside_it_and_flies_a_real_size_quad(
    tmp_path: Path,
) -> None:
    path = _replay_file(
        tmp_path, REPLAY + 'index = 2\n[expect]\nno_finding = "crash"\nmax_gyro_off_real = 0.3\n'
    )
    scenario = load_scenario(path)
    assert scenario.replay is not None
    assert scenario.replay.log == (tmp_path / "flights" / "LOG00007.BFL").resolve()
    assert scenario.replay.index == 2
    # No [vehicle]: the 5-inch, not IRIS (a real log comes from a real quad).
    assert scenario.quad.name == "5inch-freestyle" and not scenario.own_vehicle
    assert scenario.faults == () and scenario.duration_s == 0.0
    own = load_scenario(_replay_file(tmp_path, REPLAY + '[vehicle]\nmodel = "7inch-longrange"\n'
                                     '[expect]\nworst_finding = "warning"\n'))  # fmt: skip
    assert own.quad.name == "7inch-longrange" and own.own_vehicle


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ('[replay]\nlog = "flights/nope.BFL"\n[expect]\nno_finding = "crash"\n', "no such file"),
        (REPLAY + 'index = 0\n[expect]\nno_finding = "crash"\n', "index = 0"),
        (REPLAY + 'speed = 2\n[expect]\nno_finding = "crash"\n', "unknown key(s) speed"),
        (
            "duration_s = 30\n" + REPLAY + '[expect]\nno_finding = "crash"\n',
            "duration_s cannot go with it",
        ),
        (
            REPLAY + '[flight]\ntakeoff_alt_m = 2\n[expect]\nno_finding = "crash"\n',
            "flight cannot go with it",
        ),
        (REPLAY + "[expect]\nlanded_within_m = 3\n", "landed_within_m is about a flight"),
        ('replay = "x"\n[expect]\nno_finding = "crash"\n', "[replay] must be a table"),
        (REPLAY + '[rc]\nrate_hz = 50\n[expect]\nno_finding = "crash"\n', "its log's frames"),
    ],
)
def test_a_bad_replay_scenario_fails_when_read_in_one_line(
    tmp_path: Path, body: str, says: str
) -> None:
    with pytest.raises(ScenarioError) as caught:
        load_scenario(_replay_file(tmp_path, body))
    message = str(caught.value)
    assert says in message and "\n" not in message and "my-flight.toml" in message


def test_a_replays_expectation_needs_a_replay() -> None:
    data = {"duration_s": 20.0, "flight": FLIGHT, "expect": {"replay_targets_met": True}}
    with pytest.raises(ScenarioError, match="needs a \\[replay\\] table"):
        check_expectations(scenario_from_dict(data, name="t"))


def test_a_replay_flies_one_seed_unless_gusts_make_seeds_differ(tmp_path: Path) -> None:
    path = _replay_file(tmp_path, REPLAY + '[expect]\nno_finding = "crash"\n')
    replay = load_scenario(path)
    assert seeds_for(replay, 3) == 1
    steady = Wind(velocity_ned_m_s=(3.0, 0.0, 0.0))
    assert seeds_for(dataclasses.replace(replay, wind=steady), 3) == 1
    assert seeds_for(dataclasses.replace(replay, wind=Wind(gust_std_m_s=1.0)), 3) == 3
    flown = scenario_from_dict(
        {"duration_s": 20.0, "flight": FLIGHT, "expect": {"disarmed": True}}, name="t"
    )
    assert seeds_for(flown, 3) == 3


COMMAND = pilot_sticks(4)
REAL = lagged_log(COMMAND, tau_s=0.02)


def _figures(tau_s: float) -> dict[str, float | None]:
    return replay_metrics(compare_logs(REAL, lagged_log(COMMAND, tau_s=tau_s)), []).values


def test_a_replays_figures_say_how_each_axis_followed_its_setpoint_and_the_real_flight() -> None:
    same, slow = _figures(0.02), _figures(0.04)
    for axis in ("roll", "pitch", "yaw"):
        # The same quad: the gyro lies on the real one; a slower one trails its setpoint more,
        # rises later and strays from the real flight.
        assert same[f"{axis}_off_real"] == pytest.approx(0.0, abs=0.01)
        assert slow[f"{axis}_off_real"] > 0.1  # type: ignore[operator]
        assert slow[f"{axis}_tracking_dps"] > 1.3 * same[f"{axis}_tracking_dps"]  # type: ignore[operator]
        # A first-order lag rises from 10 % to 90 % in 2.2 time constants (the windowed
        # estimate comes out a little short of it).
        assert same[f"{axis}_rise_ms"] == pytest.approx(44.0, rel=0.12)
        assert 1.6 < slow[f"{axis}_rise_ms"] / same[f"{axis}_rise_ms"] < 2.2  # type: ignore[operator]
        assert same[f"{axis}_overshoot_pct"] == pytest.approx(0.0, abs=2.0)
    assert same["motor_mean_pct"] == pytest.approx(slow["motor_mean_pct"])


def _result(tau_s: float, side: str) -> ScenarioResult:
    result = ScenarioResult("my-flight", side, Verdict.PASSED, "")
    result.metrics = _figures(tau_s)
    result.behaviour = {"findings": []}
    return result


def test_a_slower_replay_on_b_is_worse_and_the_same_replay_is_the_same(tmp_path: Path) -> None:
    scenario = load_scenario(_replay_file(tmp_path, REPLAY + '[expect]\nno_finding = "crash"\n'))
    sides = (Side("A", "fw"), Side("B", "fw", ("set p_roll = 20",)))
    planned = plan_comparison([scenario], sides, 3, tmp_path / "cmp")
    assert len(planned) == 2  # one seed each: a replay repeats bit for bit
    # A side's RC link rate is not a replay's: it sends its log's frames at their own rate.
    at_50 = (sides[0], Side("B", "fw", rc_rate=RcRate(50.0)))
    (a, b) = plan_comparison([scenario], at_50, 3, tmp_path / "cmp")
    assert b.run.scenario.rc_rate_hz == a.run.scenario.rc_rate_hz == scenario.rc_rate_hz
    (same,) = compare_results(planned, [_result(0.02, "a"), _result(0.02, "b")], sides)
    assert same.change is Change.SAME, same.reason
    (slower,) = compare_results(planned, [_result(0.02, "a"), _result(0.04, "b")], sides)
    assert slower.change is Change.CHANGED, slower.reason  # worse figures and a slower rise
    judged = {figure.name: figure.change for figure in slower.figures}
    assert judged["roll_tracking_dps"] is Change.WORSE
    assert judged["roll_rise_ms"] is Change.CHANGED  # slower is a change, not better or worse
    assert judged["motor_mean_pct"] is Change.SAME
    assert "roll_tracking_dps" in slower.reason


def _replay_scenario(tmp_path: Path, expect: str) -> Any:
    return load_scenario(_replay_file(tmp_path, REPLAY + "[expect]\n" + expect))


@pytest.mark.parametrize(
    ("expect", "tau_s", "passes"),
    [
        ("replay_targets_met = true\n", 0.02, True),
        ("replay_targets_met = true\n", 0.04, False),
        ("replay_targets_met = false\n", 0.04, True),
        ("min_setpoint_correlation = 0.99\n", 0.04, True),
        ("max_gyro_off_real = 0.05\n", 0.02, True),
        ("max_gyro_off_real = 0.05\n", 0.04, False),
    ],
)
def test_a_replays_expectations_are_judged_on_the_two_logs(
    tmp_path: Path, expect: str, tau_s: float, passes: bool
) -> None:
    scenario = _replay_scenario(tmp_path, expect)
    comparison = compare_logs(REAL, lagged_log(COMMAND, tau_s=tau_s))
    (check,) = judge(scenario, Trace(replay=comparison))
    assert check.passed is passes, check.message
    if "gyro" in expect:
        assert "the largest is" in check.message


def test_a_replays_expectation_on_a_run_that_replayed_nothing_fails_saying_so() -> None:
    check = expect_replay.min_setpoint_correlation("min_setpoint_correlation", 0.99, Trace(), {})
    assert not check.passed and "replayed no log" in check.message
    check = expect_replay.replay_targets("replay_targets_met", True, Trace(), {})
    assert not check.passed and "replayed no log" in check.message


def test_a_replay_run_fills_the_result_from_the_replay(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The runner's replay branch without a SITL: the log read, the replay's lines (the side's
    and the scenario's after the log's), its figures, files, findings and verdict."""
    run = importlib.import_module("bfsitl.scenario.replay_run")
    scenario = dataclasses.replace(
        _replay_scenario(tmp_path, 'max_gyro_off_real = 0.05\nno_finding = "crash"\n'),
        cli=("set p_roll = 20",),
        seed=7,
    )
    replayed = lagged_log(COMMAND, tau_s=0.04)
    asked: dict[str, Any] = {}

    def fake_replay(log: Any, **kwargs: Any) -> Replay:
        asked.update(kwargs)
        blackbox = kwargs["out_dir"] / "replay.BFL"
        blackbox.write_bytes(b"")
        given = (*kwargs["extra_cli"], "set blackbox_device = VIRTUAL")
        flight = ReplayedFlight(blackbox, "4.6.0", 100, flown_s=20.0, wall_s=1.0, cli_lines=given)
        return Replay(
            log,
            kwargs["quad"].name,
            header_settings(log.headers),
            stick_stream(log),
            flight,
            compare_logs(log, replayed),
            replayed,
        )

    monkeypatch.setattr(run, "pick_log", lambda path, index: REAL)
    monkeypatch.setattr(run, "replay_log", fake_replay)
    result = ScenarioResult("my-flight", "fw", Verdict.ERROR, "")
    lines: list[str] = []
    timing = Timing(lockstep_spin=False)
    run.fly_replay_scenario(
        dataclasses.replace(scenario, side_cli=("set f_roll = 0",)),
        Path("fw"),
        V46,
        tmp_path,
        result,
        lines.append,
        plot=False,
        timing=timing,
    )
    # The side's lines, then the scenario's, after the log's own (replay_log adds those).
    assert asked["extra_cli"] == ("set f_roll = 0", "set p_roll = 20") and asked["seed"] == 7
    assert asked["timing"] is timing  # a suite sharing the cores does not spin
    sources = {line: source for source, line, _ in result.settings}
    assert sources["set f_roll = 0"] == "the side" and sources["set p_roll = 20"] == "the scenario"
    assert sources["set blackbox_device = VIRTUAL"] == "bfsitl"  # what the replay adds itself
    assert asked["quad"].name == "5inch-freestyle"
    assert result.verdict is Verdict.FAILED and "max_gyro_off_real" in result.reason
    assert result.metrics["roll_rise_ms"] == pytest.approx(_figures(0.04)["roll_rise_ms"])
    assert (tmp_path / "replay-report.json").is_file()
    assert result.artifacts["replay_report"] == tmp_path / "replay-report.json"
    assert result.sim_time_s == 20.0 and "loss_of_control" in result.watched
    # The synthetic log has no attitude, so the crash analyser could not watch: its silence
    # is no pass.
    crash = next(c for c in result.checks if "crash" in c.expectation)
    assert not crash.passed and "could not watch this run" in crash.message
    assert any("settings carried over" in event.text for event in result.events)
    assert lines and "reading" in lines[0]


def test_the_pytest_plugin_takes_a_replay_file_for_a_scenario(tmp_path: Path) -> None:
    from bfsitl.pytest_plugin import _looks_like_scenario

    assert _looks_like_scenario(_replay_file(tmp_path, REPLAY + '[expect]\nno_finding = "crash"\n'))
    assert not _looks_like_scenario(_replay_file(tmp_path, REPLAY))


def test_a_replays_vehicle_table_without_a_model_keeps_the_5_inch(tmp_path: Path) -> None:
    heavier = load_scenario(
        _replay_file(tmp_path, REPLAY + "[vehicle]\nmass_kg = 0.75\n[expect]\n"
                     'worst_finding = "warning"\n')
    )  # fmt: skip
    assert heavier.quad.name == "5inch-freestyle, 0.75 kg" and heavier.own_vehicle
    with pytest.raises(ScenarioError, match="heading_deg cannot go with it"):
        load_scenario(
            _replay_file(tmp_path, REPLAY + "[vehicle]\nheading_deg = 90\n[expect]\n"
                         'worst_finding = "warning"\n')
        )  # fmt: skip


def test_an_axis_that_turns_the_wrong_way_has_no_step_figures_on_that_side() -> None:
    inverted = lagged_log(COMMAND, tau_s=0.02)
    inverted = dataclasses.replace(
        inverted,
        frames=tuple(
            dataclasses.replace(f, gyro_adc=(-f.gyro_adc[0], *f.gyro_adc[1:]))
            for f in inverted.frames
        ),
    )
    figures = replay_metrics(compare_logs(REAL, inverted), []).values
    assert figures["roll_rise_ms"] is None and figures["roll_overshoot_pct"] is None
    assert figures["pitch_rise_ms"] is not None
    assert all(v is None or math.isfinite(v) for v in figures.values())


def test_the_lowest_setpoint_correlation_is_judged_and_an_axis_that_never_moved_is_said(
    tmp_path: Path,
) -> None:
    scenario = _replay_scenario(tmp_path, "min_setpoint_correlation = 0.99\n")
    comparison = compare_logs(REAL, lagged_log(COMMAND, tau_s=0.02))

    def with_correlations(*values: float) -> Trace:
        axes = tuple(
            dataclasses.replace(axis, setpoint_correlation=value)
            for axis, value in zip(comparison.axes, values, strict=True)
        )
        return Trace(replay=dataclasses.replace(comparison, axes=axes))

    for order in ((0.995, 0.98, math.nan), (math.nan, 0.98, 0.995)):
        (check,) = judge(scenario, with_correlations(*order))
        assert not check.passed and "the lowest is 0.9800 (pitch)" in check.message
        assert "never moved (not judged)" in check.message
    (check,) = judge(scenario, with_correlations(0.995, 0.999, math.nan))
    assert check.passed
    (check,) = judge(scenario, with_correlations(math.nan, math.nan, math.nan))
    assert not check.passed and "no setpoint moved" in check.message


def test_a_replay_on_a_build_without_lockstep_is_skipped_saying_what_to_build(
    tmp_path: Path,
) -> None:
    from support.scenario_files import fake_binary

    from bfsitl.scenario.run import RunOptions, run_scenario

    scenario = _replay_scenario(tmp_path, 'no_finding = "crash"\n')
    result = run_scenario(scenario, str(fake_binary(tmp_path)), RunOptions(tmp_path / "run"))
    assert result.verdict is Verdict.SKIPPED
    assert "needs a lockstep build" in result.reason and "--lockstep" in result.reason
