"""Where the vehicle went, judged: distances from a point, a point reached, the end, ground
speed, heading, the path; and the mistakes a file can make in them."""

from __future__ import annotations

import math

import pytest

from bfsitl.errors import ScenarioError
from bfsitl.scenario.expectations import judge
from bfsitl.scenario.spec import scenario_from_dict
from bfsitl.scenario.trace import Trace, TraceRow


def leg_north(speed_m_s: float = 5.0, seconds: float = 20.0, heading: float = 0.0) -> Trace:
    """Up to 10 m, then north at ``speed_m_s`` for ``seconds``; 50 rows a second."""
    rows = []
    for i in range(int(seconds * 50) + 1):
        t = i / 50
        rows.append(
            TraceRow(t, 10.0, speed_m_s * t, 0.0, 0.0, 5.0, False, True, ("ANGLE",), (), 0, heading)
        )
    return Trace(rows=rows)


def checks(trace: Trace, **expect: object):
    spec = scenario_from_dict(
        {"duration_s": 60, "flight": {"takeoff_alt_m": 10.0}, "expect": expect}, name="leg"
    )
    return judge(spec, trace)


def test_reached_ends_within_and_distances_from_a_point() -> None:
    trace = leg_north()  # ends 100 m north
    reached, ends, far, near = checks(
        trace,
        reached={"north_m": 50.0, "east_m": 0.0, "within_m": 1.0},
        ends_within_m={"value": 5.0, "north_m": 100.0, "east_m": 0.0},
        max_distance_m={"value": 60.0, "north_m": 50.0, "east_m": 0.0},
        min_distance_m={"value": 20.0, "north_m": 50.0, "east_m": 0.0, "from_s": 15.0},
    )
    assert reached.passed and reached.at_time_s == pytest.approx(9.8, abs=0.05)
    assert ends.passed and ends.measured == 0.0
    assert far.passed and far.measured == 50.0
    assert near.passed and near.measured == 25.0
    (missed,) = checks(trace, reached={"north_m": 50.0, "east_m": 30.0, "within_m": 10.0})
    assert not missed.passed and "came only within 30.00 m" in missed.message


def test_ground_speed_is_measured_over_half_a_second() -> None:
    (speed,) = checks(leg_north(7.3), max_ground_speed_m_s=6.5)
    assert not speed.passed and speed.measured == pytest.approx(7.3, abs=0.01)
    assert checks(leg_north(5.0), max_ground_speed_m_s=6.5)[0].passed


def test_the_heading_must_stay_in_its_band_over_the_window() -> None:
    trace = leg_north(heading=80.0)
    assert checks(trace, heading_deg={"value": 90.0, "within_deg": 25.0})[0].passed
    across_north = leg_north(heading=350.0)
    assert checks(across_north, heading_deg={"value": 10.0, "within_deg": 25.0})[0].passed
    (off,) = checks(trace, heading_deg={"value": 180.0, "within_deg": 25.0, "from_s": 5.0})
    assert not off.passed and off.measured == 80.0


def test_the_path_flown_in_a_window() -> None:
    (path,) = checks(leg_north(), min_path_m={"value": 40.0, "from_s": 10.0})
    assert path.passed and path.measured == pytest.approx(50.0, abs=0.1)
    assert not checks(leg_north(0.0), min_path_m=1.0)[0].passed


@pytest.mark.parametrize(
    ("expect", "message"),
    [
        ({"reached": {"north_m": 1.0, "east_m": 0.0}}, r"reached takes .*within_m"),
        ({"reached": 5.0}, "reached takes a table"),
        ({"heading_deg": {"value": 90.0, "within": 5.0}}, "heading_deg takes"),
        ({"max_tilt_deg": {"value": 9.0, "north_m": 3.0}}, "max_tilt_deg takes a number or"),
        ({"ends_within_m": {"value": "near"}}, "is not valid"),
    ],
)
def test_mistakes_in_them_fail_when_the_file_is_read(expect: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=message):
        checks(leg_north(), **expect)


def test_without_positions_they_fail_saying_so() -> None:
    trace = leg_north()
    trace.rows = [
        TraceRow(r.time_s, r.alt_m, math.nan, math.nan, 0.0, 0.0, False, True, (), ())
        for r in trace.rows
    ]
    (result,) = checks(trace, reached={"north_m": 0.0, "east_m": 0.0, "within_m": 1.0})
    assert not result.passed and "no position" in result.message
