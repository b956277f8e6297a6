"""Many scenario runs: each scenario on each firmware, one after another or side by side.

Runs are independent: each has its own directory (``OUT/<firmware>/<scenario>/``), its own
SITL in its own network namespace, and its own process when ``jobs > 1`` (a process each, not
a thread: a lockstep run keeps a core busy in Python, and the GIL would serialise threads).
Results come back as :class:`~bfsitl.scenario.result.ScenarioResult` in the order the runs
were planned, whatever order they finished in; side by side, the workers take the longest
flights first (:func:`longest_first`).

``ray_address`` hands the same runs to a Ray cluster instead (``bfsitl scenario run --ray
ADDRESS``): one task per run, one CPU each, results gathered the same way; the firmware
travels to the nodes and the files come home (:mod:`bfsitl.scenario.ray_runs`).

Ctrl-C, SIGTERM and SIGHUP stop everything alike (bfsitl.stop_signals): the workers are told
to stop, their sessions close (disarm, stop the SITL), a worker that has not ended within
:data:`WORKER_STOP_S` is killed, and the runs that finished are still returned
(:class:`SuiteResult` says it was interrupted), so the JUnit file and the report keep them.
A worker dies with the suite's process, even when that is killed outright (SIGKILL): the
kernel signals it (:func:`~bfsitl.stop_signals.die_with_parent`), so no worker, and so no
multiprocessing resource tracker or semaphore, outlives the suite.
"""

from __future__ import annotations

import multiprocessing
import multiprocessing.connection
import os
import re
import signal
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import ScenarioError
from bfsitl.scenario.planned_run import PlannedRun, fly_one
from bfsitl.scenario.result import PlotWhen, ScenarioResult, Verdict
from bfsitl.scenario.run import RunOptions, run_scenario
from bfsitl.scenario.spec import Scenario
from bfsitl.stop_signals import WorkerStop, die_with_parent, how_stopped, stop_signals_ignored

#: How long stopped workers get to close their sessions (disarm, stop the SITL, write their
#: files) before they are killed; a session's teardown takes a second or two.
WORKER_STOP_S = 20.0

Progress = Callable[[str], None]
#: Called with each finished run, in the order they finish.
OnResult = Callable[[ScenarioResult], None]


@dataclass(frozen=True, slots=True)
class SuiteResult:
    """Every run's result in plan order; ``stopped_by`` names the stop signal that ended the
    suite (``Ctrl-C``, ``SIGTERM``, ``SIGHUP``), empty when it ran to its end, and then
    ``finished`` runs had a result of their own and the others are marked not run."""

    results: list[ScenarioResult]
    stopped_by: str = ""
    finished: int = 0

    @property
    def interrupted(self) -> bool:
        return bool(self.stopped_by)

    def stop_line(self) -> str:
        """What a user is told when the suite was stopped (empty when it was not)."""
        if not self.interrupted:
            return ""
        return (
            f"interrupted ({self.stopped_by}): {self.finished} of {len(self.results)} "
            f"runs finished; the others are marked not run"
        )


