"""What a scenario run produced: a verdict, the checks behind it, its files.

These are plain records: the runner (:mod:`bfsitl.scenario.run`) fills them, the JUnit
writer (:mod:`bfsitl.scenario.junit`) and the report page (:mod:`bfsitl.scenario.report`)
read them, and they cross process boundaries (``--jobs``, Ray) by pickling.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from bfsitl.analysis import Analysis, Finding


class Verdict(enum.Enum):
    """How a scenario ended."""

    #: Flown to its end, every expectation met.
    PASSED = "passed"
    #: Flown to its end, at least one expectation not met.
    FAILED = "failed"
    #: Flown to its end, every expectation met, and a firmware defect the scenario declares
    #: (``[[known_failure]]``) happened as it was known to.
    KNOWN = "known failure"
    #: It could not be flown as written (the SITL exited, a fault the firmware cannot take,
    #: arming blocked, a bfsitl error): nothing was judged.
    ERROR = "error"
    #: Not run (the firmware asked for is not the one given, or a fault it cannot express).
    SKIPPED = "skipped"


#: When a run draws its plots: True always, False never, "failed" only when it failed or
#: errored (the runs someone looks at; a known failure is expected, as pytest's xfail), which
#: costs the other runs nothing.  Drawing them was a tenth of a lockstep run's wall time.
PlotWhen = bool | Literal["failed"]


def wants_plot(plot: PlotWhen, verdict: Verdict) -> bool:
    """Whether a run that ended with ``verdict`` draws its plots."""
    if plot == "failed":
        return verdict in (Verdict.FAILED, Verdict.ERROR)
    return bool(plot)


@dataclass(frozen=True, slots=True)
class CheckResult:
    """One expectation, judged."""

    #: The expectation as the scenario file wrote it, e.g. ``landed_within_m = 3.0``.
    expectation: str
    passed: bool
    #: One line a person reads: what was expected, what was measured, and when.
    message: str
    #: The measured value (a number, a mode name, a phase name), None when nothing was seen.
    measured: float | str | None = None
    #: Simulation time of the measurement, seconds from the start of the run.
    at_time_s: float | None = None


@dataclass(frozen=True, slots=True)
class TimedEvent:
    """Something that happened during the run (a fault injected, a mode seen, a disarm)."""

    time_s: float
    text: str


@dataclass(slots=True)
class ScenarioResult:
    """One scenario on one firmware.

    Attributes:
        name: The scenario's name (its file's stem unless it names itself).
        firmware: The firmware as asked for (a cached build's name or a path).
        verdict: Passed, failed, error or skipped.
        reason: One line: the first failed check, the error, or "all N expectations met".
        source: The scenario file, when it came from one.
        vehicle: The simulated quad's name (``iris``, ``5inch-freestyle``, a profile's).
        firmware_version: As the FC reported it (MSP_FC_VERSION); "" when it never
            answered.
        description: The scenario's one line saying what it tests.
        checks: Each expectation, judged.
        events: What happened during the run, in time order (faults injected, modes seen,
            a disarm).
        sim_time_s: Simulation seconds flown.
        wall_time_s: Wall seconds the run took.
        artifacts: Files the run wrote, by kind: "log" (CSV), "plot" (PNG), "blackbox" (the
            FC's own log), "sitl_log" (the firmware's output), "summary" (JSON).
        retried: Why earlier attempts of this run were lost (a Ray worker or node gone),
            oldest first; empty when it ran once.
        findings: What the analysers that watch every run found (:mod:`bfsitl.analysis`),
            worst first, whether or not an expectation asked.
        watched: The analysers that watched this run.
        unwatched: The analysers that could not, each with why.
        metrics: The run's figures (:mod:`bfsitl.scenario.metrics`; None: not applicable):
            what ``bfsitl scenario compare`` compares.
        behaviour: The run's behaviour in words (failsafe phases, modes, how it ended,
            findings), also compared.
        settings: The FC's configuration as given, each line with its source.
        timings_s: Where the run's wall time went, by phase.
    """

    #: The scenario's name (its file's stem unless it names itself).
    name: str
    #: The firmware as asked for (a cached build's name or a path).
    firmware: str
    verdict: Verdict
    #: One line: the first failed check, the error, or "all N expectations met".
    reason: str
    #: The scenario file, when it came from one.
    source: Path | None = None
    #: As the FC reported it (MSP_FC_VERSION); "" when it never answered.
    firmware_version: str = ""
    #: The simulated quad's name (``iris``, ``5inch-freestyle``, a profile's).
    vehicle: str = "iris"
    description: str = ""
    checks: list[CheckResult] = field(default_factory=list)
    events: list[TimedEvent] = field(default_factory=list)
    #: Simulation seconds flown and wall seconds it took.
    sim_time_s: float = 0.0
    wall_time_s: float = 0.0
    #: Files the run wrote, by kind: "log" (CSV), "plot" (PNG), "blackbox" (the FC's own
    #: log), "sitl_log" (the firmware's stdout), "summary" (JSON).
    artifacts: dict[str, Path] = field(default_factory=dict)
    #: Why earlier attempts of this run were lost (a Ray worker or node gone), oldest first;
    #: empty when it ran once.
    retried: tuple[str, ...] = ()
    #: What the analysers that watch every run found (:mod:`bfsitl.analysis`), worst first,
    #: whether or not an expectation asked.
    findings: list[Finding] = field(default_factory=list)
    #: The analysers that watched this run, and those that could not (name -> why).
    watched: list[str] = field(default_factory=list)
    unwatched: dict[str, str] = field(default_factory=dict)
    #: What the FC was given before the flight, in order: (source, line, why) per line
    #: (:mod:`bfsitl.scenario.setup_lines`: bfsitl, this build, the side, the scenario, a
    #: replayed log's header).
    settings: list[tuple[str, str, str]] = field(default_factory=list)
    #: Wall seconds per phase of the run (:mod:`bfsitl.scenario.timings`: start-up, arming,
    #: flight, stop, blackbox, analysers, plots, files).
    timings_s: dict[str, float] = field(default_factory=dict)
    #: The run's figures (:mod:`bfsitl.scenario.metrics`; None: not applicable) and its
    #: behaviour in words (failsafe phases, modes, how it ended, findings): what
    #: ``bfsitl scenario compare`` compares.
    metrics: dict[str, float | None] = field(default_factory=dict)
    behaviour: dict[str, list[str]] = field(default_factory=dict)

    def take_analysis(self, analysis: Analysis) -> None:
        """Keep what the analysers found, which watched and which could not.

        Args:
            analysis: The analysers' results on the run (a flown run's tracks combined, or
                a replayed log's).
        """
        self.findings = analysis.findings
        self.watched = analysis.watched
        self.unwatched = analysis.skipped

    @property
    def passed(self) -> bool:
        return self.verdict is Verdict.PASSED

    @property
    def test_id(self) -> str:
        """``name[firmware]``: unique within a run of several firmwares."""
        return f"{self.name}[{self.firmware}]"
