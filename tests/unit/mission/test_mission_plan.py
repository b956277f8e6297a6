"""Mission files, legs, heading control and the GPS's error model: the pure parts of flying
in three dimensions."""

from __future__ import annotations

import math
import statistics

import pytest

from bfsitl.control.angle_sticks import ActualRates, AngleStickMap
from bfsitl.control.heading import HeadingController, heading_error_deg
from bfsitl.errors import BfsitlError, MissionError
from bfsitl.mission.legs import LegReference, cross_track_m, leg_stats
from bfsitl.mission.plan import MissionPlan, Waypoint, load_mission, plan_from_dict
from bfsitl.physics.sensors import SensorConfig

SQUARE = """
takeoff_alt_m = 2.0
speed_m_s = 1.5
land = true

[[waypoint]]
north_m = 10.0
east_m = 0
alt_m = 2.0

[[waypoint]]
north_m = 10.0
east_m = 10.0
alt_m = 3
hold_s = 2.5
heading_deg = 90
"""


def test_a_mission_file_becomes_a_plan(tmp_path):
    path = tmp_path / "square.toml"
    path.write_text(SQUARE)
    plan = load_mission(path)
    assert plan.target_alt_m == 2.0 and plan.speed_m_s == 1.5 and plan.land
    assert plan.waypoints == (
        Waypoint(10.0, 0, 2.0),
        Waypoint(10.0, 10.0, 3, hold_s=2.5, heading_deg=90),
    )
    assert plan.hold_s == 0.0  # with waypoints the hold after take-off defaults to none
    assert plan.needs_position
    assert not MissionPlan().needs_position


def test_the_shipped_example_mission_loads():
    from bfsitl.library import find_mission

    square = find_mission("square")
    assert square is not None
    plan = load_mission(square)
    assert len(plan.waypoints) == 4 and plan.waypoints[-1].north_m == 0.0


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("takeoff_alt_m = 2\nspeed = 3", "unknown key(s) speed"),
        ("speed_m_s = 2", "takeoff_alt_m is missing"),
        ("takeoff_alt_m = 2\n[[waypoint]]\nnorth_m = 1\neast_m = 2", "waypoint 1: missing alt_m"),
        (
            "takeoff_alt_m = 2\n[[waypoint]]\nnorth_m = 1\neast_m = 2\nalt_m = 2\nhold = 3",
            "waypoint 1: unknown key(s) hold",
        ),
        (
            "takeoff_alt_m = 2\n[[waypoint]]\nnorth_m = 1\neast_m = 2\nalt_m = 200",
            "waypoint 1: waypoint alt_m 200",
        ),
        (
            "takeoff_alt_m = 2\n[[waypoint]]\nnorth_m = '1'\neast_m = 2\nalt_m = 2",
            "north_m must be a number",
        ),
        ("takeoff_alt_m = 2\nland = 1", "land must be true or false"),
        ("takeoff_alt_m = 0.1", "target altitude 0.1"),
        ("takeoff_alt_m = 2\nwaypoint = 3", "[[waypoint]] tables"),
    ],
)
def test_a_wrong_mission_file_says_where_and_what(tmp_path, text, expected):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(MissionError) as caught:
        load_mission(path)
    assert expected in str(caught.value) and str(path) in str(caught.value)


def test_unreadable_and_invalid_toml_are_mission_errors(tmp_path):
    with pytest.raises(MissionError, match="cannot read the mission file"):
        load_mission(tmp_path / "missing.toml")
    path = tmp_path / "broken.toml"
    path.write_text("takeoff_alt_m = = 2\n")
    with pytest.raises(MissionError, match="not valid TOML.*line 1"):
        load_mission(path)
    assert issubclass(MissionError, BfsitlError)


