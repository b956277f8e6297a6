"""How fast the Gymnasium environments step the real firmware, against wall-clock pacing.

All rows in one run, on this machine, with ``bfsitl/Hover-v0`` flown by the hand-written
policy (``bfsitl.gym.baseline``) at ``--control-hz``:

* **reset**: wall seconds of ``reset()``, median over the resets of the single-environment
  rows (warm ones, with the first, cold, one as the maximum);
* **1 environment** in this process, each way it can use the machine: spinning on two cores
  (the default in a main process), or pinned with its SITL to one core
  (``pin_core=True``), each through the shared-memory exchange with the compiled step (the
  default) and with the pure-Python one, and, for comparison, UDP;
* **the other tasks**: Waypoints-v0 and Recover-v0 (its throws flown by the same policy, in
  ANGLE mode) in ``FlightVectorEnv`` with 2 environments, their resets counted;
* **2 and 4 environments**: Gymnasium's ``AsyncVectorEnv`` (one worker process each, pinned
  by default) and bfsitl's own ``FlightVectorEnv`` (``gymnasium.make_vec(...,
  vectorization_mode="vector_entry_point")``: pinned workers, numbers in shared memory);
  the default step (compiled where it builds);
  steps per wall second and simulated seconds per wall second summed over the environments,
  resets included, over ``--seconds`` of wall time;
* **the baseline**: what a wall-clock SITL gives (gym-pybullet-drones' ``BetaAviary`` runs
  the stock SITL that way): a stock 4.6.0 SITL with bfsitl's real-time bridge, the same
  control loop paced by the wall clock, measured here in the same run: its simulated seconds
  per wall second are 1.0 by construction, and its step rate is the control rate at best.

``--sb3`` instead measures Stable-Baselines3's PPO training (collecting and learning, as
``examples/train_hover.py`` sets it up) on SB3's ``SubprocVecEnv`` and on bfsitl's
``Sb3VectorEnv``, beside the two environments stepped alone.  ``--train-minutes M`` instead
trains Hover-v0 with each of ``--methods`` (``examples/train_hover.py``) for
``--train-seeds`` seeds and prints each run's time to criterion; ``--policy FILE.onnx``
times an exported policy's inference.

What limits it: in lockstep the firmware and bfsitl take turns, so one environment is one
core's work at most (spinning on two cores only shortens the hand-over); the aggregate grows
with the cores, not past them.  Run:
``python benchmarks/gym.py [--seconds 20] [--control-hz 100] [--firmware NAME]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import gymnasium
import gymnasium.vector
import numpy as np

import bfsitl.gym  # noqa: F401  (registers the environments)
from bfsitl.backend.options import Timing
from bfsitl.gym.baseline import hand_policy
from bfsitl.gym.env import DEFAULT_FIRMWARE, HoverEnv
from bfsitl.gym.sticks import sticks_to_rc
from bfsitl.link.shm_exchange import shm_exchange_supported
from bfsitl.mission.session import FlightSession, SessionConfig, SitlLaunch

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "train_hover.py"


def single(
    firmware: str, control_hz: float, seconds: float, *, spin: bool, pin: bool, exchange: str
) -> tuple[dict[str, float], list[float]]:
    env = HoverEnv(
        sitl=SitlLaunch(firmware=firmware),
        control_hz=control_hz,
        pin_core=pin,
        timing=Timing(lockstep_spin=spin, lockstep_exchange=exchange),
    )
    resets: list[float] = []
    steps, sim_s = 0, 0.0
    try:
        started = time.monotonic()
        began = time.monotonic()
        observation, info = env.reset(seed=0)
        resets.append(time.monotonic() - began)
        while time.monotonic() - started < seconds:
            observation, _reward, terminated, truncated, info = env.step(hand_policy(observation))
            steps += 1
            if terminated or truncated:
                sim_s += info["time_s"]
                began = time.monotonic()
                observation, info = env.reset()
                resets.append(time.monotonic() - began)
        sim_s += info["time_s"]
        wall_s = time.monotonic() - started
    finally:
        env.close()
    return {"steps_per_s": steps / wall_s, "sim_per_wall": sim_s / wall_s}, resets


def vector(
    firmware: str,
    control_hz: float,
    seconds: float,
    count: int,
    *,
    own: bool,
    env_id: str = "bfsitl/Hover-v0",
) -> dict[str, float]:
    """``count`` environments in ``AsyncVectorEnv`` (its default autoreset: the step after
    an ending resets; Hover-v0) or in bfsitl's ``FlightVectorEnv`` (resets in the same step;
    ``env_id``)."""
    if own:
        envs = gymnasium.make_vec(
            env_id,
            num_envs=count,
            vectorization_mode="vector_entry_point",
            sitl=SitlLaunch(firmware=firmware),
            control_hz=control_hz,
        )
    else:
        envs = gymnasium.vector.AsyncVectorEnv(
            [
                lambda: HoverEnv(sitl=SitlLaunch(firmware=firmware), control_hz=control_hz)
                for _ in range(count)
            ]
        )
    return _drive(envs, count, seconds, final_info=own)


def _drive(
    envs: gymnasium.vector.VectorEnv, count: int, seconds: float, *, final_info: bool
) -> dict[str, float]:
    """Step ``envs`` with the hand-written policy for ``seconds`` of wall time, then close."""
    own = final_info
    steps = 0
    sim_s = np.zeros(count)
    try:
        observations, infos = envs.reset(seed=list(range(count)))
        started = time.monotonic()
        while time.monotonic() - started < seconds:
            actions = np.stack([hand_policy(o) for o in observations])
            observations, _rewards, terminated, truncated, infos = envs.step(actions)
            steps += count
            ended = np.logical_or(terminated, truncated)
            if own:
                # The episode that ended is in final_info; infos are the next one's.
                for index in np.flatnonzero(ended):
                    sim_s[index] += infos["final_info"]["time_s"][index]
            else:
                sim_s += np.where(ended, infos["time_s"], 0.0)
        if own:
            sim_s += infos["time_s"]
        else:
            sim_s += np.where(ended, 0.0, infos["time_s"])
        wall_s = time.monotonic() - started
    finally:
        envs.close()
    return {"steps_per_s": steps / wall_s, "sim_per_wall": float(sim_s.sum()) / wall_s}


def ray_vector(firmware: str, control_hz: float, seconds: float, count: int) -> dict[str, float]:
    """``count`` environments as Ray actors (bfsitl.gym.ray_vector) on a local cluster of one
    node with ``count`` CPUs: what the Ray calls cost against FlightVectorEnv's pipes."""
    from ray.cluster_utils import Cluster

    from bfsitl.gym.ray_vector import RayVectorEnv

    cluster = Cluster(
        initialize_head=True,
        head_node_args={
            "num_cpus": count,
            "include_dashboard": False,
            "object_store_memory": 100_000_000,
        },
    )
    try:
        envs = RayVectorEnv(
            "bfsitl.gym.env:HoverEnv",
            count,
            address=cluster.address,
            sitl=SitlLaunch(firmware=firmware),
            control_hz=control_hz,
        )
        return _drive(envs, count, seconds, final_info=True)
    finally:
        cluster.shutdown()


