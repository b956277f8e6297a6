"""The Gymnasium environments on the real 4.6.0 SITL (a --gps --lockstep build): Gymnasium's
own checker, bit-for-bit repeats, the FC's observation against the truth under disturbances
(a wrong sign or axis fails), and many at once with nothing left running after close() or a
crash of the parent."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import bfsitl.gym  # noqa: E402, F401  (registers the environments)
from bfsitl.backend.options import World  # noqa: E402
from bfsitl.gym.env import HoverEnv  # noqa: E402
from bfsitl.gym.observation import OBSERVATION_SIZE  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics.wind import Wind  # noqa: E402

pytestmark = pytest.mark.sitl


def sitl_processes_under(folder: Path) -> list[int]:
    """SITL processes whose run directory is inside ``folder`` (any namespace: pids are
    shared)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            exe = os.readlink(entry / "exe")
            cwd = os.readlink(entry / "cwd")
        except OSError:
            continue
        if "_SITL" in exe and cwd.startswith(str(folder)):
            found.append(int(entry.name))
    return found


def test_gymnasiums_checker_passes_for_every_registered_environment(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    from gymnasium.utils.env_checker import check_env

    for number, env_id in enumerate(bfsitl.gym.ENVIRONMENTS):
        env = gymnasium.make(
            env_id,
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / str(number)),
        )
        try:
            check_env(env.unwrapped, skip_render_check=True)
        finally:
            env.close()
    assert sitl_processes_under(tmp_path) == []


def rollout(
    firmware: Path, workdir: Path, seed: int, steps: int = 500
) -> tuple[np.ndarray, np.ndarray, int]:
    """Observations and rewards of ``steps`` steps of the same action sequence; an episode
    that ends is reset (without a seed: the environment's generator goes on)."""
    env = HoverEnv(sitl=SitlLaunch(firmware=firmware, workdir=workdir))
    actions = np.random.default_rng(99).uniform(-0.25, 0.25, size=(steps, 4)).astype(np.float32)
    actions[:, 2] += 0.12  # about the hover throttle: the episodes last
    try:
        observation, _info = env.reset(seed=seed)
        observations, rewards, resets = [observation], [], 0
        for action in actions:
            observation, reward, terminated, truncated, _info = env.step(action)
            observations.append(observation)
            rewards.append(reward)
            if terminated or truncated:
                observation, _info = env.reset()
                observations.append(observation)
                resets += 1
    finally:
        env.close()
    return np.array(observations), np.array(rewards), resets


def test_the_same_seed_and_actions_give_the_same_flight_bit_for_bit(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    first, first_rewards, resets = rollout(lockstep_gps_46_firmware, tmp_path / "a", seed=4)
    again, again_rewards, _ = rollout(lockstep_gps_46_firmware, tmp_path / "b", seed=4)
    other, _other_rewards, _ = rollout(lockstep_gps_46_firmware, tmp_path / "c", seed=5)
    assert resets >= 1  # the repeat holds across a reset too
    assert first.tobytes() == again.tobytes()
    assert first_rewards.tobytes() == again_rewards.tobytes()
    assert first.shape != other.shape or not np.array_equal(first, other)


def test_a_late_observation_is_the_one_of_that_many_steps_before(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """The same seed and sticks with and without Latency: the flight is the same (the delay
    is the observation's only, rewards unchanged), each observation is the one of two steps
    before, and the height and climb those of five."""
    from bfsitl.gym.latency import Latency

    def flown(latency: Latency, workdir: Path) -> tuple[np.ndarray, np.ndarray]:
        env = HoverEnv(
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=workdir), latency=latency
        )
        actions = np.random.default_rng(5).uniform(-0.2, 0.2, size=(40, 4)).astype(np.float32)
        actions[:, 2] += 0.12
        try:
            observation, _info = env.reset(seed=8)
            observations, rewards = [observation], []
            for action in actions:
                observation, reward, terminated, truncated, _info = env.step(action)
                assert not (terminated or truncated)
                observations.append(observation)
                rewards.append(reward)
        finally:
            env.close()
        return np.array(observations), np.array(rewards)

    prompt, prompt_rewards = flown(Latency(), tmp_path / "prompt")
    late, late_rewards = flown(Latency(steps=(2, 2), altitude_steps=(3, 3)), tmp_path / "late")
    assert late_rewards.tobytes() == prompt_rewards.tobytes()
    others = [i for i in range(20) if i not in (2, 5)]
    assert np.array_equal(late[2:, others], prompt[:-2, others])
    assert np.array_equal(late[5:, [2, 5]], prompt[:-5, [2, 5]])
    assert np.array_equal(late[:3], np.repeat(prompt[:1], 3, axis=0)[:, :])  # none before
    assert not np.array_equal(late[5:], prompt[5:])  # the flight moved: the test can tell


@pytest.mark.parametrize(("per_step", "cutoff"), [(False, "93hz"), (True, "18hz")])
def test_with_a_frame_per_step_the_fc_smooths_the_sticks_as_for_a_receiver_at_that_rate(
    lockstep_gps_46_firmware: Path, per_step: bool, cutoff: str
) -> None:
    """The FC measures the receiver's rate and sets its setpoint cutoff to 0.375 of it
    (rc.c): the RC link's 250 Hz frames by default, or one frame per 50 Hz step."""
    from bfsitl.fc.cli_session import CliSession

    env = HoverEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware),
        rc_frame_per_step=per_step,
        control_hz=50,
        start="ground",
    )
    try:
        env.reset(seed=3)
        for _ in range(100):  # 2 s of frames at idle on the ground
            env.step(np.array([0.0, 0.0, -1.0, 0.0], dtype=np.float32))
        vehicle = env._vehicle
        assert vehicle is not None
        assert vehicle.disarm()  # the FC takes no CLI while armed
        with CliSession(vehicle.client.link) as cli:
            info = cli.run("rc_smoothing_info")
    finally:
        env.close()
    assert f"Active setpoint cutoff: {cutoff} (auto)" in info, info