def dir_name(text: str) -> str:
    """A firmware name or path as one safe directory name."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", Path(text).name if "/" in text else text)
    return name.strip("._") or "firmware"


def plan_runs(
    scenarios: Sequence[Scenario], firmwares: Sequence[str], out_dir: Path
) -> list[PlannedRun]:
    """Each scenario on each of ``firmwares`` (or, when none is given, on the builds its
    file names)."""
    runs = []
    for scenario in scenarios:
        targets = list(firmwares) or list(scenario.firmware)
        if not targets:
            raise ScenarioError(
                f"{scenario.where} names no firmware: give --firmware NAME "
                f"(`bfsitl firmware list` shows the builds) or a firmware "
                f"list in the file"
            )
        for firmware in dict.fromkeys(targets):
            runs.append(
                PlannedRun(
                    scenario, firmware, out_dir / dir_name(firmware) / dir_name(scenario.name)
                )
            )
    return runs


def split_by_build(
    runs: Sequence[PlannedRun], is_built: Callable[[str], bool]
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


#: In a worker process: how it takes stop signals (set up by :func:`_start_worker`).
_worker_stop = WorkerStop()


def default_jobs(runs: int) -> int:
    """``--jobs`` when none is given: a run per core this process may use (a lockstep run
    keeps one core busy, its firmware and bfsitl taking turns), never more than the runs
    (docs/scenarios.md#scale measures both)."""
    return max(1, min(len(os.sched_getaffinity(0)), runs))


def longest_first(runs: Sequence[PlannedRun]) -> list[int]:
    """The order the workers take the runs in: the longest flights first (each scenario's
    ``duration_s``; plan order among equals).  In plan order a long flight that came last
    could fly alone on one core while the others stood idle."""
    return sorted(range(len(runs)), key=lambda index: -runs[index].scenario.duration_s)


def _start_worker(parent_pid: int) -> None:
    """A worker's set-up: it ends with the suite's process, and stops cleanly once."""
    die_with_parent(parent_pid, signal.SIGTERM)
    _worker_stop.install()


def _run_one(run: PlannedRun, speed: float | None, plot: PlotWhen, mcap: bool) -> ScenarioResult:
    with _worker_stop.job():
        return fly_one(run.scenario, run.firmware, run.out_dir, speed, plot, mcap)


def run_suite(
    runs: Sequence[PlannedRun],
    *,
    jobs: int = 1,
    speed: float | None = None,
    plot: PlotWhen = True,
    progress: Progress | None = None,
    on_result: OnResult | None = None,
    ray_address: str | None = None,
    mcap: bool = False,
    ray_retries: int = 2,
    ray_max_mb: float = 256.0,
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

            run_on_ray(
                runs,
                ray_address,
                speed=speed,
                plot=plot,
                mcap=mcap,
                results=results,
                done=done,
                say=say,
                max_artifact_mb=ray_max_mb,
                retries=ray_retries,
            )
        elif jobs == 1:
            for index, run in enumerate(runs):
                say(f"{run.test_id}: starting")
                run.out_dir.mkdir(parents=True, exist_ok=True)
                result = run_scenario(
                    run.scenario,
                    run.firmware,
                    RunOptions(run.out_dir, speed=speed, plot=plot, mcap=mcap),
                    progress=_prefixed(say, run.test_id),
                )
                results[index] = result
                done(result)
        else:
            _run_parallel(runs, jobs, speed, plot, mcap, results, done, say)
    except KeyboardInterrupt as exc:
        how, finished = how_stopped(exc), len(results)
        results.update(
            {i: _interrupted(run, how) for i, run in enumerate(runs) if i not in results}
        )
        return SuiteResult([results[i] for i in sorted(results)], stopped_by=how, finished=finished)
    return SuiteResult([results[i] for i in sorted(results)], finished=len(results))


def _prefixed(say: Progress, prefix: str) -> Progress:
    return lambda line: say(f"{prefix}: {line}")


def _run_parallel(
    runs: Sequence[PlannedRun],
    jobs: int,
    speed: float | None,
    plot: PlotWhen,
    mcap: bool,
    results: dict[int, ScenarioResult],
    done: OnResult,
    say: Progress,
) -> None:
    # spawn: a fresh interpreter per worker, nothing inherited from this one's threads.
    context = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(
        max_workers=jobs, mp_context=context, initializer=_start_worker, initargs=(os.getpid(),)
    )
    futures: dict[Future[ScenarioResult], int] = {}
    try:
        for index in longest_first(runs):
            futures[pool.submit(_run_one, runs[index], speed, plot, mcap)] = index
        say(f"{len(runs)} runs, {jobs} at a time")
        pending = set(futures)
        while pending:
            finished, pending = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                _take(future, futures[future], runs, results, done)
    except BaseException:
        _stop_workers(pool)
        # A run that ended while the workers stopped is kept, not reported as not run.
        for future, index in futures.items():
            if (
                index not in results
                and future.done()
                and not future.cancelled()
                and future.exception() is None
            ):
                _take(future, index, runs, results, done)
        raise
    pool.shutdown(wait=True)


def _take(
    future: Future[ScenarioResult],
    index: int,
    runs: Sequence[PlannedRun],
    results: dict[int, ScenarioResult],
    done: OnResult,
) -> None:
    try:
        result = future.result()
    except Exception as exc:  # noqa: BLE001 - a worker died: the run errs
        run = runs[index]
        result = ScenarioResult(
            run.scenario.name,
            run.firmware,
            Verdict.ERROR,
            f"the worker process failed: {exc!r}",
            source=run.scenario.source,
            vehicle=run.scenario.quad.name,
        )
    results[index] = result
    done(result)


def _stop_workers(pool: ProcessPoolExecutor) -> None:
    """Stop the pool's workers, whatever they are doing: each gets SIGINT (its run's session
    closes; a worker that already had one from the terminal ignores it), queued runs are
    cancelled, and a worker still there after :data:`WORKER_STOP_S` is killed.  Stop signals
    to this process are ignored meanwhile: the stop is bounded and must finish."""
    with stop_signals_ignored():
        workers = multiprocessing.active_children()
        pool.shutdown(wait=False, cancel_futures=True)
        for worker in workers:
            if worker.pid is not None:
                try:
                    os.kill(worker.pid, signal.SIGINT)
                except ProcessLookupError:
                    pass
        # Wait on the sentinels, not join(): the pool's own thread reaps these processes.
        deadline = time.monotonic() + WORKER_STOP_S
        waiting = {worker.sentinel: worker for worker in workers}
        while waiting and time.monotonic() < deadline:
            ended = set(
                multiprocessing.connection.wait(list(waiting), timeout=deadline - time.monotonic())
            )
            waiting = {
                sentinel: worker for sentinel, worker in waiting.items() if sentinel not in ended
            }
        for worker in waiting.values():
            worker.kill()


def _interrupted(run: PlannedRun, how: str = "Ctrl-C") -> ScenarioResult:
    return ScenarioResult(
        run.scenario.name,
        run.firmware,
        Verdict.SKIPPED,
        f"not run: interrupted ({how})",
        source=run.scenario.source,
        vehicle=run.scenario.quad.name,
    )
