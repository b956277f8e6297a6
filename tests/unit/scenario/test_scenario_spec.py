"""Scenario files (checked before anything flies) and expectations judged on traces."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bfsitl.analysis import Finding, Severity
from bfsitl.errors import ScenarioError
from bfsitl.library import scenarios_dir
from bfsitl.scenario.expect_flight import crash_of
from bfsitl.scenario.expectations import judge
from bfsitl.scenario.load import find_scenarios, load_scenario
from bfsitl.scenario.spec import scenario_from_dict
from bfsitl.scenario.trace import Trace, TraceRow

LIBRARY = scenarios_dir()

MINIMAL = """
duration_s = 20
[flight]
takeoff_alt_m = 3.0
[[fault]]
at_s = 8.0
kind = "rc_loss"
[expect]
disarmed = true
"""


def write(tmp_path: Path, text: str, name: str = "s.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_the_shipped_library_reads_and_runs_on_both_generations() -> None:
    scenarios = find_scenarios([LIBRARY])
    assert len(scenarios) >= 6
    for scenario in scenarios:
        # Each injects a fault, or flies a configuration (a tune, a failsafe setting).
        assert scenario.description and (scenario.faults or scenario.cli) and scenario.expect
        assert set(scenario.firmware) == {"master-lockstep", "4.6.0-gps-lockstep"}


def test_a_minimal_file_gets_its_name_and_defaults(tmp_path: Path) -> None:
    scenario = load_scenario(write(tmp_path, MINIMAL, "rc-loss.toml"))
    assert scenario.name == "rc-loss" and scenario.duration_s == 20.0
    assert scenario.plan.target_alt_m == 3.0 and scenario.faults[0].kind == "rc_loss"
    assert scenario.wind is None and scenario.settle_s == 2.0 and not scenario.requires_gps
    assert scenario.physics == "embedded"
    on_gazebo = load_scenario(write(tmp_path, 'physics = "gazebo"\n' + MINIMAL, "gz.toml"))
    assert on_gazebo.physics == "gazebo"
    assert scenario.rc_rate_hz == 250.0  # the RC link's default: an ELRS rate


@pytest.mark.parametrize(
    ("table", "rate_hz"), [("rate_hz = 50", 50.0), ('rate_hz = "packet"', None)]
)
def test_the_rc_table_sets_the_links_rate(
    tmp_path: Path, table: str, rate_hz: float | None
) -> None:
    scenario = load_scenario(write(tmp_path, MINIMAL + f"[rc]\n{table}\n"))
    assert scenario.rc_rate_hz == rate_hz


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("duration_s = 20", "duration = 20"), r"unknown key\(s\) duration"),
        (("duration_s = 20", ""), "duration_s is missing"),
        (('kind = "rc_loss"', 'kind = "rc_loss"\nmotor = 3'), "fault 1: rc_loss has no parameter"),
        (("at_s = 8.0", "at_s = 80.0"), r"fault 1 at_s = 80.0 must be a number in 0..20"),
        (("disarmed = true", "disarmd = true"), "unknown key 'disarmd'"),
        (("disarmed = true", "disarmed = 1"), "disarmed must be true or false"),
        (("disarmed = true", 'failsafe_phase = "LANDIT"'), "unknown phase"),
        (("disarmed = true", "failsafe_within_s = 1.0"), "needs failsafe_phase"),
        (("disarmed = true", "min_alt_m = { value = 1, after_s = 2 }"), "takes a number or"),
        (("disarmed = true", 'finding = "crsh"'), "unknown analyser.*'crsh'.*known: crash"),
        (("disarmed = true", "no_finding = []"), "unknown analyser"),
        (("disarmed = true", 'worst_finding = "bad"'), "is not one of none, info, warning"),
        (("[expect]\ndisarmed = true", ""), r"\[expect\] is missing"),
        (("takeoff_alt_m = 3.0", "takeoff_alt_m = 300.0"), r"\[flight\]: target altitude"),
        (("duration_s = 20", 'physics = "ode"\nduration_s = 20'), "physics must be one of"),
        (("duration_s = 20", "rc = 50\nduration_s = 20"), r"\[rc\] must be a table"),
        (("duration_s = 20", "rc = { rate = 50 }\nduration_s = 20"), r"\[rc\] has unknown key"),
        (
            ("duration_s = 20", "rc = { rate_hz = 5 }\nduration_s = 20"),
            r"rc.rate_hz = 5 .*16..1000",
        ),
        (("duration_s = 20", 'rc = { rate_hz = "fast" }\nduration_s = 20'), 'or "packet"'),
    ],
)
def test_mistakes_fail_before_flying_naming_file_and_key(
    tmp_path: Path, change: tuple, message: str
) -> None:
    path = write(tmp_path, MINIMAL.replace(*change))
    with pytest.raises(ScenarioError, match=message) as caught:
        load_scenario(path)
    assert str(path) in str(caught.value)


def test_directories_twins_and_missing_paths(tmp_path: Path) -> None:
    write(tmp_path, MINIMAL, "a.toml")
    (tmp_path / "b").mkdir()
    write(tmp_path / "b", MINIMAL, "a.toml")
    assert [s.name for s in find_scenarios([tmp_path])] == ["a"]
    with pytest.raises(ScenarioError, match="two scenarios are named 'a'"):
        find_scenarios([tmp_path, tmp_path / "b"])
    with pytest.raises(ScenarioError, match="no such scenario file"):
        find_scenarios([tmp_path / "nope.toml"])
    # A bare name is the shipped library's file of that name.
    (drop,) = find_scenarios(["rc-loss-hover-drop"])
    assert drop.source == LIBRARY / "rc-loss-hover-drop.toml"
    with pytest.raises(ScenarioError, match="nor a scenario of the shipped library"):
        find_scenarios(["rc-loss-hover-dorp"])
    (tmp_path / "empty").mkdir()
    with pytest.raises(ScenarioError, match="holds no scenario files"):
        find_scenarios([tmp_path / "empty"])
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(write(tmp_path, "duration_s = ", "broken.toml"))


# -- expectations on traces ---------------------------------------------------------------------
def row(
    t: float,
    alt: float = 3.0,
    *,
    armed: bool = True,
    ground: bool = False,
    climb: float = 0.0,
    phase: int | None = 0,
    modes: tuple[str, ...] = ("ANGLE",),
    north: float = 0.0,
    tilt: float = 2.0,
) -> TraceRow:
    return TraceRow(t, alt, north, 0.0, climb, tilt, ground, armed, modes, (), phase)


def drop_trace() -> Trace:
    """Hover at 3 m, RC lost at 8 s, DROP at 8.5 s: falls, hits the ground at 7 m/s at 9.3 s."""
    trace = Trace(fault_times_s=[8.0], takeoff_done_s=4.0)
    trace.rows = [row(t / 10) for t in range(40, 85)]
    trace.rows += [
        row(
            8.5 + k / 10,
            3.0 - 0.4 * k,
            armed=False,
            phase=4,
            climb=-1.0 * k,
            modes=("ANGLE", "FAILSAFE"),
        )
        for k in range(1, 8)
    ]
    trace.rows += [
        row(9.3, 0.0, armed=False, ground=True, climb=-7.0, phase=4),
        row(10.0, 0.0, armed=False, ground=True, phase=4, north=1.5),
    ]
    return trace


def scenario_expecting(**expect: object):
    data = {
        "duration_s": 20,
        "flight": {"takeoff_alt_m": 3.0},
        "fault": [{"at_s": 8.0, "kind": "rc_loss"}],
        "expect": expect,
    }
    return scenario_from_dict(data, name="drop")


def test_a_drop_meets_what_a_drop_does() -> None:
    checks = judge(
        scenario_expecting(
            disarmed=True,
            disarmed_within_s=1.0,
            failsafe_phase="RX_LOSS_MONITORING",
            failsafe_within_s=1.0,
            mode_seen="FAILSAFE",
            crashed=True,
            landed_within_m=2.0,
            min_alt_m=2.5,
        ),
        drop_trace(),
    )
    assert len(checks) == 7  # failsafe_within_s is judged with failsafe_phase
    assert [c.passed for c in checks] == [True] * 7, [c.message for c in checks if not c.passed]


def test_a_wrong_expectation_names_itself_the_measured_value_and_the_time() -> None:
    checks = judge(
        scenario_expecting(disarmed_within_s=0.2, landed_within_m=1.0, max_touchdown_m_s=2.0),
        drop_trace(),
    )
    disarm, landed, touchdown = checks
    assert not disarm.passed and disarm.measured == 0.6 and disarm.at_time_s == 8.6
    assert disarm.message == (
        "disarmed_within_s = 0.2: disarmed 0.60 s after the fault "
        "(expected within 0.2 s) at t=8.60 s"
    )
    assert not landed.passed and landed.measured == 1.5
    assert "landed 1.50 m from the take-off point" in landed.message
    assert not touchdown.passed and touchdown.measured == 7.0 and touchdown.at_time_s == 9.3


def test_phases_must_come_in_order_and_within_time() -> None:
    trace = drop_trace()
    wrong_order = judge(
        scenario_expecting(failsafe_phase=["RX_LOSS_MONITORING", "LANDING"]), trace
    )[0]
    assert not wrong_order.passed and "never reached LANDING" in wrong_order.message
    late = judge(
        scenario_expecting(failsafe_phase="RX_LOSS_MONITORING", failsafe_within_s=0.3), trace
    )[0]
    assert not late.passed and late.measured == 0.6


def test_limits_take_a_window_and_default_to_the_airborne_part() -> None:
    trace = drop_trace()
    # Default: from the end of the take-off to the fault; the fall is not judged.
    assert judge(scenario_expecting(min_alt_m=2.9), trace)[0].passed
    over_the_fall = judge(scenario_expecting(min_alt_m={"value": 2.9, "from_s": 8.0}), trace)[0]
    assert not over_the_fall.passed and over_the_fall.measured == 0.0
    assert "down to 0.00 m (expected at least 2.9 m)" in over_the_fall.message


def test_crash_is_judged_on_the_truth_once_nobody_flies() -> None:
    assert crash_of(drop_trace()) == (9.3, "hit the ground at 7.0 m/s")
    calm = drop_trace()
    calm.rows = [r for r in calm.rows if r.time_s < 8.0]
    assert crash_of(calm) is None


def test_findings_are_expectations_too() -> None:
    trace = drop_trace()
    trace.findings = [
        Finding("crash", Severity.FAILURE, "hit the ground at 7.0 m/s", 9.3, 7.0, "m/s"),
        Finding(
            "failsafe", Severity.INFO, "failsafe: RX_LOSS_MONITORING at 8.5 s", 8.5, 1.0, "phases"
        ),
    ]
    found, absent, worst = judge(
        scenario_expecting(
            finding=["crash", "failsafe"], no_finding="fly_away", worst_finding="failure"
        ),
        trace,
    )
    assert found.passed and absent.passed and worst.passed
    assert found.measured == "failure" and found.at_time_s == 9.3
    wrong = judge(
        scenario_expecting(finding="motor_saturation", no_finding="crash", worst_finding="warning"),
        trace,
    )
    assert [c.passed for c in wrong] == [False, False, False]
    assert "motor_saturation found nothing" in wrong[0].message
    assert "crash: failure: hit the ground at 7.0 m/s" in wrong[1].message
    assert wrong[2].measured == "failure" and wrong[2].at_time_s == 9.3
    trace.findings = []
    assert judge(scenario_expecting(worst_finding="none"), trace)[0].passed
    # An analyser that could not watch found nothing because it saw nothing: no pass.
    trace.unwatched = {"fly_away": "the blackbox track has no north_m"}
    (blind,) = judge(scenario_expecting(no_finding="fly_away"), trace)
    assert not blind.passed and "could not watch this run (fly_away: the blackbox" in blind.message


def test_blackbox_expectations_fail_clearly_without_a_log() -> None:
    check = judge(scenario_expecting(blackbox_phase="LANDED"), drop_trace())[0]
    assert not check.passed and "no blackbox log" in check.message


def test_a_vehicle_table_makes_the_quad_and_its_hover_throttle(tmp_path: Path) -> None:
    from bfsitl.physics import IRIS
    from bfsitl.scenario.setup_lines import hover_throttle_line

    default = load_scenario(write(tmp_path, MINIMAL, "a.toml"))
    heavy = load_scenario(
        write(tmp_path, MINIMAL + '[vehicle]\nmodel = "iris"\nmass_kg = 2.2\n', "b.toml")
    )
    assert default.quad is IRIS and heavy.quad.mass_kg == 2.2
    assert hover_throttle_line(IRIS) == "set ap_hover_throttle = 1545"  # measured
    heavier_us = int(hover_throttle_line(heavy.quad).split("= ")[1])
    assert 1545 < heavier_us < 1700
    with pytest.raises(ScenarioError, match="unknown vehicle 'x500': give one of iris, 3inch"):
        load_scenario(write(tmp_path, MINIMAL + '[vehicle]\nmodel = "x500"\n', "c.toml"))
    with pytest.raises(ScenarioError, match="cannot hover"):
        load_scenario(write(tmp_path, MINIMAL + "[vehicle]\nmass_kg = 19.0\n", "d.toml"))


def test_a_scenario_flies_a_shipped_profile_or_a_file_beside_it(tmp_path: Path) -> None:
    from bfsitl.scenario.setup_lines import hover_throttle_line
    from bfsitl.scenario.spec import on_vehicle
    from bfsitl.vehicles import load_vehicle, profile_text, shipped_profiles

    five = load_scenario(
        write(tmp_path, MINIMAL + '[vehicle]\nmodel = "5inch-freestyle"\n', "five.toml")
    )
    assert five.quad == load_vehicle("5inch-freestyle") and five.own_vehicle
    assert five.quad.mass_kg == pytest.approx(0.65)
    # A light quad's hover throttle is well below IRIS's (a 5-inch hovers near a quarter).
    assert 1150 < int(hover_throttle_line(five.quad).split("= ")[1]) < 1350
    spec = shipped_profiles()["7inch-longrange"]
    (tmp_path / "quads").mkdir()
    (tmp_path / "quads" / "mine.toml").write_text(profile_text(spec).replace("884.0", "900.0"))
    mine = load_scenario(
        write(tmp_path, MINIMAL + '[vehicle]\nmodel = "quads/mine.toml"\n', "mine.toml")
    )
    assert mine.quad.mass_kg == pytest.approx(0.9) and mine.quad.name == "7inch-longrange"
    with pytest.raises(
        ScenarioError, match="(?s)mine.toml: .*bad.toml: 1 bad field:\n  mass_g: must be > 0"
    ):
        (tmp_path / "quads" / "bad.toml").write_text(profile_text(spec).replace("884.0", "-1.0"))
        load_scenario(
            write(tmp_path, MINIMAL + '[vehicle]\nmodel = "quads/bad.toml"\n', "mine.toml")
        )
    # --vehicle replaces the quad of the scenarios that name none, and only theirs.
    plain = load_scenario(write(tmp_path, MINIMAL, "plain.toml"))
    assert not plain.own_vehicle
    cinewhoop = load_vehicle("3inch-cinewhoop")
    flown = on_vehicle([plain, five], cinewhoop)
    assert flown[0].quad == cinewhoop and flown[1].quad == five.quad
    assert on_vehicle([plain], None)[0] is plain


@pytest.mark.parametrize(
    ("entry", "says"),
    [
        ({"finding": "crsh", "why": "x"}, "finding = 'crsh' is no analyser; one of"),
        ({"finding": "crash"}, 'why = "..." says what the defect is (missing)'),
        ({"finding": "crash", "why": "x", "generation": "4.5"}, "generation = '4.5'; one of 4.6"),
        ({"finding": "crash", "why": "x", "seen": "y"}, "unknown key(s) seen; known: finding"),
    ],
)
def test_a_bad_known_failure_is_one_clear_line(
    tmp_path: Path, entry: dict[str, str], says: str
) -> None:
    import tomli_w

    data = {"duration_s": 20, "flight": {"takeoff_alt_m": 2.0}, "expect": {"disarmed": True}}
    path = tmp_path / "k.toml"
    path.write_text(tomli_w.dumps({**data, "known_failure": [entry]}))
    with pytest.raises(ScenarioError, match=re.escape(f"k.toml, known_failure 1: {says}")):
        load_scenario(path)
