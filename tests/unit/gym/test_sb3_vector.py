"""The Stable-Baselines3 adapter over bfsitl's vector environment, with stand-in environments
(no SITL): the scaled actions reach the workers as sticks, the episode statistics SB3 reads are
the episodes' own, an ended episode's last observation is handed over, and SB3 trains on it."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("stable_baselines3")

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.baseline import HOVER_THROTTLE  # noqa: E402
from bfsitl.gym.observation import OBSERVATION_SIZE  # noqa: E402
from bfsitl.gym.sb3_vector import Sb3VectorEnv  # noqa: E402
from bfsitl.gym.scaled import StickLimits, scale_observation  # noqa: E402
from bfsitl.gym.vector import FlightVectorEnv  # noqa: E402

FAKE = "support.fake_flight_env:FakeFlightEnv"


def test_scaled_actions_reach_the_workers_as_sticks_and_observations_come_back_scaled() -> None:
    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 2, max_episode_steps=5))
    try:
        assert envs.action_space.shape == (3,) and envs.observation_space.shape == (
            OBSERVATION_SIZE,
        )
        envs.seed(7)
        first = envs.reset()
        raw = np.zeros(OBSERVATION_SIZE, dtype=np.float32)
        raw[1], raw[3], raw[4] = 1.0, 7.0, 1.0  # episode 1, its seed, a pinned core
        np.testing.assert_allclose(first[0], scale_observation(raw))
        assert first[1][3] == pytest.approx(8.0 / 2.0)  # the second env's seed, scaled by 2
        observations, rewards, dones, infos = envs.step(
            np.array([[1.0, 0, 0], [-0.5, 0, 0]], dtype=np.float32)
        )
        # The fake's reward is the roll stick it was given: the scaled action times 0.4.
        np.testing.assert_allclose(rewards, [0.4, -0.2], atol=1e-6)
        assert observations[:, 0].tolist() == [0.5, 0.5]  # one step, over 2 m
        assert not dones.any() and infos == [{}, {}]
    finally:
        envs.close()


def test_an_ended_episode_gives_sb3_its_last_observation_and_its_statistics() -> None:
    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 2, max_episode_steps=2), limits=None)
    try:
        assert envs.action_space.shape == (4,)
        envs.reset()
        envs.step(np.array([[0.5, 0, 0, 0], [0.25, 0, 0, 0]], dtype=np.float32))
        # Environment 0 crashes (a throttle of -1 in the fake); 1 reaches its time limit.
        observations, rewards, dones, infos = envs.step(
            np.array([[0.5, 0, -1.0, 0], [0.25, 0, 0, 0]], dtype=np.float32)
        )
        assert dones.tolist() == [True, True]
        assert observations[:, 0].tolist() == [0.0, 0.0]  # the next episodes' first
        assert [info["terminal_observation"][0] for info in infos] == [2.0, 2.0]
        assert [info["TimeLimit.truncated"] for info in infos] == [False, True]
        assert [info["episode"]["r"] for info in infos] == [1.0, 0.5]
        assert [info["episode"]["l"] for info in infos] == [2, 2]
        assert infos[0]["final_info"]["ended_because"] == "crashed: asked to"
        _o, _r, dones, infos = envs.step(np.zeros((2, 4), dtype=np.float32))
        assert not dones.any() and infos == [{}, {}]
        _o, _r, dones, infos = envs.step(np.zeros((2, 4), dtype=np.float32))
        assert [info["episode"]["r"] for info in infos] == [0.0, 0.0]  # counted afresh
    finally:
        envs.close()


def test_the_hover_point_is_the_vehicles_and_what_cannot_be_reached_is_said() -> None:
    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 1), StickLimits(throttle_span=0.5))
    try:
        assert envs.hover_throttle == pytest.approx(HOVER_THROTTLE)  # IRIS, the default world
        assert envs.get_attr("render_mode") == [None]
        assert envs.env_is_wrapped(object) == [False]
        with pytest.raises(AttributeError, match="worker processes"):
            envs.get_attr("task")
        with pytest.raises(EnvironmentConfigError, match="worker processes"):
            envs.env_method("render")
    finally:
        envs.close()
    with pytest.raises(EnvironmentConfigError, match="takes a FlightVectorEnv"):
        Sb3VectorEnv(object())  # type: ignore[arg-type]


def test_ppo_trains_on_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger

    torch.set_num_threads(1)
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 2, max_episode_steps=8))
    try:
        model = PPO("MlpPolicy", envs, n_steps=16, batch_size=32, n_epochs=1, device="cpu")
        # SB3 leaves an SB3-<date> folder in the temporary directory unless given a logger.
        model.set_logger(Logger(folder=None, output_formats=[]))
        model.learn(64)
        assert not list(scratch.glob("SB3-*")), list(scratch.iterdir())
        assert model.num_timesteps == 64
        # Monitor's statistics, written by the adapter: 8-step episodes were counted.
        assert model.ep_info_buffer and {e["l"] for e in model.ep_info_buffer} == {8}
    finally:
        envs.close()
