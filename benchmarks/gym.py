"""How fast the Gymnasium environments step the real firmware, against wall-clock pacing.

All rows in one run, on this machine, with ``bfsitl/Hover-v0`` flown by the hand-written
policy (``bfsitl.gym.baseline``) at ``--control-hz``:

* **reset**: wall seconds of ``reset()`` (end the SITL, boot a fresh one from the provisioned
  EEPROM, arm, take off to 1.5 m), median over the resets of the single-environment row;
* **1, 2, 4 environments**: environment steps per wall second and simulated seconds per wall
  second, summed over the environments (``gymnasium.vector.AsyncVectorEnv`` for 2 and 4,
  one process each), resets included, over ``--seconds`` of wall time;
* **the baseline**: what a wall-clock SITL gives (gym-pybullet-drones' ``BetaAviary`` runs
  the stock SITL that way): a stock 4.6.0 SITL with bfsitl's real-time bridge, the same
  control loop paced by the wall clock, measured here in the same run: its simulated seconds
  per wall second are 1.0 by construction, and its step rate is the control rate at best.

What limits it: one environment keeps about one core busy (the firmware's passes, the physics
and the MSP exchange take turns in lockstep); so the aggregate grows with the cores, not past.
Run: ``python benchmarks/gym.py [--seconds 20] [--control-hz 100] [--firmware NAME]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace

import numpy as np

import bfsitl.gym  # noqa: F401  (registers the environments)
from bfsitl.gym.baseline import hand_policy
from bfsitl.gym.env import DEFAULT_FIRMWARE, HoverEnv
from bfsitl.gym.sticks import sticks_to_rc
from bfsitl.mission.session import FlightSession, SessionConfig


def single(firmware: str, control_hz: float, seconds: float, *, spin: bool
           ) -> tuple[dict[str, float], list[float]]:
    env = HoverEnv(firmware=firmware, control_hz=control_hz, spin=spin)
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


def vector(firmware: str, control_hz: float, seconds: float, count: int, *, spin: bool
           ) -> dict[str, float]:
    from gymnasium.vector import AsyncVectorEnv

    envs = AsyncVectorEnv([lambda: HoverEnv(firmware=firmware, control_hz=control_hz,
                                            spin=spin) for _ in range(count)])
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
            # The time of an episode that just ended; the next step resets it (autoreset).
            sim_s += np.where(ended, infos["time_s"], 0.0)
        sim_s += np.where(ended, 0.0, infos["time_s"])
        wall_s = time.monotonic() - started
    finally:
        envs.close()
    return {"steps_per_s": steps / wall_s, "sim_per_wall": float(sim_s.sum()) / wall_s}


def wall_clock_baseline(control_hz: float, seconds: float) -> dict[str, float]:
    """The stock SITL at real time: the same loop, paced by the wall clock."""
    config = SessionConfig.for_autopilot(control_rate_hz=control_hz, firmware=None, speed=1.0)
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
    args = parser.parse_args()
    rows = []
    print("[gym bench] wall-clock baseline (stock SITL, real time)", flush=True)
    baseline = wall_clock_baseline(args.control_hz, min(args.seconds, 10.0))
    rows.append(("wall-clock SITL (stock, real time)", 1, baseline))
    resets: list[float] = []
    for spin in (False, True):
        print(f"[gym bench] 1 environment, spin={spin}", flush=True)
        one, resets_here = single(args.firmware, args.control_hz, args.seconds, spin=spin)
        resets += resets_here
        rows.append((f"bfsitl/Hover-v0, lockstep, spin={spin}", 1, one))
    for count in (2, 4):
        for spin in (False, True):
            print(f"[gym bench] {count} environments (AsyncVectorEnv), spin={spin}",
                  flush=True)
            rows.append((f"bfsitl/Hover-v0, lockstep, AsyncVectorEnv, spin={spin}", count,
                         vector(args.firmware, args.control_hz, args.seconds, count,
                                spin=spin)))
    print(f"\ncontrol at {args.control_hz:g} Hz, {args.seconds:g} s of wall time per row; "
          f"reset: median {statistics.median(resets):.2f} s wall over {len(resets)} resets "
          f"(max {max(resets):.2f} s)")
    print("| environment | envs | steps/s (all envs) | sim s per wall s | x the wall-clock SITL |")
    print("| --- | ---: | ---: | ---: | ---: |")
    for name, count, row in rows:
        print(f"| {name} | {count} | {row['steps_per_s']:.0f} | {row['sim_per_wall']:.1f} | "
              f"{row['sim_per_wall'] / baseline['sim_per_wall']:.1f}x |")


if __name__ == "__main__":
    main()
