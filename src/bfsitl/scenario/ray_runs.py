"""Scenario runs on a Ray cluster: the firmware travels, the files come home, a lost node
loses nothing.

* **The firmware travels.** The driver reads each build the runs need once, names it by its
  SHA-256 and puts its bytes in Ray's object store; its build record (``build.json``: the
  options it was built with, which tell bfsitl it has a GPS) goes with it. A node that gets
  a run takes the bytes (only the first time: it keeps them in its own cache under
  ``received/<hash>/``, written whole and checked against the hash) and flies that file. A
  node needs bfsitl and Ray, nothing else: no firmware cache, no build tools.
* **The files come home.** A run flies in a temporary directory on its node; its files (CSV,
  plot, blackbox, summary, MCAP, the SITL's log) come back to the driver as one compressed
  archive, at most ``max_artifact_mb``, and are unpacked under the run's ``--out`` directory
  there, so the JUnit file and the report link to files the driver has. A run whose files
  exceed the bound is an error that says so; nothing stays only on a worker.
* **A lost node loses nothing.** A run whose worker or node dies (Ray reports a system
  error, not the run's own) is submitted again, up to ``retries`` times; the result says it
  was retried and why. A run that fails on its own merits returns a result, never an
  exception, so it is never retried. Ctrl-C cancels the cluster's tasks; each task's SITL
  runs under a namespace agent that stops it when its owner goes.
"""

from __future__ import annotations

import io
import shutil
import tarfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

from bfsitl.atomic_file import write_atomically
from bfsitl.errors import ScenarioError
from bfsitl.owned_temp import owned_temp_dir
from bfsitl.scenario.planned_run import PlannedRun, fly_one
from bfsitl.scenario.result import PlotWhen, ScenarioResult, Verdict
from bfsitl.scenario.run import write_summary
from bfsitl.sitl.firmware_parcel import FirmwareParcel, pack_firmware, unpack_firmware

#: A run's files may bring at most this much home by default (compressed).
DEFAULT_MAX_ARTIFACT_MB = 256.0
#: A run whose node or worker is lost is submitted again at most this often by default.
DEFAULT_RETRIES = 2


@dataclass(frozen=True, slots=True)
class RemoteOutcome:
    """What a task sends back: the result (artefacts relative to the run's directory), the
    run's files as one archive, where it ran and how long the task took there."""

    result: ScenarioResult
    archive: bytes
    node_id: str
    task_s: float = 0.0


@dataclass(frozen=True, slots=True)
class RayTiming:
    """One run's cost on the cluster, for planning (``benchmarks/scenarios.py``): from the
    driver's submit to its files home, the task's time on its node, the run's own time."""

    test_id: str
    latency_s: float  # submit -> result and files home (the driver's clock)
    task_s: float  # the task on its node: firmware, run, packing (the node's clock)
    run_s: float  # the run itself (ScenarioResult.wall_time_s)
    archive_bytes: int


def pack_outputs(directory: Path, max_bytes: int) -> bytes:
    """Every file under ``directory`` as one gzip'd tar; ScenarioError past ``max_bytes``."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as archive:
        for path in sorted(directory.rglob("*")):
            if path.is_file():
                archive.add(path, arcname=path.relative_to(directory).as_posix())
            if buffer.tell() > max_bytes:
                break
    size = buffer.tell()
    if size > max_bytes:
        raise ScenarioError(
            f"the run's files come to more than {max_bytes / 1e6:.0f} MB compressed, the "
            f"bound for bringing them home from a Ray node: fly it with fewer outputs "
            f"(--no-plot, no --mcap) or raise --ray-max-mb"
        )
    return buffer.getvalue()


def unpack_outputs(data: bytes, out_dir: Path) -> None:
    """A run's archive under ``out_dir``; a member that would land outside it (an absolute
    path, ``..``, a link) is refused."""
    out_dir.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as archive:
        for member in archive.getmembers():
            name = PurePosixPath(member.name)
            if name.is_absolute() or ".." in name.parts or not (member.isfile() or member.isdir()):
                raise ScenarioError(
                    f"a run's archive holds {member.name!r}, which would land "
                    f"outside its directory: refused"
                )
            target = out_dir.joinpath(*name.parts)
            if member.isdir():
                target.mkdir(parents=True, exist_ok=True)
                continue
            source = archive.extractfile(member)
            assert source is not None
            write_atomically(target, source.read())


def fly_remote(
    run: PlannedRun,
    parcel: FirmwareParcel,
    speed: float | None,
    plot: PlotWhen,
    mcap: bool,
    max_bytes: int,
) -> RemoteOutcome:
    """A Ray task: one run on this node, in a temporary directory, with the firmware that
    travelled; its files packed to go home."""
    import ray

    began_s = time.monotonic()
    binary = unpack_firmware(parcel, ray.get)
    work = owned_temp_dir("bfsitl-ray-run-")
    try:
        result = fly_one(run.scenario, str(binary), work, speed, plot, mcap)
        result.firmware = run.firmware  # as the driver named it, not this node's path
        result.artifacts = {kind: _relative(path, work) for kind, path in result.artifacts.items()}
        try:
            archive = pack_outputs(work, max_bytes)
        except ScenarioError as exc:
            result.verdict, result.reason = Verdict.ERROR, str(exc)
            result.artifacts = {}
            archive = b""
        return RemoteOutcome(
            result, archive, ray.get_runtime_context().get_node_id(), time.monotonic() - began_s
        )
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _relative(path: Path, work: Path) -> Path:
    try:
        return path.relative_to(work)
    except ValueError:
        return path  # outside the run's directory: left as it was (nothing ships it)


def bring_home(outcome: RemoteOutcome, run: PlannedRun) -> ScenarioResult:
    """The run's files under its ``out_dir`` on the driver, and its result pointing there."""
    result = outcome.result
    if outcome.archive:
        unpack_outputs(outcome.archive, run.out_dir)
    result.artifacts = {
        kind: path if path.is_absolute() else run.out_dir / path
        for kind, path in result.artifacts.items()
    }
    return result