def test_a_warm_reset_keeps_the_firmware_and_a_seeded_one_boots_it_afresh(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    from bfsitl.gym.baseline import hand_policy

    env = HoverEnv(sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "run"))
    try:
        first, _info = env.reset(seed=3)
        assert env._vehicle is not None and env._vehicle.sitl is not None
        pid = env._vehicle.sitl.pid
        for _ in range(400):  # full throttle, rolled: it crashes within a few seconds
            *_rest, terminated, truncated, info = env.step(
                np.array([0.8, 0.0, 1.0, 0.0], dtype=np.float32)
            )
            if terminated or truncated:
                break
        assert info["ended_because"] is not None and info["ended_because"].startswith(
            ("crashed", "out of bounds")
        )
        began = time.monotonic()
        observation, info = env.reset()
        assert time.monotonic() - began < 0.25  # no boot: a hand puts it back
        assert env._vehicle.sitl.pid == pid and info["armed"]
        assert abs(info["truth"]["alt_m"] - 1.5) < 0.05 and info["truth"]["tilt_deg"] < 1.0
        for _ in range(600):  # and it flies as well as before
            observation, _r, terminated, _t, info = env.step(hand_policy(observation))
            assert not terminated, info["ended_because"]
        assert info["distance_m"] < 0.5
        again, _info = env.reset(seed=3)  # a seed boots afresh: the same start
        assert env._vehicle.sitl.pid != pid
        assert again.tobytes() == first.tobytes()
    finally:
        env.close()