def sb3_training(
    firmware: str, control_hz: float, seconds: float, count: int, *, own: bool
) -> dict[str, float]:
    """Stable-Baselines3's PPO training (collecting and learning, as examples/train_hover.py
    sets it up) for ``seconds`` of wall time, on SB3's ``SubprocVecEnv`` of scaled
    environments (each in a Monitor) or on bfsitl's ``Sb3VectorEnv``."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.vec_env import SubprocVecEnv

    from bfsitl.gym.sb3_vector import Sb3VectorEnv
    from bfsitl.gym.scaled import ScaledEnv

    torch.set_num_threads(1)
    episode_steps = round(10.0 * control_hz)
    if own:
        envs = Sb3VectorEnv(
            gymnasium.make_vec(
                "bfsitl/Hover-v0",
                num_envs=count,
                sitl=SitlLaunch(firmware=firmware),
                control_hz=control_hz,
                max_episode_steps=episode_steps,
            )
        )
    else:

        def make() -> Monitor:
            return Monitor(
                ScaledEnv(
                    HoverEnv(
                        sitl=SitlLaunch(firmware=firmware),
                        control_hz=control_hz,
                        max_episode_steps=episode_steps,
                    )
                )
            )

        envs = SubprocVecEnv([make] * count, start_method="fork")
    model = PPO(
        "MlpPolicy",
        envs,
        n_steps=512,
        batch_size=256,
        learning_rate=5e-4,
        gamma=0.98,
        seed=0,
        device="cpu",
        policy_kwargs={"net_arch": [64, 64], "log_std_init": -1.0},
    )
    model.set_logger(Logger(folder=None, output_formats=[]))
    started = time.monotonic()
    sim_s = [0.0]

    class Clock(BaseCallback):
        def _on_step(self) -> bool:
            for info in self.locals["infos"]:
                if "episode" in info:
                    sim_s[0] += info["episode"]["l"] / control_hz
            return time.monotonic() - started < seconds

    try:
        model.learn(10**9, callback=Clock())
        wall_s = time.monotonic() - started
    finally:
        envs.close()
    return {"steps_per_s": model.num_timesteps / wall_s, "sim_per_wall": sim_s[0] / wall_s}


def training_to_criterion(
    firmware: str, method: str, minutes: float, seed: int, out: Path
) -> dict[str, object]:
    """examples/train_hover.py with ``method`` for ``minutes``: its evaluation.json."""
    run = out / f"{method}-seed{seed}"
    subprocess.run(
        [
            sys.executable,
            str(EXAMPLE),
            "--method",
            method,
            "--minutes",
            str(minutes),
            "--seed",
            str(seed),
            "--firmware",
            firmware,
            "--out",
            str(run),
        ],
        check=True,
    )
    summary: dict[str, object] = json.loads((run / "evaluation.json").read_text())
    return summary


def wall_clock_baseline(control_hz: float, seconds: float) -> dict[str, float]:
    """The stock SITL at real time: the same loop, paced by the wall clock."""
    config = SessionConfig.for_autopilot(control_rate_hz=control_hz, timing=Timing(speed=1.0))
    period_s = 1.0 / control_hz
    steps = 0
    with FlightSession(config) as session:
        session.arm()
        started_sim, started = session.time_s, time.monotonic()
        next_s = started_sim
        while time.monotonic() - started < seconds:
            session.set_rc(sticks_to_rc([0.0, 0.0, -1.0, 0.0], replace(session.rc_command)))
            next_s += period_s
            wait_s = next_s - session.time_s
            if wait_s > 0:
                session.clock.sleep_s(wait_s)
            session.sample()
            steps += 1
        wall_s = time.monotonic() - started
        sim_s = session.time_s - started_sim
    return {"steps_per_s": steps / wall_s, "sim_per_wall": sim_s / wall_s}


def policy_inference(path: Path) -> None:
    """An exported policy's time per call with onnxruntime (one thread), one observation
    and a batch of 64, against one control period at its rate."""
    from bfsitl.gym.observation import OBSERVATION_SIZE
    from bfsitl.gym.onnx_policy import OnnxPolicy

    policy = OnnxPolicy(path)
    rows = []
    for batch in (1, 64):
        observations = np.zeros((batch, OBSERVATION_SIZE), dtype=np.float32)
        observations[:, 15] = 9.81
        times = []
        for _ in range(3000):
            began = time.perf_counter()
            policy(observations)
            times.append(time.perf_counter() - began)
        rows.append((batch, statistics.median(times) * 1e6, float(np.percentile(times, 99)) * 1e6))
    period_us = 1e6 / policy.control_hz
    print(f"\n{path.name}: trained at {policy.control_hz:g} Hz ({period_us:.0f} us a step)")
    print("| observations per call | median us | 99th percentile us | share of a control period |")
    print("| ---: | ---: | ---: | ---: |")
    for batch, median_us, p99_us in rows:
        print(f"| {batch} | {median_us:.1f} | {p99_us:.1f} | {median_us / period_us:.2%} |")


def sb3_table(args: argparse.Namespace) -> None:
    """Two environments stepped by the hand-written policy (no learner), then PPO training on
    SB3's SubprocVecEnv and on Sb3VectorEnv: what the learner costs, and what the adapter
    saves."""
    rows = []
    print("[gym bench] 2 environments, FlightVectorEnv, the hand-written policy", flush=True)
    rows.append(
        (
            "FlightVectorEnv, the hand-written policy (no learner)",
            vector(args.firmware, args.control_hz, args.seconds, 2, own=True),
        )
    )
    for own, name in ((False, "SB3's SubprocVecEnv of ScaledEnv"), (True, "Sb3VectorEnv")):
        print(f"[gym bench] PPO training, 2 environments, {name}", flush=True)
        rows.append(
            (
                f"PPO training (collect + learn), {name}",
                sb3_training(args.firmware, args.control_hz, args.seconds, 2, own=own),
            )
        )
    print(f"\n2 environments, control at {args.control_hz:g} Hz, {args.seconds:g} s per row")
    print("| what steps them | steps/s (both envs) | sim s per wall s |")
    print("| --- | ---: | ---: |")
    for name, row in rows:
        print(f"| {name} | {row['steps_per_s']:.0f} | {row['sim_per_wall']:.1f} |")


def train_table(args: argparse.Namespace) -> None:
    """The training rows: each method and seed, its time to criterion."""
    results = []
    with tempfile.TemporaryDirectory(prefix="bfsitl-gym-bench-") as scratch:
        out = args.train_out or Path(scratch)
        for method in args.methods.split(","):
            for seed in range(args.train_seeds):
                print(f"[gym bench] training {method}, seed {seed}", flush=True)
                summary = training_to_criterion(
                    args.firmware, method, args.train_minutes, seed, out
                )
                results.append((method, seed, summary))
    print(f"\nHover-v0 at 50 Hz, 2 environments, {args.train_minutes:g} min of training each")
    print("| method | seed | steps | time to criterion | held at the end |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for method, seed, summary in results:
        training = summary["training"]
        reached = summary["time_to_criterion_s"]
        last = summary["checkpoints"][-1]  # type: ignore[index]
        print(
            f"| {method} | {seed} | {training['steps']} | "  # type: ignore[index]
            f"{'not reached' if reached is None else f'{reached:.0f} s'} | "
            f"{last['held']} of {last['flights']} |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--control-hz", type=float, default=100.0)
    parser.add_argument("--firmware", default=DEFAULT_FIRMWARE)
    parser.add_argument(
        "--ray", action="store_true", help="also 2 environments as Ray actors on a local cluster"
    )
    parser.add_argument(
        "--sb3",
        action="store_true",
        help="only PPO training on 2 environments (Stable-Baselines3): SubprocVecEnv against "
        "bfsitl's Sb3VectorEnv, beside the environments alone, at --control-hz",
    )
    parser.add_argument(
        "--train-minutes",
        type=float,
        default=0.0,
        help="instead of the step rates: train Hover-v0 with each of --methods for this "
        "long (examples/train_hover.py) and report the time to criterion; 0: not",
    )
    parser.add_argument("--methods", default="ppo,sac,td3")
    parser.add_argument("--train-seeds", type=int, default=1)
    parser.add_argument(
        "--train-out",
        type=Path,
        default=None,
        help="keep each training run's folder here (default: a temporary one, removed)",
    )
    parser.add_argument(
        "--policy",
        type=Path,
        default=None,
        metavar="FILE.onnx",
        help="only time an exported policy's inference (examples/train_hover.py writes one)",
    )
    args = parser.parse_args()
    if args.policy:
        policy_inference(args.policy)
        return
    if args.train_minutes:
        train_table(args)
        return
    if args.sb3:
        sb3_table(args)
        return
    rows = []
    print("[gym bench] wall-clock baseline (stock SITL, real time)", flush=True)
    baseline = wall_clock_baseline(args.control_hz, min(args.seconds, 10.0))
    rows.append(("wall-clock SITL (stock, real time)", 1, baseline))
    resets: list[float] = []
    exchanges = ["shm", "udp"] if shm_exchange_supported() else ["udp"]
    for exchange in exchanges:
        for spin, pin, how in ((True, False, "spin, 2 cores"), (False, True, "pinned, 1 core")):
            print(f"[gym bench] 1 environment, {how}, {exchange}", flush=True)
            one, resets_here = single(
                args.firmware, args.control_hz, args.seconds, spin=spin, pin=pin, exchange=exchange
            )
            resets += resets_here
            rows.append((f"Hover-v0, {how}, {exchange}", 1, one))
    for count in (2, 4):
        for own, name in ((False, "AsyncVectorEnv"), (True, "FlightVectorEnv")):
            print(f"[gym bench] {count} environments, {name}", flush=True)
            rows.append(
                (
                    f"Hover-v0, {name} (pinned workers)",
                    count,
                    vector(args.firmware, args.control_hz, args.seconds, count, own=own),
                )
            )
    for env_id in ("bfsitl/Waypoints-v0", "bfsitl/Recover-v0"):
        # The other tasks: shorter episodes, so more resets (a throw's hand holds the quad
        # 0.5 s of simulated time before each), in the same vector environment.
        task = env_id.split("/")[1]
        print(f"[gym bench] 2 environments, FlightVectorEnv, {task}", flush=True)
        rows.append(
            (
                f"{task}, FlightVectorEnv (pinned workers)",
                2,
                vector(args.firmware, args.control_hz, args.seconds, 2, own=True, env_id=env_id),
            )
        )
    if args.ray:
        print("[gym bench] 2 environments, RayVectorEnv (local cluster)", flush=True)
        rows.append(
            (
                "Hover-v0, RayVectorEnv (Ray actors, one node)",
                2,
                ray_vector(args.firmware, args.control_hz, args.seconds, 2),
            )
        )
    print(
        f"\ncontrol at {args.control_hz:g} Hz, {args.seconds:g} s of wall time per row; "
        f"reset: median {statistics.median(resets):.3f} s wall over {len(resets)} resets "
        f"(max {max(resets):.2f} s)"
    )
    print("| environment | envs | steps/s (all envs) | sim s per wall s | x the wall-clock SITL |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, count, row in rows:
        print(
            f"| {name} | {count} | {row['steps_per_s']:.0f} | {row['sim_per_wall']:.1f} | "
            f"{row['sim_per_wall'] / baseline['sim_per_wall']:.1f}x |"
        )


if __name__ == "__main__":
    main()
