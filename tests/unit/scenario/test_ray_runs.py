"""Scenario runs on Ray without a cluster: a build travels by its hash and is kept whole, a
run's files come home under its directory (and nothing lands outside it, or past the bound),
and only a lost worker or node is tried again; a run that failed on its merits is not.
The cluster itself: tests/integration/test_scenarios_sitl.py."""

from __future__ import annotations

import hashlib
import io
import random
import tarfile
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from bfsitl.errors import ScenarioError, SitlError
from bfsitl.mission import MissionPlan
from bfsitl.scenario import ray_runs
from bfsitl.scenario.planned_run import PlannedRun
from bfsitl.scenario.ray_runs import RemoteOutcome, bring_home, pack_outputs, unpack_outputs
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.spec import Scenario
from bfsitl.sitl.firmware_parcel import FirmwareParcel, received_path, unpack_firmware

BINARY = b"\x7fELF pretend SITL " * 1000
SCENARIO = Scenario("hover", MissionPlan(), 10.0)


def parcel_of(data: bytes, name: str = "4.6.0-lockstep") -> FirmwareParcel:
    return FirmwareParcel(
        name, hashlib.sha256(data).hexdigest(), "betaflight_4.6.0_SITL", len(data), ref="the object"
    )


def test_a_build_is_fetched_once_kept_by_its_hash_and_runnable(tmp_path: Path) -> None:
    fetched: list[Any] = []

    def fetch(ref: Any) -> bytes:
        fetched.append(ref)
        return BINARY

    parcel = parcel_of(BINARY)
    first = unpack_firmware(parcel, fetch, tmp_path)
    again = unpack_firmware(parcel, fetch, tmp_path)
    assert first == again == received_path(parcel, tmp_path)
    assert first.parent.name == parcel.sha256[:20] and first.name == "betaflight_4.6.0_SITL"
    assert first.read_bytes() == BINARY and first.stat().st_mode & 0o111
    assert fetched == ["the object"]  # the second run on this node reads its own copy
    assert not (first.parent / "build.json").exists()
    # A build with its record: the record lands beside it (it says GPS, lockstep, ...).
    recorded = replace(parcel_of(BINARY + b"gps"), record=b'{"options": {"gps": true}}')
    path = unpack_firmware(recorded, lambda _ref: BINARY + b"gps", tmp_path)
    assert (path.parent / "build.json").read_bytes() == recorded.record
    # Another build of the same name is another file: nothing mixes.
    other = parcel_of(BINARY + b"patched")
    assert unpack_firmware(other, lambda _ref: BINARY + b"patched", tmp_path) != first


def test_a_damaged_build_is_refused_and_not_kept(tmp_path: Path) -> None:
    parcel = parcel_of(BINARY)
    with pytest.raises(SitlError, match="arrived damaged"):
        unpack_firmware(parcel, lambda _ref: BINARY[:-1] + b"!", tmp_path)
    assert not received_path(parcel, tmp_path).exists()


def test_a_runs_files_come_home_under_its_directory(tmp_path: Path) -> None:
    work = tmp_path / "node"
    (work / "sitl").mkdir(parents=True)
    (work / "flight.csv").write_text("time_s\n0.0\n")
    (work / "sitl" / "sitl.log").write_text("booted\n")
    archive = pack_outputs(work, max_bytes=1_000_000)
    home = tmp_path / "driver" / "4.6.0" / "hover"
    result = ScenarioResult(
        "hover",
        "4.6.0",
        Verdict.PASSED,
        "all met",
        artifacts={"log": Path("flight.csv"), "sitl_log": Path("sitl/sitl.log")},
    )
    run = PlannedRun(SCENARIO, "4.6.0", home)
    brought = bring_home(RemoteOutcome(result, archive, "node-1"), run)
    assert (home / "flight.csv").read_text() == "time_s\n0.0\n"
    assert brought.artifacts == {"log": home / "flight.csv", "sitl_log": home / "sitl" / "sitl.log"}
    assert all(path.is_file() for path in brought.artifacts.values())


