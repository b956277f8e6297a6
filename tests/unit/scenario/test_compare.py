"""A/B judging on made-up results: the seeds' spread, the directions, behaviour, findings,
errors, accepting; the plan; what is written."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from junitparser import Failure, JUnitXml

from bfsitl.analysis import Finding, Severity
from bfsitl.errors import ScenarioError
from bfsitl.scenario.compare import (
    Change,
    ComparedRun,
    RcRate,
    Side,
    compare_results,
    plan_comparison,
)
from bfsitl.scenario.compare_output import (
    comparison_lines,
    write_comparison_json,
    write_comparison_junit,
    write_comparison_report,
)
from bfsitl.scenario.planned_run import PlannedRun
from bfsitl.scenario.report import overridden
from bfsitl.scenario.result import CheckResult, ScenarioResult, Verdict
from bfsitl.scenario.setup_lines import hover_throttle_line, provisioned_settings, scenario_profile
from bfsitl.scenario.spec import scenario_from_dict
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from tests.support.scenario_files import V46

SIDES = (
    Side("A", "4.6.0-gps-lockstep"),
    Side("B", "4.6.0-gps-lockstep", ("set ap_hover_throttle = 1275",)),
)


def scenario(name: str = "drop", seed: int = 5):
    return scenario_from_dict(
        {
            "duration_s": 20,
            "seed": seed,
            "cli": ["set x = 1"],
            "flight": {"takeoff_alt_m": 3.0},
            "expect": {"disarmed": True},
        },
        name=name,
    )


def result(
    name: str = "drop",
    *,
    touchdown: float = 1.0,
    tilt: float = 10.0,
    phases: tuple[str, ...] = ("LANDING",),
    findings: tuple[Finding, ...] = (),
    verdict: Verdict = Verdict.PASSED,
    failed: tuple[str, ...] = (),
    **metrics: float | None,
) -> ScenarioResult:
    run = ScenarioResult(name, "fw", verdict, "r")
    run.metrics = {"touchdown_m_s": touchdown, "max_tilt_deg": tilt, **metrics}
    run.behaviour = {
        "phases": list(phases),
        "modes": ["ANGLE"],
        "ended": ["disarmed on the ground"],
    }
    run.findings = list(findings)
    run.checks = [CheckResult(e, e not in failed, e) for e in ("disarmed = true", *failed)]
    return run


def judge(a: list[ScenarioResult], b: list[ScenarioResult], accepted: tuple[str, ...] = ()):
    planned = [
        ComparedRun(side, seed, PlannedRun(scenario(r.name), "fw", Path("x")))
        for side, runs in (("A", a), ("B", b))
        for seed, r in enumerate(runs)
    ]
    (comparison,) = compare_results(planned, [*a, *b], SIDES, accepted)
    return comparison


def test_the_plan_flies_each_seed_on_each_side_with_the_sides_lines_first(tmp_path) -> None:
    planned = plan_comparison([scenario(seed=5)], SIDES, 3, tmp_path)
    assert [(p.side, p.seed) for p in planned] == [
        ("A", 5),
        ("B", 5),
        ("A", 6),
        ("B", 6),
        ("A", 7),
        ("B", 7),
    ]
    b = planned[1].run
    assert b.scenario.seed == 5 and b.firmware == "4.6.0-gps-lockstep"
    # A changed default goes before the scenario's own lines: a scenario that sets it wins.
    assert b.scenario.side_cli == ("set ap_hover_throttle = 1275",)
    assert b.scenario.cli == planned[0].run.scenario.cli == ("set x = 1",)
    lines = scenario_profile(b.scenario, V46, ()).cli_lines
    assert lines.index("set ap_hover_throttle = 1275") < lines.index("set x = 1")
    assert lines.index(hover_throttle_line(b.scenario.quad)) < lines.index(
        "set ap_hover_throttle = 1275"
    )
    sources = {s.line: s.source for s in provisioned_settings(b.scenario, V46, ())}
    assert sources["set ap_hover_throttle = 1275"] == "the side"
    assert sources["set x = 1"] == "the scenario"
    assert sources["set debug_mode = FAILSAFE"] == "bfsitl"
    assert b.out_dir == tmp_path / "B" / "drop" / "seed-5"
    with pytest.raises(ScenarioError, match="at least 1"):
        plan_comparison([scenario()], SIDES, 0, tmp_path)


def test_identical_runs_are_the_same() -> None:
    runs = [result(touchdown=t) for t in (1.0, 1.4, 1.2)]
    comparison = judge(runs, [result(touchdown=t) for t in (1.0, 1.4, 1.2)])
    assert comparison.change is Change.SAME and not comparison.fails
    assert "within the seeds' spread (3 seeds)" in comparison.reason


def test_a_difference_inside_the_seeds_spread_or_the_tolerance_is_the_same() -> None:
    a = [result(touchdown=t) for t in (1.0, 2.0, 1.5)]
    assert judge(a, [result(touchdown=t) for t in (1.9, 2.2, 2.1)]).change is Change.SAME
    # Apart, but by less than touchdown's 0.3 m/s tolerance.
    a = [result(touchdown=1.0)] * 3
    assert judge(a, [result(touchdown=1.25)] * 3).change is Change.SAME


def test_a_figure_beyond_the_spread_is_worse_or_better_by_its_direction() -> None:
    a = [result(touchdown=t) for t in (1.0, 1.2, 1.1)]
    worse = judge(a, [result(touchdown=t) for t in (2.0, 2.3, 2.1)])
    assert worse.change is Change.WORSE and worse.fails
    figure = next(f for f in worse.figures if f.name == "touchdown_m_s")
    assert figure.change is Change.WORSE and figure.b == (2.0, 2.3, 2.1)
    assert "A 1.00..1.20, B 2.00..2.30 m/s" in worse.reason
    better = judge([result(touchdown=t) for t in (2.0, 2.3, 2.1)], a)
    assert better.change is Change.BETTER and not better.fails


def test_a_neutral_figure_beyond_the_spread_is_a_change() -> None:
    a = [result(fault_to_LANDING_s=0.5)] * 2
    changed = judge(a, [result(fault_to_LANDING_s=1.5)] * 2)
    assert changed.change is Change.CHANGED
    assert "fault_to_LANDING_s" in changed.reason
    # Reached on one side only.
    assert judge(a, [result()] * 2).change is Change.CHANGED


def test_better_and_worse_figures_together_are_a_change() -> None:
    a = [result(tilt=30.0, hold_rms_m=0.05)] * 2
    assert judge(a, [result(tilt=10.0, hold_rms_m=0.5)] * 2).change is Change.CHANGED
    # Unless the worse one is how the flight ended: a harder touchdown is worse, however
    # little it tilted on the way down.
    harder = judge([result(touchdown=1.0, tilt=30.0)] * 2, [result(touchdown=3.0, tilt=10.0)] * 2)
    assert harder.change is Change.WORSE


def test_a_different_phase_sequence_or_failed_expectation_is_changed_behaviour() -> None:
    a = [result(phases=("LANDING", "RX_LOSS_MONITORING"))] * 2
    changed = judge(a, [result(phases=("RX_LOSS_MONITORING",))] * 2)
    assert changed.change is Change.CHANGED
    assert changed.differences == [
        "failsafe phases: A LANDING -> RX_LOSS_MONITORING; B RX_LOSS_MONITORING"
    ]
    failing = judge([result()] * 2, [result(failed=("crashed = false",))] * 2)
    assert failing.change is Change.CHANGED
    assert failing.differences == ["expectations: A all met; B crashed = false failed"]
    # One seed of B like one of A: the seeds already disagree, no consistent change.
    mixed = judge(
        [result(phases=("LANDING",)), result(phases=("GPS_RESCUE",))],
        [result(phases=("GPS_RESCUE",)), result(phases=("LANDED",))],
    )
    assert mixed.change is Change.SAME


def crash(severity: Severity = Severity.FAILURE) -> Finding:
    return Finding("crash", severity, "hit the ground", 9.0, 6.0, "m/s")


def test_a_new_finding_on_every_seed_is_worse_even_with_a_better_figure() -> None:
    a = [result(touchdown=1.0, throttle_s=15.0)] * 2
    b = [result(touchdown=1.1, throttle_s=8.0, findings=(crash(),))] * 2
    worse = judge(a, b)
    assert worse.change is Change.WORSE
    assert worse.differences == ["finding crash: A none,none, B failure,failure"]
    assert judge(b, a).change is Change.BETTER
    # A warning on some seeds only: no consistent difference (a failure would be: see below).
    warned = result(touchdown=1.1, throttle_s=8.0, findings=(crash(Severity.WARNING),))
    assert judge(a, [warned, a[0]]).change is Change.SAME


def test_errors_skips_and_accepting() -> None:
    broken = result(verdict=Verdict.ERROR)
    comparison = judge([result()], [broken])
    assert comparison.change is Change.ERROR and comparison.fails
    assert judge([result()], [broken], accepted=("drop",)).fails  # no waiving an error
    skipped = result(verdict=Verdict.SKIPPED)
    assert judge([skipped], [skipped]).change is Change.SKIPPED
    a = [result(touchdown=1.0)]
    accepted = judge(a, [result(touchdown=5.0)], accepted=("drop",))
    assert accepted.change is Change.WORSE and accepted.accepted and not accepted.fails


def test_a_side_may_fly_every_scenario_at_another_rc_link_rate(tmp_path: Path) -> None:
    own = scenario_from_dict(
        {
            "duration_s": 10,
            "flight": {"takeoff_alt_m": 2.0},
            "rc": {"rate_hz": 150},
            "expect": {"disarmed": False},
        },
        name="own",
    )
    sides = (Side("A", "fw"), Side("B", "fw", rc_rate=RcRate(50.0)))
    planned = plan_comparison([own, scenario()], sides, 1, tmp_path)
    rates = [(p.side, p.run.scenario.name, p.run.scenario.rc_rate_hz) for p in planned]
    assert rates == [
        ("A", "own", 150.0),
        ("B", "own", 50.0),
        ("A", "drop", DEFAULT_RC_RATE_HZ),
        ("B", "drop", 50.0),
    ]
    every_packet = Side("B", "fw", rc_rate=RcRate(None))
    (_, b) = plan_comparison([own], (sides[0], every_packet), 1, tmp_path)
    assert b.run.scenario.rc_rate_hz is None
    assert sides[1].title == "B: fw, RC link 50 Hz"
    assert every_packet.title == "B: fw, RC link packet"
    data = json.loads(write_comparison_json([], sides, tmp_path / "c.json").read_text())
    assert "rc_rate_hz" not in data["sides"][0] and data["sides"][1]["rc_rate_hz"] == 50.0


def test_the_rc_rate_options_parse_and_refuse_what_no_receiver_sends() -> None:
    from bfsitl.cli.main import build_parser

    parser = build_parser()
    args = parser.parse_args(
        ["scenario", "compare", "--firmware", "fw", "--a-rc-rate", "packet", "--b-rc-rate", "500"]
    )
    assert (args.a_rc_rate, args.b_rc_rate) == (RcRate(None), RcRate(500.0))
    plain = parser.parse_args(["scenario", "compare", "--firmware", "fw"])
    assert plain.a_rc_rate is None and plain.b_rc_rate is None  # each scenario's own
    with pytest.raises(SystemExit):
        parser.parse_args(["scenario", "compare", "--firmware", "fw", "--b-rc-rate", "5"])


def test_what_a_comparison_writes(tmp_path: Path) -> None:
    same = judge([result("hover")] * 2, [result("hover")] * 2)
    worse = judge([result(touchdown=1.0)] * 2, [result(touchdown=4.0, findings=(crash(),))] * 2)
    comparisons = [same, worse]
    lines = comparison_lines(comparisons)
    assert lines[0].startswith("SAME") and lines[1].startswith("WORSE")
    assert lines[-1] == "1 same, 1 worse"
    data = json.loads(write_comparison_json(comparisons, SIDES, tmp_path / "c.json").read_text())
    assert data["sides"][1]["cli"] == ["set ap_hover_throttle = 1275"]
    assert [s["change"] for s in data["scenarios"]] == ["same", "worse"]
    assert data["scenarios"][1]["fails"] is True
    xml = JUnitXml.fromfile(str(write_comparison_junit(comparisons, SIDES, tmp_path / "c.xml")))
    (suite,) = list(xml)
    cases = {case.name: case for case in suite}
    assert not cases["hover"].result
    (failure,) = cases["drop"].result
    assert isinstance(failure, Failure) and failure.message.startswith("worse: ")
    properties = {p.name: p.value for p in suite.properties()}
    assert properties["drop.change"] == "worse"
    assert properties["drop.touchdown_m_s"] == "A 1,1 | B 4,4 m/s"
    page = write_comparison_report(comparisons, SIDES, tmp_path / "report").read_text()
    assert "B: 4.6.0-gps-lockstep + set ap_hover_throttle = 1275" in page
    assert 'class="verdict worse"' in page and "finding crash" in page


def test_the_report_says_what_each_side_was_given_and_links_each_runs_files(
    tmp_path: Path,
) -> None:
    a_runs, b_runs = [result("hover"), result("hover")], [result("hover"), result("hover")]
    given = [("bfsitl", "set debug_mode = FAILSAFE", "the FC's own log")]
    assert overridden(
        [*given, ("x", "set ap_hover_throttle = 1", ""), ("y", "set ap_hover_throttle = 2", "")]
    ) == [False, True, False]
    for run in a_runs:
        run.settings = list(given)
    for run in b_runs:
        run.settings = [*given, ("the side", "set ap_hover_throttle = 1275", "")]
    summary = tmp_path / "B" / "hover" / "seed-5" / "result.json"
    summary.parent.mkdir(parents=True)
    summary.write_text("{}")
    b_runs[0].artifacts["summary"] = summary
    b_runs[0].artifacts["blackbox"] = tmp_path / "gone.BFL"  # not there: not linked
    page = write_comparison_report([judge(a_runs, b_runs)], SIDES, tmp_path / "report").read_text()
    assert "B only: <code>set ap_hover_throttle = 1275</code> (the side)" in page
    assert page.count("(a later line sets it again)") == 0
    assert "A: the 1 lines its FC was given" in page and "the FC&#x27;s own log" in page
    assert '<a href="../B/hover/seed-5/result.json">summary</a>' in page
    assert "gone.BFL" not in page
    # A side's line the scenario sets again tested nothing: said, and not a difference.
    shadowed_a, shadowed_b = [result("hover")], [result("hover")]
    shadowed_a[0].settings = [("the scenario", "set failsafe_delay = 5", "")]
    shadowed_b[0].settings = [
        ("the side", "set failsafe_delay=20", ""),
        ("the scenario", "set failsafe_delay = 5", ""),
    ]
    shadowed = write_comparison_report(
        [judge(shadowed_a, shadowed_b)], SIDES, tmp_path / "shadowed"
    ).read_text()
    assert "B's <code>set failsafe_delay=20</code> had no effect" in shadowed
    assert "only:" not in shadowed
    same = [result("hover")]
    same[0].settings = list(given)
    assert (
        "Both sides were given the same lines"
        in write_comparison_report([judge(same, same)], SIDES, tmp_path / "again").read_text()
    )


def test_a_new_failure_is_worse_whatever_else_changed() -> None:
    """The hover throttle set too low: B falls instead of landing (a crash on every seed, a
    failed expectation, another ending, less throttle time).  Before, that read "changed",
    with the shorter throttle time as an improvement."""
    a = [result(throttle_s=15.0, findings=(crash(Severity.WARNING),))] * 2
    fell = result(throttle_s=8.0, findings=(crash(),), failed=("max_touchdown_m_s = 2",))
    fell.behaviour["ended"] = ["crashed"]
    verdict = judge(a, [fell, fell])
    assert verdict.change is Change.WORSE
    assert verdict.reason.startswith("new failure: crash (failure on 2 of 2 seeds)")
    (throttle,) = [f for f in verdict.figures if f.name == "throttle_s"]
    assert throttle.change is Change.SKIPPED and "ended otherwise or worse" in throttle.note
    # A crash on one seed of B that A never had is enough.
    assert judge(a, [fell, a[0]]).change is Change.WORSE
    # Back the other way: the crash A had on every seed is gone.
    assert judge([fell, fell], a).change is Change.BETTER
    # A crash both sides have is no news.
    assert judge([fell, fell], [fell, fell]).change is Change.SAME


def test_a_harder_fall_is_worse_however_little_throttle_it_took() -> None:
    """Both sides crash (no new failure), B at twice the speed and sooner: its shorter
    throttle time is no improvement, so the harder touchdown decides."""
    a = [result(touchdown=3.2, throttle_s=15.1, findings=(crash(),))] * 2
    b = [result(touchdown=6.7, throttle_s=8.6, findings=(crash(),))] * 2
    verdict = judge(a, b)
    assert verdict.change is Change.WORSE
    (throttle,) = [f for f in verdict.figures if f.name == "throttle_s"]
    assert throttle.change is Change.SKIPPED  # shown, not judged: the ending decides
    # The other way round B lands softer, and takes longer over it: both figures count.
    assert judge(b, a).change is Change.CHANGED
