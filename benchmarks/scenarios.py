"""How fast the scenario library runs: simulated time against wall time, one run at a time,
two side by side, and through a local Ray cluster.

Every configuration flies the same runs (the shipped library on the given builds, lockstep
where the build is one); the first starts with no FC configuration prepared (each run that
meets a new build and configuration prepares it, bfsitl.scenario.prepared_fc), the others
find them.  Each reports its total simulated seconds, its wall seconds and their
ratio.  The baseline is what the firmware's own harness does (``src/test/sitl/sitl_harness.py``
in the firmware tree): each scenario in real time, one after another, so its wall time equals
the simulated time (1.0x), before any boot or set-up is counted.  The speed-up column is
against that.  What limits it: with lockstep, each run keeps one core busy (the firmware's
passes and the Python physics and MSP in turn); two cores run two at a time.

With Ray, also a few runs one at a time through the cluster: what Ray adds to each (from the
driver's submit to the run's files home, against the run's own time: scheduling, the build's
fetch on a node's first run, packing and unpacking the files), so that a suite's time on N
machines can be planned on paper.

Then where a run's wall time goes (preparing the FC's configuration, start-up, arming,
flight, stop, blackbox, analysers, plots, files), summed over the one-at-a-time runs (with and
without the configurations prepared), and the five slowest.

Run: ``python benchmarks/scenarios.py [--firmware master-lockstep --firmware
4.6.0-gps-lockstep] [--no-ray | --only-ray] [PATHS...]`` (default: the library in
``scenarios/``).
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bfsitl.cache_location import cache_root
from bfsitl.library import scenarios_dir
from bfsitl.scenario.load import find_scenarios
from bfsitl.scenario.prepared_fc import PREPARED_DIR
from bfsitl.scenario.ray_runs import RayTiming, run_on_ray
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.suite import plan_runs, run_suite
from bfsitl.scenario.timings import timings_table
from bfsitl.sitl.core_claim import PIN_ENV

DEFAULT_BUILDS = ["master-lockstep", "4.6.0-gps-lockstep"]
#: The first row's label: every FC configuration prepared by the run that first needs it.
COLD = "--jobs 1, no FC configuration prepared yet"


def measure(
    label: str,
    runs_dir: Path,
    paths: list[str],
    firmwares: list[str],
    *,
    jobs: int = 1,
    ray_address: str | None = None,
) -> dict[str, object]:
    runs = plan_runs(find_scenarios(paths), firmwares, runs_dir)
    started = time.monotonic()
    results = run_suite(runs, jobs=jobs, plot=False, ray_address=ray_address).results
    wall_s = time.monotonic() - started
    simulated_s = sum(r.sim_time_s for r in results)
    verdicts = {v.value: sum(1 for r in results if r.verdict is v) for v in Verdict}
    return {
        "label": label,
        "runs": len(results),
        "simulated_s": simulated_s,
        "wall_s": wall_s,
        "verdicts": verdicts,
        "phases": [(r.test_id, r.timings_s, r.sim_time_s) for r in results if r.timings_s],
    }


def ray_overhead(
    runs_dir: Path, paths: list[str], firmwares: list[str], address: str, count: int
) -> list[RayTiming]:
    """``count`` runs through Ray one at a time (no queueing): what Ray adds to each run, from
    the driver's submit to its files home, against the run's own time."""
    runs = plan_runs(find_scenarios(paths), firmwares, runs_dir)[:count]
    timings: list[RayTiming] = []
    for run in runs:
        run_on_ray(
            [run],
            address,
            speed=None,
            plot=True,
            mcap=False,
            results={},
            done=lambda _result: None,
            say=lambda _line: None,
            timings=timings,
        )
    return timings


def start_ray(num_cpus: int) -> str:
    """A local Ray head with ``num_cpus`` CPUs and a small object store; its address."""
    out = subprocess.run(
        [
            sys.executable,
            "-m",
            "ray.scripts.scripts",
            "start",
            "--head",
            "--port=0",
            f"--num-cpus={num_cpus}",
            "--include-dashboard=false",
            "--disable-usage-stats",
            "--object-store-memory=100000000",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    for line in (out.stdout + out.stderr).splitlines():
        if "--address=" in line:
            return line.split("--address=")[1].strip().strip("'\"")
    raise RuntimeError(f"no address in `ray start` output:\n{out.stdout}{out.stderr}")


def stop_ray() -> None:
    subprocess.run(
        [sys.executable, "-m", "ray.scripts.scripts", "stop", "--force"],
        capture_output=True,
        text=True,
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", default=[str(scenarios_dir())])
    parser.add_argument("--firmware", action="append", default=[])
    parser.add_argument("--no-ray", action="store_true")
    parser.add_argument(
        "--only-ray",
        action="store_true",
        help="only the Ray rows (the cluster and its cost per run)",
    )
    args = parser.parse_args()
    firmwares = args.firmware or DEFAULT_BUILDS
    rows = []
    with tempfile.TemporaryDirectory(prefix="bfsitl-bench-scenarios-") as tmp:
        root = Path(tmp)
        if not args.only_ray:
            # First with none of the FCs' configurations prepared (as on a new machine, or
            # after a rebuild): each configuration is prepared by the first run that needs it.
            shutil.rmtree(cache_root() / PREPARED_DIR, ignore_errors=True)
            rows.append(measure(COLD, root / "j1c", args.paths, firmwares))
            rows.append(measure("--jobs 1", root / "j1", args.paths, firmwares))
            rows.append(measure("--jobs 2", root / "j2", args.paths, firmwares, jobs=2))
            # The same without core claims (each run sleeping for its packets, as before).
            os.environ[PIN_ENV] = "0"
            try:
                rows.append(
                    measure(
                        "--jobs 2, runs not pinned", root / "j2u", args.paths, firmwares, jobs=2
                    )
                )
            finally:
                del os.environ[PIN_ENV]
        timings: list[RayTiming] = []
        if not args.no_ray:
            address = start_ray(2)
            try:
                rows.append(
                    measure(
                        "--ray (local, 2 CPUs)",
                        root / "ray",
                        args.paths,
                        firmwares,
                        ray_address=address,
                    )
                )
                timings = ray_overhead(root / "ray1", args.paths, firmwares, address, 6)
            finally:
                stop_ray()
    print(
        f"\nScenario library on {', '.join(firmwares)}; baseline: the firmware's harness "
        f"approach, real time (1.0x)\n"
    )
    print(
        "| configuration | runs | simulated s | wall s | x real time (speed-up) | "
        "passed / failed / error / skipped |"
    )
    print("| --- | --- | --- | --- | --- | --- |")
    for row in rows:
        v = row["verdicts"]
        assert isinstance(v, dict)
        ratio = float(row["simulated_s"]) / float(row["wall_s"])  # type: ignore[arg-type]
        print(
            f"| {row['label']} | {row['runs']} | {row['simulated_s']:.0f} | "
            f"{row['wall_s']:.0f} | {ratio:.1f}x | {v['passed']} / {v['failed']} / "
            f"{v['error']} / {v['skipped']} |"
        )
    for row in rows:
        if row["label"] in ("--jobs 1", COLD) and row["phases"]:
            print_phases(str(row["label"]), row["phases"])  # type: ignore[arg-type]
    if timings:
        print_overhead(timings)


def print_phases(label: str, phases: list[tuple[str, dict[str, float], float]]) -> None:
    """Where the runs' wall time went, one at a time (``bfsitl scenario run --timings``'s
    table): the sum and each phase's share, then the five slowest runs."""
    print(f"\nWhere a run's wall time goes, {label} (seconds, summed over the runs):\n")
    table = timings_table(phases)
    print("\n".join(table[:1] + table[-2:]))
    slowest = sorted(phases, key=lambda run: -sum(run[1].values()))[:5]
    print("\nThe five slowest runs:\n")
    print("\n".join(timings_table(slowest)[: 1 + len(slowest)]))


def print_overhead(timings: list[RayTiming]) -> None:
    """What Ray adds per run, and the plan it gives for N machines."""
    print(
        "\nRay's cost per run, one run at a time (no queueing), the first run fetching the "
        "build to its node:\n"
    )
    print("| run | run s | task on its node s | submit to files home s | Ray adds s | archive MB |")
    print("| --- | --- | --- | --- | --- | --- |")
    for t in timings:
        print(
            f"| {t.test_id} | {t.run_s:.2f} | {t.task_s:.2f} | {t.latency_s:.2f} | "
            f"{t.latency_s - t.run_s:.2f} | {t.archive_bytes / 1e6:.2f} |"
        )
    added = statistics.median(t.latency_s - t.run_s for t in timings)
    run_s = statistics.mean(t.run_s for t in timings)
    print(
        f"\nmedian added per run {added:.2f} s against a mean run of {run_s:.2f} s: a "
        f"suite of R runs on N machines of C cores takes about R x ({run_s:.1f} + "
        f"{added:.1f}) / (N x C) s, and each node fetches each build once."
    )


if __name__ == "__main__":
    main()
