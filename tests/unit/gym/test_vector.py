"""The shared-memory vector environment's plumbing, with stand-in environments (no SITL):
the numbers of each step come back for the right environment, an ended episode is reset in
the same step with its last observation and info beside it, a worker's error or death is
raised in the parent, and close() leaves no worker behind."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from bfsitl.backend.options import Timing  # noqa: E402
from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.observation import OBSERVATION_SIZE  # noqa: E402
from bfsitl.gym.vector import FlightVectorEnv  # noqa: E402

FAKE = "support.fake_flight_env:FakeFlightEnv"


def actions(*rows: tuple[float, float, float, float]) -> np.ndarray:
    return np.array(rows, dtype=np.float32)


def test_each_step_comes_back_for_its_own_environment() -> None:
    envs = FlightVectorEnv(FAKE, 2, max_episode_steps=5)
    try:
        observations, info = envs.reset(seed=7)
        assert observations.shape == (2, OBSERVATION_SIZE) and observations.dtype == np.float32
        assert list(observations[:, 3]) == [7.0, 8.0]  # one seed each, counted on
        assert envs.observation_space.shape == (
            2,
            OBSERVATION_SIZE,
        ) and envs.action_space.shape == (2, 4)
        observations, rewards, terminated, truncated, info = envs.step(
            actions((0.25, 0, 0, 0), (-0.5, 0, 0, 0))
        )
        assert list(rewards) == [0.25, -0.5]  # each its own action
        assert list(observations[:, 0]) == [1.0, 1.0]
        assert not terminated.any() and not truncated.any()
        assert info["distance_m"].tolist() == [1.5, 1.5] and info["_distance_m"].all()
        assert info["armed"].dtype == bool and info["armed"].all()
        assert info["target"].tolist() == [[1.0, 2.0, 3.0]] * 2
        assert info["position_m"].tolist() == [[0.1, 0.2, 2.5]] * 2
        assert info["velocity_m_s"][:, 2].tolist() == [-0.5, -0.5]
        assert "final_obs" not in info
    finally:
        envs.close()


def test_an_ended_episode_is_reset_in_the_same_step_with_its_end_beside_it() -> None:
    envs = FlightVectorEnv(FAKE, 2, max_episode_steps=2)
    try:
        envs.reset(seed=[1, 2])
        envs.step(actions((0, 0, 0, 0), (0, 0, 0, 0)))
        # Environment 0 is told to crash; environment 1 reaches its time limit.
        observations, _rewards, terminated, truncated, info = envs.step(
            actions((0, 0, -1, 0), (0, 0, 0, 0))
        )
        assert terminated.tolist() == [True, False] and truncated.tolist() == [False, True]
        assert observations[:, 0].tolist() == [0.0, 0.0]  # the next episodes' first
        assert observations[:, 1].tolist() == [2.0, 2.0]
        assert info["_final_obs"].tolist() == [True, True]
        assert [o[0] for o in info["final_obs"]] == [2.0, 2.0]  # the ended episodes' last
        # Gymnasium's layout: the ended episodes' infos batched key by key, with masks.
        final = info["final_info"]
        assert final["ended_because"].tolist() == ["crashed: asked to", None]
        assert final["time_s"].tolist() == [0.02, 0.02] and final["_time_s"].all()
        assert final["truth"]["alt_m"].tolist() == [3.5, 3.5]
        _o, _r, terminated, truncated, info = envs.step(actions((0, 0, 0, 0), (0, 0, 0, 0)))
        assert not terminated.any() and not truncated.any() and "final_info" not in info
    finally:
        envs.close()


def test_workers_ask_for_a_core_each_and_no_spin_unless_told_otherwise() -> None:
    for options, expected in (
        ({}, [1.0, 0.0]),
        ({"pin_core": False}, [0.0, 0.0]),
        ({"timing": Timing(lockstep_spin=True), "pin_core": False}, [0.0, 1.0]),
    ):
        envs = FlightVectorEnv(FAKE, 2, **options)
        try:
            observations, _info = envs.reset()
            assert observations[:, 4:6].tolist() == [expected, expected]
        finally:
            envs.close()


def test_an_option_no_environment_takes_is_raised_when_it_is_made() -> None:
    with pytest.raises(EnvironmentConfigError, match="environment 0: TypeError: .*wings"):
        FlightVectorEnv(FAKE, 2, wings=3)


def test_only_some_endings_fill_the_final_masks() -> None:
    envs = FlightVectorEnv(FAKE, 2, max_episode_steps=5)
    try:
        envs.reset(seed=0)
        _o, _r, terminated, _t, info = envs.step(actions((0, 0, 0, 0), (0, 0, -1, 0)))
        assert terminated.tolist() == [False, True]
        assert info["_final_obs"].tolist() == [False, True]
        assert info["final_obs"][0] is None
        assert info["final_info"]["_ended_because"].tolist() == [False, True]
    finally:
        envs.close()


def test_a_workers_error_is_raised_in_the_parent_and_ends_the_rest() -> None:
    envs = FlightVectorEnv(FAKE, 2)
    envs.reset(seed=0)
    with pytest.raises(EnvironmentConfigError, match="environment 1: ValueError: a stick of NaN"):
        envs.step(actions((0, 0, 0, 0), (float("nan"), 0, 0, 0)))
    assert all(not process.is_alive() for process in envs._processes)


def test_a_worker_that_dies_is_named_with_its_exit_code() -> None:
    envs = FlightVectorEnv(FAKE, 2)
    envs.reset(seed=0)
    with pytest.raises(
        EnvironmentConfigError,
        match=r"environment 0: its worker process ended "
        r"\(exit code 3\)",
    ):
        envs.step(actions((0, 1, 0, 0), (0, 0, 0, 0)))


def test_close_ends_every_worker_and_bad_input_is_refused() -> None:
    envs = FlightVectorEnv(FAKE, 3)
    envs.reset()
    with pytest.raises(EnvironmentConfigError, match="3 x 4 sticks"):
        envs.step(np.zeros((2, 4), dtype=np.float32))
    with pytest.raises(EnvironmentConfigError, match="2 seeds for 3 environments"):
        envs.reset(seed=[1, 2])
    envs.close()
    envs.close()  # twice is harmless
    assert all(not process.is_alive() for process in envs._processes)
    with pytest.raises(EnvironmentConfigError, match="closed: make a new one"):
        envs.step(np.zeros((3, 4), dtype=np.float32))
    with pytest.raises(EnvironmentConfigError, match="outside 1..256"):
        FlightVectorEnv(FAKE, 0)
