"""Planning a suite: which firmware each scenario runs on, and what happens to a build the
files name that the user has not made."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from bfsitl.library import scenarios_dir
from bfsitl.scenario.load import find_scenarios
from bfsitl.scenario.suite import plan_runs, split_by_build


def test_builds_the_files_name_that_are_not_there_are_set_aside_not_run(tmp_path: Path) -> None:
    scenarios = find_scenarios([scenarios_dir()])
    runs = plan_runs(scenarios, [], tmp_path)
    named = {run.firmware for run in runs}
    assert {"master-lockstep", "4.6.0-gps-lockstep"} <= named

    asked: list[str] = []

    def only_46(name: str) -> bool:
        asked.append(name)
        return name.startswith("4.6")

    kept, missing = split_by_build(runs, only_46)
    assert missing == ["master-lockstep"]
    assert kept and all(run.firmware == "4.6.0-gps-lockstep" for run in kept)
    assert len(kept) == sum(1 for run in runs if run.firmware == "4.6.0-gps-lockstep")
    assert sorted(asked) == sorted(named)  # each build looked up once, not once per run


def test_with_every_build_there_nothing_is_set_aside(tmp_path: Path) -> None:
    runs = plan_runs(find_scenarios([scenarios_dir()]), [], tmp_path)
    kept, missing = split_by_build(runs, lambda _name: True)
    assert kept == runs and missing == []


def _bfsitl(*args: str, cache: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cache)}
    env.pop("BFSITL_FIRMWARE", None)
    return subprocess.run(
        [sys.executable, "-m", "bfsitl.cli.main", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        cwd=cache,
    )


def test_scenario_list_with_no_path_lists_the_shipped_library(tmp_path: Path) -> None:
    listed = _bfsitl("scenario", "list", cache=tmp_path)
    assert listed.returncode == 0, listed.stderr
    heads = [line.split()[0] for line in listed.stdout.splitlines() if not line.startswith(" ")]
    assert heads == [path.stem for path in sorted(scenarios_dir().glob("*.toml"))]
    assert len(heads) >= 12


def test_scenario_run_with_no_build_made_says_how_to_make_one(tmp_path: Path) -> None:
    ran = _bfsitl("scenario", "run", cache=tmp_path)  # an empty cache: nothing is built
    assert ran.returncode == 1  # EXIT_ERROR: stopped before any run
    assert "Traceback" not in ran.stderr
    assert "not running on master-lockstep: not built (`bfsitl firmware build --git" in ran.stderr
    last = ran.stderr.strip().splitlines()[-1]
    assert last.startswith("bfsitl: error: none of the builds") and "--gps --lockstep" in last


def test_without_jobs_given_a_suite_runs_one_per_core_and_never_more_than_its_runs(monkeypatch):
    from bfsitl.scenario.suite import default_jobs

    monkeypatch.setattr("os.sched_getaffinity", lambda _pid: {0, 1, 2, 3})
    assert [default_jobs(runs) for runs in (0, 1, 2, 4, 76)] == [1, 1, 2, 4, 4]
    monkeypatch.setattr("os.sched_getaffinity", lambda _pid: {3})
    assert default_jobs(76) == 1  # one core: in this process, every event shown


def test_side_by_side_the_longest_flights_go_first_and_results_keep_plan_order(
    tmp_path: Path, monkeypatch
) -> None:
    """A long flight taken last would fly alone while the other cores wait."""
    from concurrent.futures import Future

    from bfsitl.scenario import suite
    from bfsitl.scenario.result import ScenarioResult, Verdict

    runs = plan_runs(find_scenarios([scenarios_dir()]), [], tmp_path)[::5]
    durations = [run.scenario.duration_s for run in runs]
    # The test means something only where plan order is not already longest first.
    assert durations != sorted(durations, reverse=True)
    submitted: list[str] = []

    class OneAtATimePool:
        def __init__(self, **_kwargs: object) -> None:
            pass

        def submit(self, _function, run, *_args) -> Future[ScenarioResult]:
            submitted.append(run.test_id)
            future: Future[ScenarioResult] = Future()
            future.set_result(ScenarioResult(run.scenario.name, run.firmware, Verdict.PASSED, ""))
            return future

        def shutdown(self, **_kwargs: object) -> None:
            pass

    monkeypatch.setattr(suite, "ProcessPoolExecutor", OneAtATimePool)
    result = suite.run_suite(runs, jobs=2)
    by_id = {run.test_id: run.scenario.duration_s for run in runs}
    assert [by_id[test_id] for test_id in submitted] == sorted(durations, reverse=True)
    assert [(r.name, r.firmware) for r in result.results] == [
        (run.scenario.name, run.firmware) for run in runs
    ]