def test_plans_from_python_check_their_waypoints():
    with pytest.raises(MissionError, match="waypoints must be Waypoint"):
        MissionPlan(waypoints=((1.0, 2.0, 3.0),))  # type: ignore[arg-type]
    with pytest.raises(MissionError, match="heading_deg"):
        Waypoint(0, 0, 2, heading_deg=400)
    assert plan_from_dict({"takeoff_alt_m": 3}).hold_s == 10.0  # no waypoints: the usual hold


# -- legs ---------------------------------------------------------------------------------------
def test_a_leg_reference_accelerates_cruises_brakes_and_stops_at_the_end():
    leg = LegReference((0.0, 0.0, 2.0), (30.0, 40.0, 4.0), speed_m_s=2.0, accel_m_s2=1.0)
    assert leg.length_m == 50.0
    assert leg.duration_s == pytest.approx(2 * 2.0 + (50.0 - 4.0) / 2.0)
    points = [leg.at(k * 0.05) for k in range(int(leg.duration_s / 0.05) + 40)]
    speeds = [math.hypot(p.v_north_m_s, p.v_east_m_s) for p in points]
    assert max(speeds) == pytest.approx(2.0) and speeds[0] == 0.0 and speeds[-1] == 0.0
    end = points[-1]
    assert end.finished and (end.north_m, end.east_m, end.alt_m) == pytest.approx((30, 40, 4))
    # On the line all the way, and the altitude in proportion to the distance flown.
    for p in points:
        assert cross_track_m(p.north_m, p.east_m, (0, 0), (30, 40)) < 1e-9
        assert p.alt_m == pytest.approx(2.0 + 2.0 * math.hypot(p.north_m, p.east_m) / 50.0)
    # Accelerating along the track at first, braking at the end.
    assert points[10].a_north_m_s2 > 0 and points[-45].a_north_m_s2 < 0


def test_a_short_leg_peaks_below_the_cruise_speed_and_a_null_leg_is_done_at_once():
    short = LegReference((0, 0, 1), (0, 2, 1), speed_m_s=5.0, accel_m_s2=1.0)
    peak = max(short.at(t / 100).v_east_m_s for t in range(0, 400))
    assert peak == pytest.approx(math.sqrt(2.0), rel=0.01)
    assert short.duration_s == pytest.approx(2 * math.sqrt(2.0))
    assert short.peak_speed_m_s == pytest.approx(math.sqrt(2.0))
    assert LegReference((0, 0, 1), (0, 40, 1), speed_m_s=5.0).peak_speed_m_s == 5.0
    null = LegReference((1, 1, 1), (1, 1, 2), speed_m_s=2.0)
    assert null.duration_s == 0.0 and null.at(0.0).finished and null.at(0.0).alt_m == 2.0
    with pytest.raises(MissionError):
        LegReference((0, 0, 0), (1, 0, 0), speed_m_s=0.0)


def test_cross_track_is_across_the_line_and_overshoot_along_it():
    assert cross_track_m(5.0, 1.0, (0, 0), (10, 0)) == pytest.approx(1.0)
    assert cross_track_m(12.0, -0.5, (0, 0), (10, 0)) == pytest.approx(0.5)  # past the end
    stats = leg_stats(
        3,
        (0.0, 0.0),
        (10.0, 0.0, 2.0),
        [(0.0, 0.0, 2.0), (5.0, 0.3, 2.1), (10.6, -0.4, 2.0), (10.1, 0.0, 1.9)],
        took_s=7.5,
    )
    assert stats.waypoint == 3 and stats.took_s == 7.5
    assert stats.arrival_error_m == pytest.approx(0.1)
    assert stats.arrival_alt_error_m == pytest.approx(-0.1)
    assert stats.cross_track_max_m == pytest.approx(0.4)
    assert stats.overshoot_m == pytest.approx(0.6)
    assert stats.cross_track_rms_m == pytest.approx(math.sqrt((0.09 + 0.16) / 4))


# -- heading ------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("target", "heading", "error"),
    [(90, 0, 90), (0, 90, -90), (10, 350, 20), (350, 10, -20), (180, 0, -180), (0, 0, 0)],
)
def test_the_heading_error_is_the_short_way_round(target, heading, error):
    assert heading_error_deg(target, heading) == pytest.approx(error)


