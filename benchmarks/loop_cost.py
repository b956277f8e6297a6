"""The mission loop's own cost against the firmware's: what bfsitl's Python spends per control
step and per simulated millisecond, beside what the SITL spends, on the default mission.

Each flight is the default mission of ``benchmarks/lockstep.py`` (arm, 2 s on the ground,
take off to 2 m, hold ``--hold`` s, land; the fused controller, ``--seed``) through shared
memory, pinned to one core so that neither side spins: the Python process's CPU time is
then its own work, and the SITL's is the firmware's.  Per flight:

* **loop**: the Python thread's CPU time in ``bfsitl.fly`` less the time inside the compiled
  lockstep loop (the physics and the hand-over), per control step and per simulated ms;
* **FC**: the SITL process's CPU time per simulated millisecond (its passes, its MSP);
* **calls**: Python function calls per control step, counted by a profiled flight (the one
  figure that does not move with the machine).

This machine's speed moves by up to a factor of two within minutes, so a comparison of two
source trees (``--against DIR``, a checkout of another commit) alternates them flight by
flight, each flight in a fresh process, and reports the minimum and the median.

Run: ``python benchmarks/loop_cost.py [--flights 10] [--against /path/to/old/checkout]``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

from lockstep import firmware_path

HERE = Path(__file__).resolve().parent
SOURCE = HERE.parent / "src"


def time_compiled_loop() -> list[float]:
    """From now on, add the thread CPU time spent inside the compiled lockstep loop to the
    one-element list returned (this process's bfsitl only)."""
    import time

    import bfsitl.sim.lockstep_stepper as stepper

    inside_s = [0.0]
    run = stepper.KernelStepper.run

    def timed_run(self: object, *args: object, **kwargs: object) -> object:
        began = time.thread_time()
        try:
            return run(self, *args, **kwargs)  # type: ignore[arg-type]
        finally:
            inside_s[0] += time.thread_time() - began

    stepper.KernelStepper.run = timed_run  # type: ignore[method-assign]
    return inside_s


def run_fresh(script: Path, tree: Path, arguments: list[str]) -> dict[str, float]:
    """``script --worker ...`` in a fresh process that imports bfsitl from ``tree``; the
    figures its last line prints as JSON."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tree / "src"), str(HERE)]))
    command = [sys.executable, str(script), "--worker", *arguments]
    done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.exit(f"a run with {tree} failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])  # type: ignore[no-any-return]


def add_comparison_options(parser: argparse.ArgumentParser) -> None:
    """``--against DIR`` (repeatable), and the hidden options of a run in a fresh process."""
    parser.add_argument(
        "--against", type=Path, action="append", default=[], help="another checkout to compare"
    )
    parser.add_argument("--worker", help=argparse.SUPPRESS)
    parser.add_argument("--profiled", action="store_true", help=argparse.SUPPRESS)


def compared_trees(args: argparse.Namespace) -> list[Path]:
    """This checkout, then each ``--against`` one (refused unless it holds bfsitl)."""
    trees = [HERE.parent, *[path.resolve() for path in args.against]]
    for tree in trees[1:]:
        if not (tree / "src" / "bfsitl").is_dir():
            sys.exit(f"--against {tree}: no src/bfsitl there (a checkout of bfsitl?)")
    return trees


def worker(binary: str, hold_s: float, seed: int, profiled: bool) -> dict[str, float]:
    """One flight in this process (the tree on ``sys.path``); its figures."""
    import cProfile
    import time

    from lockstep import sitl_cpu_s

    from bfsitl.backend.options import Timing, World
    from bfsitl.control import make_controller
    from bfsitl.mission import FlightSession, MissionPlan, SessionConfig, SitlLaunch, fly
    from bfsitl.sitl.core_claim import claim_core

    inside_s = time_compiled_loop()
    claim = claim_core()  # the SITL started below shares this core: nobody spins
    try:
        config = SessionConfig(
            sitl=SitlLaunch(firmware=binary),
            world=World(seed=seed),
            timing=Timing(lockstep=True, lockstep_exchange="shm", lockstep_spin=False),
        )
        with FlightSession(config) as session:
            pid = session.sitl.pid if session.sitl else None
            profile = cProfile.Profile() if profiled else None
            fc_before, sim_before = sitl_cpu_s(pid), session.time_s
            cpu_before, wall_before = time.thread_time(), time.perf_counter()
            if profile is not None:
                profile.enable()
            result = fly(session, MissionPlan(hold_s=hold_s), make_controller("fused"))
            if profile is not None:
                profile.disable()
            cpu_s = time.thread_time() - cpu_before - inside_s[0]
            wall_s = time.perf_counter() - wall_before
            sim_ms = (session.time_s - sim_before) * 1000.0
            fc_after = sitl_cpu_s(pid)
    finally:
        if claim is not None:
            claim.release()
    steps = len(result.rows)
    figures = {
        "steps": steps,
        "loop_us_per_step": cpu_s / steps * 1e6,
        "loop_us_per_ms": cpu_s / sim_ms * 1e6,
        "fc_us_per_ms": (fc_after - fc_before) / sim_ms * 1e6
        if fc_before is not None and fc_after is not None
        else float("nan"),
        "mission_x": sim_ms / 1000.0 / wall_s,
    }
    if profile is not None:
        import pstats

        figures["calls_per_step"] = pstats.Stats(profile).total_calls / steps  # type: ignore[attr-defined]
    return figures


def fly_in(tree: Path, binary: str, args: argparse.Namespace, profiled: bool) -> dict[str, float]:
    """One flight in a fresh process that imports bfsitl from ``tree``."""
    arguments = [binary, "--hold", str(args.hold), "--seed", str(args.seed)]
    return run_fresh(Path(__file__).resolve(), tree, [*arguments, *(["--profiled"] * profiled)])


def _commit(tree: Path) -> str:
    """The tree's commit, for the table (its directory if git cannot say)."""
    done = subprocess.run(
        ["git", "-C", str(tree), "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        check=False,
    )
    return done.stdout.strip() or tree.name


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=10, help="flights per tree and build")
    parser.add_argument("--hold", type=float, default=10.0, help="hold seconds (default 10)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--generations", default="4.6.0,master")
    parser.add_argument("--build", action="store_true", help="build missing firmware")
    add_comparison_options(parser)
    args = parser.parse_args()
    if args.worker:
        print(json.dumps(worker(args.worker, args.hold, args.seed, args.profiled)))
        return

    trees = compared_trees(args)
    rows: list[tuple[str, str, list[dict[str, float]], dict[str, float]]] = []
    for generation in args.generations.split(","):
        binary = firmware_path(f"{generation}-lockstep", args.build)
        flights: dict[Path, list[dict[str, float]]] = {tree: [] for tree in trees}
        for index in range(args.flights):
            for tree in trees:  # alternated, so that a slow minute falls on both
                flights[tree].append(fly_in(tree, binary, args, profiled=False))
            print(f"{generation}: {index + 1}/{args.flights} flights per tree", file=sys.stderr)
        for tree in trees:
            counted = fly_in(tree, binary, args, profiled=True)
            label = _commit(tree) + (" (this tree)" if tree == trees[0] else "")
            rows.append((generation, label, flights[tree], counted))

    print(
        "| firmware | tree | loop us per step: min | median | loop us per sim ms: min | "
        "FC us per sim ms: median | loop / FC | calls per step | mission sim/wall: median |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for generation, label, flown, counted in rows:
        per_step = [f["loop_us_per_step"] for f in flown]
        per_ms = [f["loop_us_per_ms"] for f in flown]
        fc = statistics.median(f["fc_us_per_ms"] for f in flown)
        print(
            f"| {generation} | {label} | {min(per_step):.0f} | {statistics.median(per_step):.0f} "
            f"| {min(per_ms):.1f} | {fc:.1f} | {min(per_ms) / fc:.2f} | "
            f"{counted['calls_per_step']:.0f} | "
            f"{statistics.median(f['mission_x'] for f in flown):.1f}x |"
        )


if __name__ == "__main__":
    main()