def test_what_the_fc_reports_follows_the_truth_in_wind_and_stick_steps(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """Roll right, pitch forward, yaw right, in a 3 m/s wind from the east: the FC's attitude,
    gyro, climb and GPS in the observation against the same slots filled from the truth."""
    env = HoverEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "run"),
        world=World(wind=Wind.from_direction(3.0, 90.0)),
        max_episode_steps=6000,
    )
    try:
        _obs, info = env.reset(seed=2)
        hover = 0.12

        def fly(
            sticks: tuple[float, float, float, float], seconds: float
        ) -> list[tuple[np.ndarray, np.ndarray]]:
            pairs = []
            for _ in range(round(seconds * env.control_hz)):
                fc, _r, terminated, _t, info = env.step(np.array(sticks, dtype=np.float32))
                assert not terminated, info["ended_because"]
                assert env._snapshot is not None
                pairs.append((fc, observe_truth(env)))
            return pairs

        def observe_truth(env: HoverEnv) -> np.ndarray:
            from bfsitl.gym.observation import observe

            assert env._snapshot is not None
            return observe(env._snapshot, env.task.target, "truth")

        def mean(pairs: list[tuple[np.ndarray, np.ndarray]], slot: int) -> tuple[float, float]:
            return (
                float(np.mean([fc[slot] for fc, _ in pairs])),
                float(np.mean([truth[slot] for _, truth in pairs])),
            )

        rolled = fly((0.3, 0.0, hover, 0.0), 0.6)[20:]  # right wing down
        fc_roll, true_roll = mean(rolled, 6)
        assert true_roll > 0.05 and abs(fc_roll - true_roll) < 0.05
        fly((0.0, 0.0, hover, 0.0), 1.0)
        pitched = fly((0.0, 0.3, hover, 0.0), 0.6)[20:]  # stick forward: nose down
        fc_pitch, true_pitch = mean(pitched, 7)
        assert true_pitch > 0.05 and abs(fc_pitch - true_pitch) < 0.05
        fly((0.0, 0.0, hover, 0.0), 1.0)
        turning = fly((0.0, 0.0, hover, 0.5), 1.0)[20:]  # yaw right: z rate negative in FLU
        fc_rate, true_rate = mean(turning, 12)
        assert true_rate < -0.3 and abs(fc_rate - true_rate) < 0.1
        drifting = fly((0.0, 0.0, hover, 0.0), 1.5)
        # The wind from the east pushes west: the GPS and the truth agree on where.
        fc_last, truth_last = drifting[-1]
        assert truth_last[4] < -0.3  # moving west (east velocity < 0)
        assert abs(fc_last[1] - truth_last[1]) < 0.5  # east offset, GPS vs truth
        assert abs(fc_last[0] - truth_last[0]) < 0.5
        fc_climb, true_climb = mean(drifting, 5)
        assert abs(fc_climb - true_climb) < 0.2
    finally:
        env.close()
    assert sitl_processes_under(tmp_path) == []


def test_a_vector_of_environments_runs_side_by_side_and_leaves_nothing(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    from gymnasium.vector import AsyncVectorEnv

    def make(number: int):  # type: ignore[no-untyped-def]
        return lambda: HoverEnv(
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / f"env{number}")
        )

    envs = AsyncVectorEnv([make(0), make(1)])
    try:
        observations, _infos = envs.reset(seed=[1, 2])
        assert observations.shape == (2, OBSERVATION_SIZE)
        assert not np.array_equal(observations[0], observations[1])  # two targets
        assert len(sitl_processes_under(tmp_path)) == 2  # each in its own namespace
        for _ in range(50):
            observations, rewards, _terminated, _truncated, _infos = envs.step(
                np.tile(np.array([0.0, 0.0, 0.12, 0.0], dtype=np.float32), (2, 1))
            )
        assert np.all(np.isfinite(rewards))
    finally:
        envs.close()
    assert sitl_processes_under(tmp_path) == []


def env0_flies_as_alone(
    envs: Any, single: HoverEnv, *, after_reset: Callable[[], None] = lambda: None
) -> None:
    """Two environments (seeds 5 and 6) and the first of them alone, through one 0.5 s
    episode with the same actions: bit for bit the same, and the episode's end batched as
    Gymnasium does it (SAME_STEP)."""
    observations, info = envs.reset(seed=[5, 6])
    alone, _ = single.reset(seed=5)
    assert np.array_equal(observations[0], alone)
    assert not np.array_equal(observations[0], observations[1])
    after_reset()
    action = np.array([0.0, 0.0, 0.12, 0.0], dtype=np.float32)
    for _ in range(60):
        observations, rewards, _terminated, truncated, info = envs.step(np.tile(action, (2, 1)))
        alone, reward, _done, ended, alone_info = single.step(action)
        if "final_info" in info:
            break
        assert np.array_equal(observations[0], alone) and rewards[0] == reward
        assert info["distance_m"][0] == alone_info["distance_m"]
    assert ended and truncated.all() and info["_final_info"].all()
    assert np.array_equal(info["final_obs"][0], alone)  # the ended episode's last
    assert info["final_info"]["time_s"][0] == pytest.approx(0.5, abs=0.01)
    assert (info["time_s"] < 0.01).all()  # already the next episodes


def test_bfsitls_own_vector_environment_pins_each_firmware_and_flies_as_one_alone(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    envs = gymnasium.make_vec(
        "bfsitl/Hover-v0",
        num_envs=2,
        vectorization_mode="vector_entry_point",
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "vector"),
        max_episode_steps=50,
    )
    single = HoverEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "single"),
        max_episode_steps=50,
    )
    try:

        def pinned_a_core_each() -> None:
            pinned = [
                os.sched_getaffinity(pid) for pid in sitl_processes_under(tmp_path / "vector")
            ]
            assert len(pinned) == 2 and all(len(cores) == 1 for cores in pinned)
            if len(os.sched_getaffinity(0)) >= 2:
                assert pinned[0] != pinned[1]

        # Pinned, without spinning, in another process: the same flight as on its own.
        env0_flies_as_alone(envs, single, after_reset=pinned_a_core_each)
    finally:
        envs.close()
        single.close()
    assert sitl_processes_under(tmp_path) == []


