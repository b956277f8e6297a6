"""How fast the Gymnasium environments step the real firmware, against wall-clock pacing.

All rows in one run, on this machine, with ``bfsitl/Hover-v0`` flown by the hand-written
policy (``bfsitl.gym.baseline``) at ``--control-hz``:

* **reset**: wall seconds of ``reset()``, median over the resets of the single-environment
  rows (warm ones, with the first, cold, one as the maximum);
* **1 environment** in this process, each way it can use the machine: spinning on two cores
  (the default in a main process), or pinned with its SITL to one core
  (``pin_core=True``), each through the shared-memory exchange with the compiled step (the
  default) and with the pure-Python one, and, for comparison, UDP;
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

What limits it: in lockstep the firmware and bfsitl take turns, so one environment is one
core's work at most (spinning on two cores only shortens the hand-over); the aggregate grows
with the cores, not past them.  Run:
``python benchmarks/gym.py [--seconds 20] [--control-hz 100] [--firmware NAME]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

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
    firmware: str, control_hz: float, seconds: float, count: int, *, own: bool
) -> dict[str, float]:
    """``count`` environments in ``AsyncVectorEnv`` (its default autoreset: the step after
    an ending resets) or in bfsitl's ``FlightVectorEnv`` (resets in the same step)."""
    if own:
        envs = gymnasium.make_vec(
            "bfsitl/Hover-v0",
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--control-hz", type=float, default=100.0)
    parser.add_argument("--firmware", default=DEFAULT_FIRMWARE)
    parser.add_argument(
        "--ray", action="store_true", help="also 2 environments as Ray actors on a local cluster"
    )
    args = parser.parse_args()
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
