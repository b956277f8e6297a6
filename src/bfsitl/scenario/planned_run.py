"""One planned run (a scenario on a firmware, and where its files go), and how a worker
process or a Ray task flies it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import BfsitlError
from bfsitl.scenario.result import PlotWhen, ScenarioResult
from bfsitl.scenario.run import RunOptions, run_scenario
from bfsitl.scenario.spec import Scenario
from bfsitl.sitl.core_claim import claim_core
from bfsitl.sitl.firmware import find_firmware


@dataclass(frozen=True, slots=True)
class PlannedRun:
    """One scenario on one firmware, and where its files go."""

    scenario: Scenario
    firmware: str
    out_dir: Path

    @property
    def test_id(self) -> str:
        return f"{self.scenario.name}[{self.firmware}]"


def _is_lockstep(firmware: str) -> bool:
    """The build is a lockstep one (False if it cannot be found: the run says why)."""
    try:
        return find_firmware(firmware).lockstep
    except BfsitlError:
        return False


def fly_one(
    scenario: Scenario,
    firmware: str,
    out_dir: Path,
    speed: float | None,
    plot: PlotWhen,
    mcap: bool,
) -> ScenarioResult:
    """A worker's job: the run's progress goes to a file in its directory (several runs'
    lines interleaved on one terminal would be unreadable).  Workers share the machine's
    cores, so a lockstep run does not busy-wait (Timing.lockstep_spin); it claims a
    core for itself and its SITL instead (bfsitl.sitl.core_claim), so that runs side by side
    neither take each other's time nor wake each other's cores."""
    out_dir.mkdir(parents=True, exist_ok=True)
    # Only a lockstep run is one core's work; a stock SITL runs on the wall clock beside us.
    claim = claim_core() if _is_lockstep(firmware) else None
    try:
        with open(out_dir / "progress.log", "w", buffering=1) as log:
            return run_scenario(
                scenario,
                firmware,
                RunOptions(out_dir, speed=speed, plot=plot, mcap=mcap, shares_cores=True),
                progress=lambda line: print(line, file=log),
            )
    finally:
        if claim is not None:
            claim.release()
