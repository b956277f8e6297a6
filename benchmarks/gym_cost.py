"""Where one learning step's CPU goes: bfsitl's Python, the compiled lockstep loop (physics and
hand-over) and the firmware, per ``bfsitl/Hover-v0`` step, and the step rate their sum allows.

Each run is one ``HoverEnv`` (4.6.0's GPS lockstep build, shared memory, 100 Hz) flown by the
hand-written policy for ``--steps`` steps after a warm-up, pinned with its SITL to one core
so that neither side spins: the Python thread's CPU time is then its own work and the
SITL's is the firmware's.  Per run:

* **Python**: the thread's CPU time less the time inside the compiled loop, per step (the
  MSP round trip's Python side, the samples, the observation, the reward, the info);
* **loop**: the compiled lockstep loop's CPU time per step (the physics in C, the hand-overs);
* **FC**: the SITL process's CPU time per step (its passes and its MSP);
* **ceiling**: ``cores x 1 s / (Python + loop + FC)``, the aggregate step rate this machine's
  cores would give if every core did nothing else (no vector environment's pipes, no learner);
* **calls**: Python function calls per step, counted by a profiled run (the one figure that
  does not move with the machine).

Then two environments in ``FlightVectorEnv`` (pinned workers, the default), stepped by the
hand-written policy for ``--seconds``: the CPU time per environment step of this process
(the policy and the vector environment's side), of the workers (each environment's Python
and compiled loop, the pipes) and of the firmwares, beside the steps per second they gave.

This machine's speed moves by up to a factor of two within minutes, so a comparison of two
source trees (``--against DIR``, a checkout of another commit) alternates them run by run,
each run in a fresh process, and reports the minimum and the median.

Run: ``python benchmarks/gym_cost.py [--runs 5] [--steps 5000] [--seconds 15] [--against DIR]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from pathlib import Path

from loop_cost import (
    _commit,
    add_comparison_options,
    compared_trees,
    run_fresh,
    time_compiled_loop,
)


def worker(firmware: str, steps: int, seed: int, profiled: bool) -> dict[str, float]:
    """One run in this process (the tree on ``sys.path``); its figures per step."""
    import cProfile
    import time

    from lockstep import sitl_cpu_s

    from bfsitl.backend.options import Timing
    from bfsitl.gym.baseline import hand_policy
    from bfsitl.gym.env import HoverEnv
    from bfsitl.mission.session import SitlLaunch

    inside_s = time_compiled_loop()
    env = HoverEnv(
        sitl=SitlLaunch(firmware=firmware),
        control_hz=100.0,
        pin_core=True,  # the SITL shares this core: nobody spins
        timing=Timing(lockstep_spin=False, lockstep_exchange="shm"),
    )
    try:
        observation, _info = env.reset(seed=seed)

        def fly(count: int) -> None:
            nonlocal observation
            for _ in range(count):
                observation, _r, terminated, truncated, _i = env.step(hand_policy(observation))
                if terminated or truncated:
                    observation, _i = env.reset()

        fly(200)  # past the first reset's boot and take-off
        session = env._vehicle  # noqa: SLF001 - the benchmark reads the SITL's pid
        pid = session.sitl.pid if session is not None and session.sitl is not None else None
        fc_before = sitl_cpu_s(pid)
        inside_s[0] = 0.0
        cpu_before, wall_before = time.thread_time(), time.perf_counter()
        fly(steps)
        cpu_s = time.thread_time() - cpu_before
        wall_s = time.perf_counter() - wall_before
        fc_after = sitl_cpu_s(pid)
        loop_s = inside_s[0]
        figures = {
            "python_us": (cpu_s - loop_s) / steps * 1e6,
            "loop_us": loop_s / steps * 1e6,
            "fc_us": (fc_after - fc_before) / steps * 1e6
            if fc_before is not None and fc_after is not None
            else float("nan"),
            "steps_per_s": steps / wall_s,
        }
        if profiled:
            import pstats

            profile = cProfile.Profile()
            profile.enable()
            fly(steps)
            profile.disable()
            figures["calls_per_step"] = pstats.Stats(profile).total_calls / steps  # type: ignore[attr-defined]
    finally:
        env.close()
    return figures


def _cpu_s_by_process() -> dict[int, tuple[str, float]]:
    """CPU seconds so far of this process and every process it started, by pid: (name, s)."""
    table: dict[int, tuple[int, str, float]] = {}
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue  # ended meanwhile
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        fields = stat[stat.rindex(")") + 2 :].split()
        cpu_s = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        table[int(entry.name)] = (int(fields[1]), name, cpu_s)
    mine = {os.getpid()}
    grew = True
    while grew:
        grew = False
        for pid, (parent, _name, _cpu) in table.items():
            if parent in mine and pid not in mine:
                mine.add(pid)
                grew = True
    return {pid: (table[pid][1], table[pid][2]) for pid in mine if pid in table}


def vector_split(firmware: str, seconds: float) -> dict[str, float]:
    """Two environments in FlightVectorEnv: CPU microseconds per environment step of this
    process, the workers and the firmwares, and the steps per second."""
    import time

    import gymnasium
    import numpy as np

    import bfsitl.gym  # noqa: F401 - registers the environments
    from bfsitl.gym.baseline import hand_policy
    from bfsitl.mission.session import SitlLaunch

    count = 2
    envs = gymnasium.make_vec(
        "bfsitl/Hover-v0",
        num_envs=count,
        vectorization_mode="vector_entry_point",
        sitl=SitlLaunch(firmware=firmware),
        control_hz=100.0,
    )
    try:
        observations, _infos = envs.reset(seed=list(range(count)))

        def fly_for(wall_s: float) -> int:
            nonlocal observations
            steps, began = 0, time.perf_counter()
            while time.perf_counter() - began < wall_s:
                actions = np.stack([hand_policy(o) for o in observations])
                observations, *_rest = envs.step(actions)
                steps += count
            return steps

        fly_for(2.0)  # past the boots and take-offs
        before, began = _cpu_s_by_process(), time.perf_counter()
        steps = fly_for(seconds)
        wall_s, after = time.perf_counter() - began, _cpu_s_by_process()
    finally:
        envs.close()
    spent = {"main": 0.0, "workers": 0.0, "firmwares": 0.0}
    for pid, (name, cpu_s) in after.items():
        if pid not in before:
            continue
        used_us = (cpu_s - before[pid][1]) / steps * 1e6
        if pid == os.getpid():
            spent["main"] += used_us
        elif name.startswith("betaflight"):
            spent["firmwares"] += used_us
        else:
            spent["workers"] += used_us
    return {**spent, "steps_per_s": steps / wall_s}


def run_in(tree: Path, args: argparse.Namespace, profiled: bool) -> dict[str, float]:
    """One run in a fresh process that imports bfsitl from ``tree``."""
    arguments = [args.firmware, "--steps", str(args.steps), "--seed", str(args.seed)]
    return run_fresh(Path(__file__).resolve(), tree, [*arguments, *(["--profiled"] * profiled)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="runs per tree")
    parser.add_argument("--steps", type=int, default=5000, help="steps per run")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--firmware", default="4.6.0-gps-lockstep")
    parser.add_argument(
        "--seconds", type=float, default=15.0, help="wall seconds of the two-environment run"
    )
    add_comparison_options(parser)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.steps, args.seed, args.profiled)))
        return

    trees = compared_trees(args)
    runs: dict[Path, list[dict[str, float]]] = {tree: [] for tree in trees}
    for index in range(args.runs):
        for tree in trees:  # alternated, so that a slow minute falls on both
            runs[tree].append(run_in(tree, args, profiled=False))
        print(f"{index + 1}/{args.runs} runs per tree", file=sys.stderr)
    cores = os.cpu_count() or 1
    print(
        "| tree | Python us/step: min | median | loop us/step: median | FC us/step: median "
        f"| sum: median | ceiling on {cores} cores, steps/s | one env pinned, steps/s: median "
        "| calls per step |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for tree in trees:
        counted = run_in(tree, args, profiled=True)
        flown = runs[tree]
        python = [f["python_us"] for f in flown]
        loop = statistics.median(f["loop_us"] for f in flown)
        fc = statistics.median(f["fc_us"] for f in flown)
        total = statistics.median(f["python_us"] + f["loop_us"] + f["fc_us"] for f in flown)
        label = _commit(tree) + (" (this tree)" if tree == trees[0] else "")
        print(
            f"| {label} | {min(python):.0f} | {statistics.median(python):.0f} | {loop:.0f} "
            f"| {fc:.0f} | {total:.0f} | {cores * 1e6 / total:,.0f} "
            f"| {statistics.median(f['steps_per_s'] for f in flown):,.0f} "
            f"| {counted['calls_per_step']:.0f} |"
        )
    print(f"two environments in FlightVectorEnv, {args.seconds:g} s", file=sys.stderr)
    split = vector_split(args.firmware, args.seconds)
    total = split["main"] + split["workers"] + split["firmwares"]
    print()
    print(
        "| two environments in FlightVectorEnv, CPU us per environment step: this process "
        "| workers | firmwares | sum | ceiling on these cores, steps/s | steps/s measured |"
    )
    print("|---|---|---|---|---|---|")
    print(
        f"| (this tree) | {split['main']:.0f} | {split['workers']:.0f} | "
        f"{split['firmwares']:.0f} | {total:.0f} | {cores * 1e6 / total:,.0f} | "
        f"{split['steps_per_s']:,.0f} |"
    )


if __name__ == "__main__":
    main()