CRASHING_PARENT = """
import os, sys, numpy as np
from gymnasium.vector import AsyncVectorEnv
from bfsitl.gym.env import HoverEnv
from bfsitl.gym.vector import FlightVectorEnv
from bfsitl.mission.session import SitlLaunch
firmware, folder, kind = sys.argv[1], sys.argv[2], sys.argv[3]
if kind == "async":
    envs = AsyncVectorEnv([lambda n=n: HoverEnv(sitl=SitlLaunch(firmware=firmware,
                                                                workdir=f"{folder}/env{n}"))
                           for n in range(2)])
else:
    envs = FlightVectorEnv("bfsitl.gym.env:HoverEnv", 2,
                           sitl=SitlLaunch(firmware=firmware, workdir=folder))
envs.reset(seed=0)
envs.step(np.zeros((2, 4), dtype=np.float32))
print("flying", flush=True)
os.kill(os.getpid(), 9)
"""


@pytest.mark.parametrize("kind", ["async", "own"])
def test_a_crashed_parent_leaves_no_firmware_running(
    lockstep_gps_46_firmware: Path, tmp_path: Path, kind: str
) -> None:
    parent = subprocess.run(
        [sys.executable, "-c", CRASHING_PARENT, str(lockstep_gps_46_firmware), str(tmp_path), kind],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert "flying" in parent.stdout, parent.stderr
    assert parent.returncode == -signal.SIGKILL
    deadline = time.monotonic() + 15.0
    while sitl_processes_under(tmp_path) and time.monotonic() < deadline:
        time.sleep(0.2)  # the workers notice their parent is gone and close their SITLs
    assert sitl_processes_under(tmp_path) == []


def test_step_before_reset_says_to_reset(lockstep_gps_46_firmware: Path) -> None:
    from bfsitl.errors import EnvironmentConfigError

    env = HoverEnv(sitl=SitlLaunch(firmware=lockstep_gps_46_firmware))
    try:
        with pytest.raises(EnvironmentConfigError, match=r"call env.reset\(\) first"):
            env.step(np.zeros(4, dtype=np.float32))
        env.reset(seed=0)
        with pytest.raises(EnvironmentConfigError, match="4 sticks"):
            env.step(np.zeros(3, dtype=np.float32))
    finally:
        env.close()
    assert not env.workdir.exists()  # its own temporary run directory is removed


@pytest.mark.timeout(300)
def test_environments_as_ray_actors_fly_as_one_alone_and_leave_nothing(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """Two environments on a cluster of a head and two worker nodes with empty caches: the
    firmware travels, environment 0 flies the same flight bit for bit as the same environment
    here, the episode's end comes as Gymnasium batches it, and close() leaves no SITL."""
    pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    from bfsitl.cli.doctor import stale_sitl_processes
    from bfsitl.gym.ray_vector import RayVectorEnv

    before = {pid for pid, _name in stale_sitl_processes()}
    cluster = Cluster(
        initialize_head=True,
        head_node_args={
            "num_cpus": 0,
            "include_dashboard": False,
            "object_store_memory": 100_000_000,
        },
    )
    caches = [tmp_path / f"node{index}-cache" for index in range(2)]
    single = HoverEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "single"),
        max_episode_steps=50,
    )
    envs = None
    try:
        for cache in caches:
            cluster.add_node(
                num_cpus=1,
                object_store_memory=100_000_000,
                env_vars={"BFSITL_CACHE_DIR": str(cache)},
            )
        cluster.wait_for_nodes()
        envs = RayVectorEnv(
            "bfsitl.gym.env:HoverEnv",
            2,
            address=cluster.address,
            sitl=SitlLaunch(firmware=str(lockstep_gps_46_firmware)),
            max_episode_steps=50,
        )
        assert all(list(cache.glob("received/*/*_SITL")) for cache in caches)
        env0_flies_as_alone(envs, single)
    finally:
        if envs is not None:
            envs.close()
        single.close()
        cluster.shutdown()
    deadline = time.monotonic() + 10
    while {pid for pid, _name in stale_sitl_processes()} - before and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not {pid for pid, _name in stale_sitl_processes()} - before
