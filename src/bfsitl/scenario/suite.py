"""Many scenario runs: each scenario on each firmware, one after another or side by side.

Runs are independent: each has its own directory (``OUT/<firmware>/<scenario>/``), its own
SITL in its own network namespace, and its own process when ``jobs > 1`` (a process each, not
a thread: a lockstep run keeps a core busy in Python, and the GIL would serialise threads).
Results come back as :class:`~bfsitl.scenario.result.ScenarioResult` in the order the runs
were planned, whatever order they finished in.

``ray_address`` hands the same runs to a Ray cluster instead (``bfsitl scenario run --ray
ADDRESS``): one task per run, one CPU each, results gathered the same way; the firmware
travels to the nodes and the files come home (:mod:`bfsitl.scenario.ray_runs`).

Ctrl-C stops everything: the workers' sessions close (disarm, stop the SITL), and the runs
that finished are still returned (:class:`SuiteResult` says it was interrupted), so the JUnit
file and the report keep them.
"""

from __future__ import annotations

import multiprocessing
import re
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import ScenarioError
from bfsitl.scenario.planned_run import PlannedRun, fly_one
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.run import RunOptions, run_scenario
from bfsitl.scenario.spec import Scenario

Progress = Callable[[str], None]
#: Called with each finished run, in the order they finish.
OnResult = Callable[[ScenarioResult], None]


@dataclass(frozen=True, slots=True)
class SuiteResult:
    """Every run's result in plan order; ``interrupted`` when Ctrl-C ended the suite."""

    results: list[ScenarioResult]
    interrupted: bool = False


def dir_name(text: str) -> str:
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
                                   out_dir / dir_name(firmware) / dir_name(scenario.name)))
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


def _run_one(run: PlannedRun, speed: float | None, plot: bool, mcap: bool
             ) -> ScenarioResult:
    return fly_one(run.scenario, run.firmware, run.out_dir, speed, plot, mcap)


def run_suite(runs: Sequence[PlannedRun], *, jobs: int = 1, speed: float | None = None,
              plot: bool = True, progress: Progress | None = None,
              on_result: OnResult | None = None, ray_address: str | None = None,
              mcap: bool = False, ray_retries: int = 2, ray_max_mb: float = 256.0
              ) -> SuiteResult:
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
            from bfsitl.scenario.ray_runs import run_on_ray

            run_on_ray(runs, ray_address, speed=speed, plot=plot, mcap=mcap, results=results,
                       done=done, say=say, max_artifact_mb=ray_max_mb, retries=ray_retries)
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


def _interrupted(run: PlannedRun) -> ScenarioResult:
    return ScenarioResult(run.scenario.name, run.firmware, Verdict.SKIPPED,
                          "not run: interrupted (Ctrl-C)", source=run.scenario.source)
