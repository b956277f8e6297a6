"""bfsitl/Waypoints-v0 on the real 4.6.0 SITL (a --gps --lockstep build): the hand-written
policy, which flies to the observation's point, passes a course that turns north, east, south
and down in order (a wrong sign or axis in the observation's point would fly it away), the
observation carries the leg after each point, the progress it is paid adds up to the metres
it closed, and a fixed course is the same lap for the same seed."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from bfsitl.gym.baseline import hand_policy  # noqa: E402
from bfsitl.gym.env import WaypointsEnv  # noqa: E402
from bfsitl.gym.tasks import PROGRESS_PER_M, REACHED_M, WAYPOINT_BONUS  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402

pytestmark = pytest.mark.sitl

#: North, then east and up, then back west and down: every axis, both ways.
COURSE = ((3.0, 0.0, 2.0), (3.0, 3.0, 2.5), (0.0, 3.0, 1.5))


def lap(env: WaypointsEnv, seed: int, options: dict[str, Any] | None = None) -> dict[str, Any]:
    observation, info = env.reset(seed=seed, options=options)
    start = info["truth"]
    position = (start["north_m"], start["east_m"], start["alt_m"])
    waypoints, progress, bonuses, track, legs = [], 0.0, 0.0, [], [observation[20:23]]
    while True:
        action = hand_policy(observation)
        observation, reward, terminated, truncated, info = env.step(action)
        truth = info["truth"]
        track.append((truth["north_m"], truth["east_m"], truth["alt_m"]))
        stick_cost = 0.01 * float(action[0] ** 2 + action[1] ** 2 + action[3] ** 2)
        paid = reward + stick_cost
        if info["waypoint"] != (waypoints[-1] if waypoints else 0) or (
            terminated and info["ended_because"] is None
        ):
            paid -= WAYPOINT_BONUS
            bonuses += WAYPOINT_BONUS
        progress += paid
        waypoints.append(info["waypoint"])
        legs.append(observation[20:23])
        if terminated or truncated:
            return {
                "start": position,
                "waypoints": waypoints,
                "progress": progress,
                "bonuses": bonuses,
                "track": np.array(track),
                "legs": np.array(legs),
                "ended_because": info["ended_because"],
                "terminated": terminated,
                "time_s": info["time_s"],
            }


def test_the_hand_written_policy_passes_the_course_in_order_and_is_paid_its_progress(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    env = WaypointsEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "sitl"),
        max_episode_steps=3000,  # 30 s: the hand-written policy is slow and careful
    )
    try:
        # The course given at a reset is flown from then on: the second lap has no options.
        first = lap(env, seed=4, options={"course": COURSE})
        again = lap(env, seed=4)
    finally:
        env.close()
    # Passed every point, in order, and the last one ended the episode as a success.
    assert first["terminated"] and first["ended_because"] is None, first["ended_because"]
    assert sorted(set(first["waypoints"])) == [0, 1, 2]
    assert first["bonuses"] == 3 * WAYPOINT_BONUS
    track = first["track"]
    for point in COURSE:  # within the reach of each point, as the truth has it
        assert np.min(np.linalg.norm(track - np.array(point), axis=1)) <= REACHED_M
    # The progress paid is the metres closed on each point in turn, times the pay: from the
    # start to the first point, then point to point, each leg begun and ended within the
    # reach of its points (9.2 m of legs; paying the change of point as progress would be
    # 2.6 m off at each).
    legs = [math.dist(first["start"], COURSE[0])]
    legs += [math.dist(a, b) for a, b in zip(COURSE, COURSE[1:], strict=False)]
    closed_m = first["progress"] / PROGRESS_PER_M
    low_m, high_m = sum(legs) - 5 * REACHED_M, sum(legs) + 2 * REACHED_M
    assert low_m <= closed_m <= high_m, (closed_m, legs)
    # The observation's next leg, point by point: from the point flown to, to the one after
    # it; none (0) on the way to the last.
    for index, leg in zip([0, *first["waypoints"]], first["legs"], strict=True):
        following = COURSE[index + 1] if index + 1 < len(COURSE) else COURSE[index]
        np.testing.assert_allclose(leg, np.subtract(following, COURSE[index]), atol=1e-6)
    # A fixed course and the same seed: the same lap, to the step.
    assert again["time_s"] == first["time_s"]
    np.testing.assert_array_equal(again["track"], first["track"])