def is_lost_worker(ray: Any, exc: BaseException) -> bool:
    """Whether a task failed because its worker or node went (worth another try), not
    because of anything in the run (a RayTaskError carries the run's own exception)."""
    errors = ray.exceptions
    return isinstance(exc, errors.RayError) and not isinstance(
        exc, errors.RayTaskError | errors.TaskCancelledError
    )


@dataclass
class _Attempt:
    index: int
    parcel: FirmwareParcel
    tries: int = 1
    why: tuple[str, ...] = ()
    submitted_s: float = 0.0


def run_on_ray(
    runs: Sequence[PlannedRun],
    address: str,
    *,
    speed: float | None,
    plot: PlotWhen,
    mcap: bool,
    results: dict[int, ScenarioResult],
    done: Callable[[ScenarioResult], None],
    say: Callable[[str], None],
    max_artifact_mb: float = DEFAULT_MAX_ARTIFACT_MB,
    retries: int = DEFAULT_RETRIES,
    timings: list[RayTiming] | None = None,
) -> None:
    """Every run as a Ray task on the cluster at ``address`` (module docstring); results
    into ``results`` by plan index, each passed to ``done`` as it comes; each run's
    :class:`RayTiming` appended to ``timings`` when given."""
    try:
        import ray
    except ImportError as exc:
        raise ScenarioError("--ray needs Ray: pip install 'bfsitl[ray]'") from exc
    if retries < 0:
        raise ScenarioError(f"--ray-retries {retries}: 0 or more")
    try:
        ray.init(address=address, log_to_driver=False, ignore_reinit_error=True)
    except (ConnectionError, RuntimeError, ValueError) as exc:
        raise ScenarioError(
            f"cannot reach the Ray cluster at {address}: {exc} (start one "
            f"with `ray start --head`, then pass the address it prints)"
        ) from exc
    try:
        parcels = pack_firmware(ray, [run.firmware for run in runs])
        say(
            f"{len(runs)} runs on the Ray cluster at {address} "
            f"({ray.cluster_resources().get('CPU', 0):g} CPUs); "
            + ", ".join(
                f"{p.name} travels as {p.sha256[:12]} ({p.size / 1e6:.1f} MB)"
                for p in parcels.values()
            )
        )
        task = ray.remote(num_cpus=1, max_retries=0)(fly_remote)
        max_bytes = int(max_artifact_mb * 1e6)

        def submit(attempt: _Attempt) -> Any:
            run = runs[attempt.index]
            attempt.submitted_s = time.monotonic()
            return task.remote(run, attempt.parcel, speed, plot, mcap, max_bytes)

        pending = {
            submit(a): a for a in (_Attempt(i, parcels[run.firmware]) for i, run in enumerate(runs))
        }
        try:
            while pending:
                ready, _rest = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    attempt = pending.pop(ref)
                    result = _collect(ray, ref, runs[attempt.index], attempt, retries, timings)
                    if result is None:  # lost with its worker: once more
                        pending[submit(attempt)] = attempt
                        say(
                            f"{runs[attempt.index].test_id}: {attempt.why[-1]}; trying again "
                            f"(attempt {attempt.tries} of {retries + 1})"
                        )
                        continue
                    results[attempt.index] = result
                    done(result)
        except KeyboardInterrupt:
            for ref in pending:
                ray.cancel(ref, force=True)  # the namespace agent stops each task's SITL
            raise
    finally:
        ray.shutdown()


def _collect(
    ray: Any,
    ref: Any,
    run: PlannedRun,
    attempt: _Attempt,
    retries: int,
    timings: list[RayTiming] | None = None,
) -> ScenarioResult | None:
    """The run's result with its files home; None when it should be tried again."""
    try:
        outcome: RemoteOutcome = ray.get(ref)
    except Exception as exc:  # noqa: BLE001 - a lost worker is retried, anything else errs
        if is_lost_worker(ray, exc) and attempt.tries <= retries:
            attempt.tries += 1
            attempt.why += (f"its Ray worker or node was lost ({type(exc).__name__})",)
            return None
        return ScenarioResult(
            run.scenario.name,
            run.firmware,
            Verdict.ERROR,
            f"the Ray task failed: {exc!r}"[:500],
            source=run.scenario.source,
            vehicle=run.scenario.quad.name,
            retried=attempt.why,
        )
    result = bring_home(outcome, run)
    result.retried = attempt.why
    if timings is not None:
        timings.append(
            RayTiming(
                run.test_id,
                time.monotonic() - attempt.submitted_s,
                outcome.task_s,
                result.wall_time_s,
                len(outcome.archive),
            )
        )
    if "summary" in result.artifacts:
        write_summary(result, run.out_dir)  # the driver's names and paths
    return result