def test_files_past_the_bound_are_an_error_that_says_what_to_do(tmp_path: Path) -> None:
    (tmp_path / "noise.bin").write_bytes(random.Random(1).randbytes(300_000))  # incompressible
    with pytest.raises(ScenarioError, match=r"more than 0 MB .*--no-plot.*--ray-max-mb"):
        pack_outputs(tmp_path, max_bytes=100_000)


@pytest.mark.parametrize("name", ["../escape.txt", "/etc/passwd-like", "a/../../b"])
def test_an_archive_member_that_would_land_outside_is_refused(tmp_path: Path, name: str) -> None:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as archive:
        info = tarfile.TarInfo(name)
        info.size = 2
        archive.addfile(info, io.BytesIO(b"hi"))
    with pytest.raises(ScenarioError, match="outside its directory"):
        unpack_outputs(buffer.getvalue(), tmp_path / "out")
    assert not (tmp_path / "escape.txt").exists()


class LostNode(Exception):
    """Stands for a Ray system error (a worker or node gone)."""


class TaskRaised(LostNode):
    """Stands for a RayTaskError: the task's own code raised."""


class Cancelled(LostNode):
    pass


FAKE_RAY = SimpleNamespace(
    exceptions=SimpleNamespace(
        RayError=LostNode, RayTaskError=TaskRaised, TaskCancelledError=Cancelled
    )
)


def test_only_a_lost_worker_is_worth_another_try() -> None:
    assert ray_runs.is_lost_worker(FAKE_RAY, LostNode("node died"))
    assert not ray_runs.is_lost_worker(FAKE_RAY, TaskRaised("the run's own bug"))
    assert not ray_runs.is_lost_worker(FAKE_RAY, Cancelled("Ctrl-C"))
    assert not ray_runs.is_lost_worker(FAKE_RAY, ValueError("not Ray's"))


def test_a_lost_run_is_retried_up_to_the_bound_and_says_why(tmp_path: Path) -> None:
    run = PlannedRun(SCENARIO, "4.6.0", tmp_path / "out")
    attempt = ray_runs._Attempt(0, parcel_of(BINARY))
    outcomes: list[Any] = [LostNode("node 2 died"), LostNode("worker crashed")]

    def get(_ref: Any) -> Any:
        outcome = outcomes.pop(0)
        if isinstance(outcome, Exception):
            raise outcome
        return outcome

    ray = SimpleNamespace(exceptions=FAKE_RAY.exceptions, get=get)
    assert ray_runs._collect(ray, "ref", run, attempt, retries=2) is None
    assert ray_runs._collect(ray, "ref", run, attempt, retries=2) is None
    assert attempt.tries == 3 and len(attempt.why) == 2 and "LostNode" in attempt.why[0]
    passed = ScenarioResult("hover", "4.6.0", Verdict.PASSED, "all 2 expectations met")
    outcomes.append(RemoteOutcome(passed, pack_outputs(tmp_path, 10_000_000), "node-3"))
    result = ray_runs._collect(ray, "ref", run, attempt, retries=2)
    assert result is not None and result.verdict is Verdict.PASSED
    assert result.retried == attempt.why  # the JUnit file and the report say it
    # Past the bound the run errs, with every lost attempt named.
    attempt = ray_runs._Attempt(0, parcel_of(BINARY))
    outcomes[:] = [LostNode("1"), LostNode("2")]
    assert ray_runs._collect(ray, "ref", run, attempt, retries=1) is None
    final = ray_runs._collect(ray, "ref", run, attempt, retries=1)
    assert final is not None and final.verdict is Verdict.ERROR
    assert "the Ray task failed" in final.reason and len(final.retried) == 1


def test_a_run_that_raised_in_its_task_is_not_retried(tmp_path: Path) -> None:
    run = PlannedRun(SCENARIO, "4.6.0", tmp_path)

    def get(_ref: Any) -> Any:
        raise TaskRaised("ZeroDivisionError in the run")

    ray = SimpleNamespace(exceptions=FAKE_RAY.exceptions, get=get)
    result = ray_runs._collect(ray, "ref", run, ray_runs._Attempt(0, parcel_of(BINARY)), 5)
    assert result is not None and result.verdict is Verdict.ERROR and not result.retried
