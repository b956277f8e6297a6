"""A wind drawn per episode: inside its range, from every direction, the same for a seed,
and refused beside a fixed one."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from support.fake_builds import fake_lockstep_build  # noqa: E402

from bfsitl.backend.options import World  # noqa: E402
from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.env import HoverEnv  # noqa: E402
from bfsitl.gym.random_wind import RandomWind  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics.wind import Wind  # noqa: E402


def test_each_draw_is_inside_the_range_from_any_direction_and_repeats_for_a_seed() -> None:
    winds = [RandomWind(4.0, 2.0).draw(np.random.default_rng(seed)) for seed in range(400)]
    speeds = [math.hypot(*w.velocity_ned_m_s[:2]) for w in winds]
    assert max(speeds) <= 4.0 and min(speeds) < 0.5 and max(speeds) > 3.5
    assert all(w.velocity_ned_m_s[2] == 0.0 for w in winds)  # horizontal
    gusts = [w.gust_std_m_s for w in winds]
    assert max(gusts) <= 2.0 and max(gusts) > 1.8
    # Blowing every way: towards each quadrant.
    quadrants = {(w.velocity_ned_m_s[0] > 0, w.velocity_ned_m_s[1] > 0) for w in winds}
    assert len(quadrants) == 4
    rng = np.random.default_rng
    assert RandomWind().draw(rng(3)) == RandomWind().draw(rng(3)) != RandomWind().draw(rng(4))


def test_a_random_wind_beside_a_fixed_one_or_out_of_range_is_refused(tmp_path: Path) -> None:
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    with pytest.raises(EnvironmentConfigError, match="give one wind"):
        HoverEnv(sitl=sitl, world=World(wind=Wind.from_direction(2.0)), random_wind=RandomWind())
    with pytest.raises(EnvironmentConfigError, match="random_wind must be a RandomWind"):
        HoverEnv(sitl=sitl, random_wind=3.0)
    with pytest.raises(EnvironmentConfigError, match=r"RandomWind.max_speed_m_s 20.0 is outside"):
        RandomWind(max_speed_m_s=20.0)
    env = HoverEnv(sitl=sitl, random_wind=RandomWind(2.0, 1.0))
    assert env.random_wind == RandomWind(2.0, 1.0)
    env.close()