def test_the_heading_controller_turns_towards_the_target_within_its_rate_limit():
    control = HeadingController()
    assert control.rate_deg_s(350.0, 10.0) > 0  # clockwise through north
    assert control.rate_deg_s(10.0, 350.0) < 0
    assert control.rate_deg_s(0.0, 170.0) == control.gains.max_rate_deg_s
    assert control.rate_deg_s(45.0, 45.0) == 0.0


def test_the_yaw_stick_asks_for_the_rate_on_the_fcs_curve():
    rates = ActualRates(rc_rate=20, rate=67, expo=54)
    sticks = AngleStickMap(rates, rates, 55.0, yaw=rates)
    for wanted in (-300.0, -45.0, 0.0, 10.0, 90.0):
        stick = sticks.yaw_stick_us(wanted)
        assert rates.setpoint((stick - 1500.0) / 500.0) == pytest.approx(wanted, abs=1e-6)
    assert sticks.yaw_stick_us(10_000.0) == pytest.approx(2000.0)  # clamped to full stick


# -- the GPS's errors ---------------------------------------------------------------------------
def _gps_errors(config: SensorConfig, seed: int, readings: int) -> list[tuple[float, float]]:
    """(north m, north m/s) the GPS reports, every 10 ms, of a quad parked at home: with the
    vehicle still, all of it is error."""
    from bfsitl.physics import Simulator
    from bfsitl.physics.frames import EARTH_RADIUS_M

    sim = Simulator(sensors=config, seed=seed)
    errors = []
    for _ in range(readings):
        sim.step((0.0, 0.0, 0.0, 0.0), 0.01)
        reading = sim.read_sensors()
        errors.append(
            (math.radians(reading.geodetic[1]) * EARTH_RADIUS_M, reading.velocity_enu_m_s[1])
        )
    return errors


def test_an_exact_gps_has_no_error_and_the_typical_one_wanders_within_its_spread():
    assert _gps_errors(SensorConfig(), 1, 10) == [(0.0, 0.0)] * 10
    config = SensorConfig().with_typical_gps()
    assert not config.is_ideal
    errors = _gps_errors(config, 4, 60_000)  # 10 minutes at 100 Hz
    north = [e[0] for e in errors]
    assert 0.05 < statistics.pstdev(north) < 0.3  # about gps_drift_std_m over 20 drift times
    # Correlated: a second apart the wander has hardly moved; white noise alone would have.
    steps = [abs(north[k + 100] - north[k]) for k in range(0, len(north) - 100, 100)]
    assert statistics.mean(steps) < 0.08
    assert statistics.pstdev([e[1] for e in errors]) == pytest.approx(0.05, rel=0.1)
    assert _gps_errors(config, 4, 100) == errors[:100]  # seeded


def test_the_gps_error_moves_the_gps_fields_only():
    from bfsitl.physics import Simulator

    exact = Simulator(seed=3)
    noisy = Simulator(sensors=SensorConfig().with_typical_gps(), seed=3)
    a, b = exact.read_sensors(), noisy.read_sensors()
    assert a.position_ned_m == b.position_ned_m and a.pressure_pa == b.pressure_pa
    assert a.geodetic[:2] != b.geodetic[:2] and a.geodetic[2] == b.geodetic[2]
    with pytest.raises(Exception, match="gps_drift_time_s"):
        SensorConfig(gps_drift_time_s=0.0)


def test_hold_position_is_a_flag_of_the_file():
    assert plan_from_dict({"takeoff_alt_m": 2}).hold_position is True
    assert plan_from_dict({"takeoff_alt_m": 2, "hold_position": False}).hold_position is False
    with pytest.raises(MissionError, match="hold_position must be true or false"):
        plan_from_dict({"takeoff_alt_m": 2, "hold_position": "yes"})
