"""Waypoints as a course to fly fast: paid for progress (closing on the point pays, backing
off costs, the next point's distance is no windfall), a fixed course every episode, and courses
the episode's bounds would end refused with the point that is wrong."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from support.fake_builds import fake_lockstep_build  # noqa: E402
from support.true_views import true_view  # noqa: E402

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.env import WaypointsEnv  # noqa: E402
from bfsitl.gym.option_checks import check_course  # noqa: E402
from bfsitl.gym.snapshot import TrueView  # noqa: E402
from bfsitl.gym.tasks import PROGRESS_PER_M, WAYPOINT_BONUS, Hover, Waypoints  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402

CENTRED = np.zeros(4, dtype=np.float32)
COURSE = ((4.0, 0.0, 2.0), (4.0, 4.0, 3.0))


def at(north_m: float, east_m: float, alt_m: float, tilt_deg: float = 0.0) -> TrueView:
    return true_view(north_m=north_m, east_m=east_m, alt_m=alt_m, tilt_deg=tilt_deg)


def test_closing_on_the_point_pays_backing_off_costs_and_tilt_is_free() -> None:
    task = Waypoints(course=COURSE)
    task.reset(np.random.default_rng(0))
    # The first step has nothing to compare with.
    assert task.reward(at(0.0, 0.0, 2.0), CENTRED) == 0.0
    # 0.1 m closer, leaning hard: the progress, all of it.
    assert task.reward(at(0.1, 0.0, 2.0, tilt_deg=30.0), CENTRED) == pytest.approx(
        PROGRESS_PER_M * 0.1
    )
    assert task.reward(at(0.1, 0.0, 2.0), CENTRED) == 0.0  # standing: nothing
    assert task.reward(at(0.0, 0.0, 2.0), CENTRED) == pytest.approx(-PROGRESS_PER_M * 0.1)
    # The sticks' effort costs as in a hover (roll, pitch, yaw; the throttle is free).
    sticks = np.array([0.5, 0.0, 1.0, 0.0], dtype=np.float32)
    assert task.reward(at(0.0, 0.0, 2.0), sticks) == pytest.approx(-0.01 * 0.25)


def test_reaching_a_point_counts_progress_on_the_next_without_a_windfall() -> None:
    task = Waypoints(course=COURSE)
    task.reset(np.random.default_rng(0))
    task.reward(at(3.0, 0.0, 2.0), CENTRED)
    reached = at(3.8, 0.0, 2.0)
    assert task.reward(reached, CENTRED) == pytest.approx(PROGRESS_PER_M * 0.8)
    assert task.advance(reached) == (WAYPOINT_BONUS, False) and task.index == 1
    # The next point is about 4 m away: moving 0.1 m towards it pays 0.1 m, not 4 m lost
    # or won by the change of target.
    before = np.linalg.norm(np.subtract(COURSE[1], (3.8, 0.0, 2.0)))
    step = np.subtract(COURSE[1], (3.8, 0.0, 2.0)) / before * 0.1
    closer = at(3.8 + step[0], step[1], 2.0 + step[2])
    assert task.reward(closer, CENTRED) == pytest.approx(PROGRESS_PER_M * 0.1)
    assert task.advance(at(*COURSE[1])) == (WAYPOINT_BONUS, True)
    assert task.info() == {"waypoints": 2}


def test_the_point_after_the_target_is_known_until_the_last_and_a_hover_has_none() -> None:
    task = Waypoints(course=COURSE)
    task.reset(np.random.default_rng(0))
    assert task.target == COURSE[0] and task.next_target == COURSE[1]
    task.advance(at(*COURSE[0]))
    assert task.target == COURSE[1] and task.next_target is None
    hover = Hover()
    hover.reset(np.random.default_rng(0))
    assert hover.next_target is None


def test_a_course_is_flown_every_episode_whatever_the_seed_and_random_points_stay_near() -> None:
    task = Waypoints(course=COURSE, count=7)
    for seed in (0, 1, 2):
        task.reset(np.random.default_rng(seed))
        assert task.targets == list(COURSE)
    drawn = Waypoints(count=4, horizontal_m=3.0)
    points = []
    for seed in range(100):
        drawn.reset(np.random.default_rng(seed))
        assert len(drawn.targets) == 4
        points += drawn.targets
    north, east, _up = np.array(points).T
    assert np.abs(north).max() <= 3.0 and np.abs(east).max() > 2.8


@pytest.mark.parametrize(
    ("course", "fix"),
    [
        ((), "course has no points"),
        (((1.0, 2.0),), r"course point 1 is not three numbers"),
        (((1.0, "x", 2.0),), r"course point 1 is not three numbers"),
        (((1.0, 0.0, float("nan")),), "course point 1 is not finite"),
        (((1.0, 0.0, 25.0),), r"course point 1 is 25 m up: outside 0.5..20 m"),
        (((1.0, 0.0, 0.2),), r"course point 1 is 0.2 m up"),
        (((10.0, 0.0, 1.5),), r"course point 1 is 10.0 m from the one before \(the start"),
        (((4.0, 0.0, 2.0), (-6.0, 0.0, 2.0)), "course point 2 is 10.0 m.*add a point between"),
    ],
)
def test_a_course_the_bounds_would_end_is_refused_with_the_point(course, fix) -> None:
    with pytest.raises(EnvironmentConfigError, match=fix):
        check_course(course, start_up_m=1.5)


def test_a_course_inside_the_bounds_is_taken_as_a_tuple_of_points() -> None:
    course = [[4, 0, 2], (-5.0, 0.0, 2.0)]  # 9 m apart: inside the 10 m bounds
    assert check_course(course, start_up_m=1.5) == ((4.0, 0.0, 2.0), (-5.0, 0.0, 2.0))


def test_the_environment_takes_a_course_or_a_spread_and_refuses_a_bad_one(tmp_path: Path) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    with pytest.raises(EnvironmentConfigError, match="horizontal_m 5 is outside 0.5..3 m"):
        WaypointsEnv(sitl=sitl, horizontal_m=5)
    with pytest.raises(EnvironmentConfigError, match="course point 1 is 10.0 m from"):
        # 8 m north of the start and 6 m above it: the start's height is the option's.
        WaypointsEnv(sitl=sitl, course=[(8.0, 0.0, 9.0)], start_alt_m=3.0)
    env = WaypointsEnv(sitl=sitl, course=[[4, 0, 2], [4, 4, 3]])
    try:
        assert env.task.course == COURSE  # type: ignore[attr-defined]
        # A reset's course is checked as the constructor's, before anything boots.
        with pytest.raises(EnvironmentConfigError, match="course point 2 is 10.0 m"):
            env.reset(options={"course": [(4.0, 0.0, 2.0), (-6.0, 0.0, 2.0)]})
        assert env.task.course == COURSE  # type: ignore[attr-defined]
    finally:
        env.close()
