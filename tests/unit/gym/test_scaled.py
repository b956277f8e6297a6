"""ScaledEnv without a SITL: what the policy's numbers become on the sticks, and what the
observation becomes for the policy."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

import gymnasium  # noqa: E402

from bfsitl.backend.options import World  # noqa: E402
from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.baseline import HOVER_THROTTLE, hover_stick  # noqa: E402
from bfsitl.gym.observation import OBSERVATION_SIZE, observation_space  # noqa: E402
from bfsitl.gym.scaled import (  # noqa: E402
    OBSERVATION_OFFSET,
    OBSERVATION_SCALE,
    ScaledEnv,
    StickLimits,
    scale_observation,
)
from bfsitl.vehicles import load_vehicle  # noqa: E402


class StickRecorder(gymnasium.Env[np.ndarray, np.ndarray]):
    """Keeps the sticks it is given; observes a fixed hovering observation."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.action_space = gymnasium.spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.observation_space = observation_space()
        self.sticks: list[np.ndarray] = []
        self.observation = np.array(
            [1.0, -2.0, 0.5, 0.2, 0.0, -0.4, 0.1, -0.1, 0.0, 1.0]
            + [0.0, 0.0, 0.5, 0.0, 0.0, 9.81, 0.5, 0.5, 0.6, 0.4]
            + [3.0, 0.0, -1.0],
            dtype=np.float32,
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        return self.observation, {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        self.sticks.append(np.asarray(action))
        return self.observation, 1.0, False, False, {"distance_m": 0.0}


def test_a_scaled_action_moves_each_stick_within_its_limit_about_the_hover_throttle() -> None:
    inner = StickRecorder(World())
    env = ScaledEnv(inner)
    assert env.action_space.shape == (3,)
    env.reset()
    env.step(np.array([1.0, -0.5, 0.0], dtype=np.float32))  # full right, half back, hover
    env.step(np.array([-7.0, 7.0, 1.0], dtype=np.float32))  # clipped; full climb
    env.step(np.array([0.0, 0.0, -1.0], dtype=np.float32))  # full descent
    roll, pitch, throttle, yaw = np.array(inner.sticks).T
    np.testing.assert_allclose(roll, [0.4, -0.4, 0.0], atol=1e-6)
    np.testing.assert_allclose(pitch, [-0.2, 0.4, 0.0], atol=1e-6)
    # IRIS hovers at the stick's 0.1: the throttle swings 0.4 either side of it.
    np.testing.assert_allclose(throttle, [HOVER_THROTTLE, 0.5, -0.3], atol=1e-6)
    assert list(yaw) == [0.0, 0.0, 0.0]  # yaw held: not the policy's by default


def test_the_hover_point_is_the_wrapped_vehicles_and_yaw_can_be_given() -> None:
    quad = load_vehicle("5inch-freestyle")
    inner = StickRecorder(World(quad=quad))
    env = ScaledEnv(inner, StickLimits(tilt_stick=0.2, throttle_span=0.3, yaw_stick=0.5))
    assert env.action_space.shape == (4,)
    assert env.hover_throttle == pytest.approx(hover_stick(quad))
    assert env.hover_throttle != pytest.approx(HOVER_THROTTLE)  # a lighter quad, less throttle
    env.step(np.array([1.0, 1.0, 1.0, -1.0], dtype=np.float32))
    np.testing.assert_allclose(
        inner.sticks[0], [0.2, 0.2, hover_stick(quad) + 0.3, -0.5], atol=1e-6
    )
    with pytest.raises(EnvironmentConfigError, match="4 numbers"):
        env.step(np.zeros(3, dtype=np.float32))


def test_observations_are_scaled_slot_by_slot_and_clipped() -> None:
    inner = StickRecorder(World())
    env = ScaledEnv(inner)
    observation, _info = env.reset()
    expected = (inner.observation - OBSERVATION_OFFSET) / OBSERVATION_SCALE
    np.testing.assert_allclose(observation, expected, rtol=1e-6)
    assert observation[0] == pytest.approx(0.5) and observation[1] == pytest.approx(-1.0)
    assert observation[15] == pytest.approx(0.0)  # 1 g on z is the middle
    assert observation[20] == pytest.approx(1.5)  # a 3 m leg after the target
    assert env.observation_space.contains(observation)
    wild = np.zeros(OBSERVATION_SIZE, dtype=np.float32)
    wild[0] = 1000.0  # a kilometre off
    assert scale_observation(wild)[0] == 10.0


@pytest.mark.parametrize(
    ("limits", "message"),
    [
        ({"tilt_stick": 1.5}, "tilt_stick 1.5 is outside"),
        ({"yaw_stick": -0.1}, "yaw_stick -0.1 is outside"),
        ({"throttle_span": 0.0}, "cannot fly"),
    ],
)
def test_limits_outside_the_sticks_travel_are_refused(
    limits: dict[str, float], message: str
) -> None:
    with pytest.raises(EnvironmentConfigError, match=message):
        StickLimits(**limits)


def test_only_a_bfsitl_environment_is_wrapped() -> None:
    with pytest.raises(EnvironmentConfigError, match="wraps a bfsitl environment"):
        ScaledEnv(gymnasium.make("CartPole-v1"))
