"""How fast the scenario library runs: simulated time against wall time, one run at a time,
two side by side, and through a local Ray cluster.

Every configuration flies the same runs (the shipped library on the given builds, lockstep
where the build is one) and reports its total simulated seconds, its wall seconds and their
ratio.  The baseline is what the firmware's own harness does (``src/test/sitl/sitl_harness.py``
in the firmware tree): each scenario in real time, one after another, so its wall time equals
the simulated time (1.0x), before any boot or set-up is counted.  The speed-up column is
against that.  What limits it: with lockstep, each run keeps one core busy (the firmware's
passes and the Python physics and MSP in turn); two cores run two at a time.

Run: ``python benchmarks/scenarios.py [--firmware master-lockstep --firmware
4.6.0-gps-lockstep] [--no-ray] [PATHS...]`` (default: the library in ``scenarios/``).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bfsitl.library import scenarios_dir
from bfsitl.scenario.load import find_scenarios
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.suite import plan_runs, run_suite
from bfsitl.sitl.core_claim import PIN_ENV

DEFAULT_BUILDS = ["master-lockstep", "4.6.0-gps-lockstep"]


def measure(label: str, runs_dir: Path, paths: list[str], firmwares: list[str], *,
            jobs: int = 1, ray_address: str | None = None) -> dict[str, object]:
    runs = plan_runs(find_scenarios(paths), firmwares, runs_dir)
    started = time.monotonic()
    results = run_suite(runs, jobs=jobs, plot=False, ray_address=ray_address).results
    wall_s = time.monotonic() - started
    simulated_s = sum(r.sim_time_s for r in results)
    verdicts = {v.value: sum(1 for r in results if r.verdict is v) for v in Verdict}
    return {"label": label, "runs": len(results), "simulated_s": simulated_s,
            "wall_s": wall_s, "verdicts": verdicts}


def start_ray(num_cpus: int) -> str:
    """A local Ray head with ``num_cpus`` CPUs and a small object store; its address."""
    out = subprocess.run(
        [sys.executable, "-m", "ray.scripts.scripts", "start", "--head", "--port=0",
         f"--num-cpus={num_cpus}", "--include-dashboard=false", "--disable-usage-stats",
         "--object-store-memory=100000000"],
        capture_output=True, text=True, check=True)
    for line in (out.stdout + out.stderr).splitlines():
        if "--address=" in line:
            return line.split("--address=")[1].strip().strip("'\"")
    raise RuntimeError(f"no address in `ray start` output:\n{out.stdout}{out.stderr}")


def stop_ray() -> None:
    subprocess.run([sys.executable, "-m", "ray.scripts.scripts", "stop", "--force"],
                   capture_output=True, text=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*", default=[str(scenarios_dir())])
    parser.add_argument("--firmware", action="append", default=[])
    parser.add_argument("--no-ray", action="store_true")
    args = parser.parse_args()
    firmwares = args.firmware or DEFAULT_BUILDS
    rows = []
    with tempfile.TemporaryDirectory(prefix="bfsitl-bench-scenarios-") as tmp:
        root = Path(tmp)
        rows.append(measure("--jobs 1", root / "j1", args.paths, firmwares))
        rows.append(measure("--jobs 2", root / "j2", args.paths, firmwares, jobs=2))
        # The same without core claims (each run sleeping for its packets, as before them).
        os.environ[PIN_ENV] = "0"
        try:
            rows.append(measure("--jobs 2, runs not pinned", root / "j2u", args.paths,
                                firmwares, jobs=2))
        finally:
            del os.environ[PIN_ENV]
        if not args.no_ray:
            address = start_ray(2)
            try:
                rows.append(measure("--ray (local, 2 CPUs)", root / "ray", args.paths,
                                    firmwares, ray_address=address))
            finally:
                stop_ray()
    print(f"\nScenario library on {', '.join(firmwares)}; baseline: the firmware's harness "
          f"approach, real time (1.0x)\n")
    print("| configuration | runs | simulated s | wall s | x real time (speed-up) | "
          "passed / failed / error / skipped |")
    print("| --- | --- | --- | --- | --- | --- |")
    for row in rows:
        v = row["verdicts"]
        assert isinstance(v, dict)
        ratio = float(row["simulated_s"]) / float(row["wall_s"])  # type: ignore[arg-type]
        print(f"| {row['label']} | {row['runs']} | {row['simulated_s']:.0f} | "
              f"{row['wall_s']:.0f} | {ratio:.1f}x | {v['passed']} / {v['failed']} / "
              f"{v['error']} / {v['skipped']} |")


if __name__ == "__main__":
    main()
