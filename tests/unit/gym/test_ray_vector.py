"""RayVectorEnv's checks before it reaches a cluster (the cluster itself:
tests/integration/test_gym_sitl.py)."""

from __future__ import annotations

import pytest

pytest.importorskip("ray")
pytest.importorskip("gymnasium")

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.ray_vector import RayVectorEnv  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402


def test_a_workdir_is_refused_with_the_reason() -> None:
    with pytest.raises(EnvironmentConfigError, match="temporary directory of its node"):
        RayVectorEnv(
            "bfsitl.gym.env:HoverEnv", 2, address="127.0.0.1:1", sitl=SitlLaunch(workdir="runs")
        )


@pytest.mark.parametrize("count", [0, 257])
def test_a_count_outside_the_range_is_refused(count: int) -> None:
    with pytest.raises(EnvironmentConfigError, match=r"num_envs .* outside 1..256"):
        RayVectorEnv("bfsitl.gym.env:HoverEnv", count, address="127.0.0.1:1")
