"""Many scenario runs: each scenario on each firmware, one after another or side by side.

Runs are independent: each has its own directory (``OUT/<firmware>/<scenario>/``), its own
SITL in its own network namespace, and its own process when ``jobs > 1`` (a process each, not
a thread: a lockstep run keeps a core busy in Python, and the GIL would serialise threads).
Results come back as :class:`~bfsitl.scenario.result.ScenarioResult` in the order the runs
were planned, whatever order they finished in.

``ray_address`` hands the same runs to a Ray cluster instead (``bfsitl scenario run --ray
ADDRESS``): one task per run, one CPU each, results gathered the same way.

Ctrl-C stops everything: the workers' sessions close (disarm, stop the SITL), and the runs
that finished are still returned (:class:`SuiteResult` says it was interrupted), so the JUnit
file and the report keep them.
"""

from __future__ import annotations

import multiprocessing
import os
import re
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from bfsitl.build.cache import CACHE_ENV_VAR
from bfsitl.errors import BfsitlError, ScenarioError
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.run import RunOptions, run_scenario
from bfsitl.scenario.spec import Scenario
from bfsitl.sitl.core_claim import claim_core
from bfsitl.sitl.firmware import ENV_VAR as FIRMWARE_ENV_VAR
from bfsitl.sitl.firmware import find_firmware

Progress = Callable[[str], None]
#: Called with each finished run, in the order they finish.
OnResult = Callable[[ScenarioResult], None]


@dataclass(frozen=True, slots=True)
class SuiteResult:
    """Every run's result in plan order; ``interrupted`` when Ctrl-C ended the suite."""

    results: list[ScenarioResult]
    interrupted: bool = False


@dataclass(frozen=True, slots=True)
class PlannedRun:
    """One scenario on one firmware, and where its files go."""

    scenario: Scenario
    firmware: str
    out_dir: Path

    @property
    def test_id(self) -> str:
        return f"{self.scenario.name}[{self.firmware}]"


