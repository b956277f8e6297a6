"""A trained policy leaves the simulator as one ONNX file: onnxruntime, without torch's
policy, gives the sticks the trained model gives, for each learning method and limits; what
it was trained at rides in the file; a file that is not a bfsitl policy is said as such."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("stable_baselines3")
pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

from support.onnx_policies import linear_policy_file  # noqa: E402

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.observation import FIRST_LAYOUT_SIZE, OBSERVATION_SIZE  # noqa: E402
from bfsitl.gym.onnx_policy import OnnxPolicy  # noqa: E402
from bfsitl.gym.policy_export import export_policy, trained_sticks  # noqa: E402
from bfsitl.gym.sb3_vector import Sb3VectorEnv  # noqa: E402
from bfsitl.gym.scaled import StickLimits  # noqa: E402
from bfsitl.gym.vector import FlightVectorEnv  # noqa: E402

FAKE = "support.fake_flight_env:FakeFlightEnv"


def observations(count: int) -> np.ndarray:
    """Observations as a flight gives them: offsets of metres, rates, 1 g, motors."""
    rng = np.random.default_rng(4)
    values = rng.normal(0.0, 1.0, size=(count, OBSERVATION_SIZE)).astype(np.float32)
    values[:, 0:3] *= 3.0
    values[:, 20:23] *= 3.0  # the next leg
    values[:, 15] += 9.81
    values[:, 16:20] = rng.uniform(0.0, 1.0, size=(count, 4))
    values[0, 0] = 500.0  # far away: the scaling's clip is in the file too
    return values


@pytest.mark.parametrize(
    ("method", "limits"),
    [
        ("ppo", StickLimits()),
        ("sac", StickLimits(tilt_stick=0.3, throttle_span=0.5)),
        ("td3", StickLimits(yaw_stick=0.25)),
    ],
)
def test_the_exported_policy_gives_the_trained_ones_sticks(
    method: str, limits: StickLimits, tmp_path: Path
) -> None:
    import torch
    from stable_baselines3 import PPO, SAC, TD3
    from stable_baselines3.common.logger import Logger

    torch.set_num_threads(1)
    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 1, max_episode_steps=8), limits)
    try:
        if method == "ppo":
            model = PPO("MlpPolicy", envs, n_steps=32, batch_size=32, n_epochs=1, seed=1)
        else:
            cls = SAC if method == "sac" else TD3
            model = cls("MlpPolicy", envs, learning_starts=8, batch_size=8, seed=1)
        # A logger that writes nothing: SB3 leaves a folder in /tmp otherwise.
        model.set_logger(Logger(folder=None, output_formats=[]))
        model.learn(48)  # weights moved from their start: not an untrained identity
    finally:
        envs.close()
    path = export_policy(
        model,
        tmp_path / "policy.onnx",
        limits=limits,
        hover_throttle=0.1,
        control_hz=50.0,
        description=f"{method} on the fake",
    )
    policy = OnnxPolicy(path)
    assert (policy.control_hz, policy.mode) == (50.0, "angle")
    assert policy.info.description == f"{method} on the fake"
    batch = observations(100)
    expected = trained_sticks(model, batch, limits, 0.1)
    got = policy(batch)
    assert got.shape == (100, 4)
    np.testing.assert_allclose(got, expected, atol=1e-5)
    np.testing.assert_allclose(policy(batch[7]), expected[7], atol=1e-5)  # one at a time
    # The sticks are the environment's: within the limits about the hover throttle.
    assert np.abs(got[:, :2]).max() <= limits.tilt_stick + 1e-6
    assert np.abs(got[:, 2] - 0.1).max() <= limits.throttle_span + 1e-6
    assert np.abs(got[:, 3]).max() <= limits.yaw_stick + 1e-6
    if limits.yaw_stick == 0.0:
        assert not got[:, 3].any()
    assert len(np.unique(got[:, 0])) > 50  # it depends on the observation


def test_limits_that_are_not_the_policys_are_refused(tmp_path: Path) -> None:
    from stable_baselines3 import PPO

    envs = Sb3VectorEnv(FlightVectorEnv(FAKE, 1))
    try:
        model = PPO("MlpPolicy", envs, n_steps=8, batch_size=8)
    finally:
        envs.close()
    with pytest.raises(EnvironmentConfigError, match="give the limits it was trained with"):
        export_policy(
            model,
            tmp_path / "p.onnx",
            limits=StickLimits(yaw_stick=0.5),
            hover_throttle=0.1,
            control_hz=50.0,
        )


def test_a_file_that_is_not_a_bfsitl_policy_is_said_as_such(tmp_path: Path) -> None:
    import onnx
    import torch

    with pytest.raises(EnvironmentConfigError, match="no such policy file"):
        OnnxPolicy(tmp_path / "missing.onnx")
    garbage = tmp_path / "garbage.onnx"
    garbage.write_bytes(b"\x00not onnx at all")
    with pytest.raises(EnvironmentConfigError, match="not an ONNX model"):
        OnnxPolicy(garbage)
    other = tmp_path / "other.onnx"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation
        torch.onnx.export(
            torch.nn.Linear(20, 4),
            (torch.zeros(1, 20),),
            str(other),
            input_names=["observation"],
            output_names=["sticks"],
            dynamo=False,
        )
    assert onnx.load(str(other))  # a valid model, only not one of ours
    with pytest.raises(EnvironmentConfigError, match="not a bfsitl policy"):
        OnnxPolicy(other)


def test_a_policy_exported_before_the_next_leg_slots_reads_the_first_twenty(
    tmp_path: Path,
) -> None:
    weights = np.random.default_rng(1).normal(size=(FIRST_LAYOUT_SIZE, 4)).astype(np.float32)
    older = linear_policy_file(
        tmp_path / "older.onnx", weights, layout=f"bfsitl.gym.observation/{FIRST_LAYOUT_SIZE}"
    )
    policy = OnnxPolicy(older)
    assert policy.info.observation_size == FIRST_LAYOUT_SIZE
    batch = observations(10)
    np.testing.assert_allclose(
        policy(batch), batch[:, :FIRST_LAYOUT_SIZE] @ weights, rtol=1e-5, atol=1e-5
    )
    # A layout this bfsitl does not know is refused with what to do.
    odd = linear_policy_file(
        tmp_path / "odd.onnx", np.zeros((17, 4)), layout="bfsitl.gym.observation/17"
    )
    with pytest.raises(EnvironmentConfigError, match="export the policy again"):
        OnnxPolicy(odd)