def _dir_name(text: str) -> str:
    """A firmware name or path as one safe directory name."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(text).name if "/" in text else text)
    return name.strip("._") or "firmware"


def plan_runs(scenarios: Sequence[Scenario], firmwares: Sequence[str], out_dir: Path
              ) -> list[PlannedRun]:
    """Each scenario on each of ``firmwares`` (or, when none is given, on the builds its
    file names)."""
    runs = []
    for scenario in scenarios:
        targets = list(firmwares) or list(scenario.firmware)
        if not targets:
            raise ScenarioError(f"{scenario.where} names no firmware: give --firmware NAME "
                                f"(`bfsitl firmware list` shows the builds) or a firmware "
                                f"list in the file")
        for firmware in dict.fromkeys(targets):
            runs.append(PlannedRun(scenario, firmware,
                                   out_dir / _dir_name(firmware) / _dir_name(scenario.name)))
    return runs


def split_by_build(runs: Sequence[PlannedRun], is_built: Callable[[str], bool]
                   ) -> tuple[list[PlannedRun], list[str]]:
    """(the runs whose firmware is built, the names of the builds that are not).

    For the builds the scenario files name themselves: a user who built only 4.6.0 runs the
    library on 4.6.0 and is told what master would add, rather than stopped.  Builds given
    with ``--firmware`` are not passed through here: a missing one is a mistake to report."""
    built: dict[str, bool] = {}
    kept = []
    for run in runs:
        if run.firmware not in built:
            built[run.firmware] = is_built(run.firmware)
        if built[run.firmware]:
            kept.append(run)
    return kept, [name for name, there in built.items() if not there]


def _is_lockstep(firmware: str) -> bool:
    """The build is a lockstep one (False if it cannot be found: the run says why)."""
    try:
        return find_firmware(firmware).lockstep
    except BfsitlError:
        return False


def _run_one(run: PlannedRun, speed: float | None, plot: bool, mcap: bool
             ) -> ScenarioResult:
    """A worker's job: the run's progress goes to a file in its directory (several runs'
    lines interleaved on one terminal would be unreadable).  Workers share the machine's
    cores, so a lockstep run does not busy-wait (SessionConfig.lockstep_spin); it claims a
    core for itself and its SITL instead (bfsitl.sitl.core_claim), so that runs side by side
    neither take each other's time nor wake each other's cores."""
    run.out_dir.mkdir(parents=True, exist_ok=True)
    # Only a lockstep run is one core's work; a stock SITL runs on the wall clock beside us.
    claim = claim_core() if _is_lockstep(run.firmware) else None
    try:
        with open(run.out_dir / "progress.log", "w", buffering=1) as log:
            return run_scenario(run.scenario, run.firmware,
                                RunOptions(run.out_dir, speed=speed, plot=plot, mcap=mcap,
                                           shares_cores=True),
                                progress=lambda line: print(line, file=log))
    finally:
        if claim is not None:
            claim.release()


def run_suite(runs: Sequence[PlannedRun], *, jobs: int = 1, speed: float | None = None,
              plot: bool = True, progress: Progress | None = None,
              on_result: OnResult | None = None, ray_address: str | None = None,
              mcap: bool = False) -> SuiteResult:
    """Every planned run, ``jobs`` at a time; results in plan order.  With ``jobs = 1`` the
    runs happen in this process and their events go to ``progress`` as they happen; with a
    ``ray_address`` they are Ray tasks on that cluster (one CPU each).  Ctrl-C ends it with
    the runs so far (the rest marked not run) and ``interrupted`` set."""
    if jobs < 1:
        raise ScenarioError(f"--jobs {jobs}: at least 1")
    say = progress or (lambda _line: None)
    done = on_result or (lambda _result: None)
    results: dict[int, ScenarioResult] = {}
    try:
        if ray_address is not None:
            _run_on_ray(runs, ray_address, speed, plot, mcap, results, done, say)
        elif jobs == 1:
            for index, run in enumerate(runs):
                say(f"{run.test_id}: starting")
                run.out_dir.mkdir(parents=True, exist_ok=True)
                result = run_scenario(run.scenario, run.firmware,
                                      RunOptions(run.out_dir, speed=speed, plot=plot,
                                                 mcap=mcap),
                                      progress=_prefixed(say, run.test_id))
                results[index] = result
                done(result)
        else:
            _run_parallel(runs, jobs, speed, plot, mcap, results, done, say)
    except KeyboardInterrupt:
        say(f"interrupted: {len(results)} of {len(runs)} runs finished")
        results.update({i: _interrupted(run) for i, run in enumerate(runs)
                        if i not in results})
        return SuiteResult([results[i] for i in sorted(results)], interrupted=True)
    return SuiteResult([results[i] for i in sorted(results)])


def _prefixed(say: Progress, prefix: str) -> Progress:
    return lambda line: say(f"{prefix}: {line}")


def _run_parallel(runs: Sequence[PlannedRun], jobs: int, speed: float | None, plot: bool,
                  mcap: bool, results: dict[int, ScenarioResult], done: OnResult,
                  say: Progress) -> None:
    # spawn: a fresh interpreter per worker, nothing inherited from this one's threads.
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=jobs, mp_context=context) as pool:
        futures: dict[Future[ScenarioResult], int] = {}
        for index, run in enumerate(runs):
            futures[pool.submit(_run_one, run, speed, plot, mcap)] = index
        say(f"{len(runs)} runs, {jobs} at a time")
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                index = futures[future]
                try:
                    result = future.result()
                except Exception as exc:  # noqa: BLE001 - a worker died: the run errs
                    run = runs[index]
                    result = ScenarioResult(run.scenario.name, run.firmware, Verdict.ERROR,
                                            f"the worker process failed: {exc!r}",
                                            source=run.scenario.source)
                results[index] = result
                done(result)


def _run_on_ray(runs: Sequence[PlannedRun], address: str, speed: float | None, plot: bool,
                mcap: bool, results: dict[int, ScenarioResult], done: OnResult,
                say: Progress) -> None:
    """The same runs as Ray tasks.  Each task flies one run on whichever node Ray picks, in
    that node's namespaces, with the firmware builds where this process finds them (the
    cache path must hold them on every node); its files land under ``out_dir`` on that node
    (one machine, or a shared filesystem, keeps them together)."""
    try:
        import ray
    except ImportError as exc:
        raise ScenarioError("--ray needs Ray: pip install 'bfsitl[ray]'") from exc
    # The tasks find firmware builds as this process does: its cache and firmware settings
    # go with them (a Ray worker has the environment of the node's raylet, not ours).
    env_vars = {name: os.environ[name] for name in (CACHE_ENV_VAR, FIRMWARE_ENV_VAR,
                                                   "XDG_CACHE_HOME") if name in os.environ}
    try:
        ray.init(address=address, log_to_driver=False, ignore_reinit_error=True,
                 runtime_env={"env_vars": env_vars})
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise ScenarioError(f"cannot reach the Ray cluster at {address}: {exc} (start one "
                            f"with `ray start --head`, then pass the address it prints)") \
            from exc
    remote = ray.remote(num_cpus=1, max_retries=0)(_run_one)
    refs = {remote.remote(run, speed, plot, mcap): index for index, run in enumerate(runs)}
    say(f"{len(runs)} runs on the Ray cluster at {address} "
        f"({ray.cluster_resources().get('CPU', 0):g} CPUs)")
    pending = list(refs)
    try:
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            for ref in ready:
                index = refs[ref]
                try:
                    result = ray.get(ref)
                except Exception as exc:  # noqa: BLE001 - a task died: the run errs
                    run = runs[index]
                    result = ScenarioResult(run.scenario.name, run.firmware, Verdict.ERROR,
                                            f"the Ray task failed: {exc!r}"[:500],
                                            source=run.scenario.source)
                results[index] = result
                done(result)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)  # the namespace agent stops each task's SITL
        raise
    finally:
        ray.shutdown()


def _interrupted(run: PlannedRun) -> ScenarioResult:
    return ScenarioResult(run.scenario.name, run.firmware, Verdict.SKIPPED,
                          "not run: interrupted (Ctrl-C)", source=run.scenario.source)
