"""A/B: the same scenarios on two builds (or one build with changed defaults), over several
seeds, and a verdict per scenario: did the change alter any failsafe, rescue or mission
behaviour, and how?

The plan flies each scenario with seeds ``seed, seed + 1, ...`` on side A and side B
(:func:`plan_comparison`).  A side is a firmware and CLI lines applied before the scenario's
own, so a changed default reaches every scenario that does not set it.  Judging
(:func:`compare_results`) is pure:

* **behaviour** (the failsafe's phases, the flight modes, how the run ended, the expectations'
  outcome): changed when no seed of B behaves like any seed of A;
* **findings** (:mod:`bfsitl.analysis`): an analyser that finds something on every seed of
  one side and nothing on any seed of the other, or is worse on every seed, makes the side
  worse or better;
* **figures** (:mod:`bfsitl.scenario.metrics`): different when B's values lie outside A's
  range (the seed-to-seed spread) by more than the figure's tolerance; a figure with a better
  direction (lower touchdown speed, tilt, hold error, energy) is then better or worse, one
  without (the time to a failsafe phase, the path) is a change.

Verdicts: ``same``, ``better``, ``worse``, ``changed`` (behaviour, a neutral figure, or better
and worse at once), ``error`` (a run could not be flown), ``skipped``.  Severity comes first:
a failure-severity finding (a crash, lost control) on any seed of B that no seed of A had makes
B **worse**, whatever else changed, and one A had on every seed that B never has makes it
better.  A figure of flights that ended otherwise (fell instead of landing) or worse (a harder
touchdown, farther from home) is never better: less time on the throttle is how a fall looks.
"""

from __future__ import annotations

import enum
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from bfsitl.analysis import Severity
from bfsitl.errors import ScenarioError
from bfsitl.scenario.metrics import METRICS, metric
from bfsitl.scenario.planned_run import PlannedRun
from bfsitl.scenario.result import ScenarioResult, Verdict
from bfsitl.scenario.spec import Scenario
from bfsitl.scenario.suite import dir_name

#: Behaviour keys compared, and how each is named in a reason.
BEHAVIOUR_KEYS = {
    "phases": "failsafe phases",
    "modes": "flight modes",
    "ended": "ended",
    "expectations": "expectations",
}


#: The figures that say how a flight ended; when one is worse on B, no other figure of B's
#: flights counts as better.
OUTCOME_FIGURES = frozenset({"touchdown_m_s", "landed_distance_m"})


class Change(enum.Enum):
    SAME = "same"
    BETTER = "better"
    WORSE = "worse"
    CHANGED = "changed"
    ERROR = "error"
    SKIPPED = "skipped"

    @property
    def fails(self) -> bool:
        """Whether this verdict stops a pull request unless accepted."""
        return self in (Change.WORSE, Change.CHANGED, Change.ERROR)


@dataclass(frozen=True, slots=True)
class RcRate:
    """An RC link rate a side flies every scenario at instead of its own ``[rc] rate_hz``."""

    hz: float | None  # None: a frame in every fdm packet

    @property
    def text(self) -> str:
        return "packet" if self.hz is None else f"{self.hz:g} Hz"


@dataclass(frozen=True, slots=True)
class Side:
    """One side of a comparison: a firmware and CLI lines applied before each scenario's,
    and the RC link's rate when it is not each scenario's own (``rc_rate``)."""

    label: str  # "A" or "B"
    firmware: str
    cli: tuple[str, ...] = ()
    rc_rate: RcRate | None = None

    @property
    def title(self) -> str:
        extra = f" + {'; '.join(self.cli)}" if self.cli else ""
        link = f", RC link {self.rc_rate.text}" if self.rc_rate is not None else ""
        return f"{self.label}: {self.firmware}{extra}{link}"

    def flies(self, scenario: Scenario) -> Scenario:
        """``scenario`` as this side flies it: its lines first, at its RC link rate (a
        replay keeps its log's, the rate its receiver had)."""
        if self.rc_rate is None or scenario.replay is not None:
            return replace(scenario, side_cli=self.cli)
        return replace(scenario, side_cli=self.cli, rc_rate_hz=self.rc_rate.hz)


@dataclass(frozen=True, slots=True)
class ComparedRun:
    """A planned run, and which side and seed it is."""

    side: str
    seed: int
    run: PlannedRun


def plan_comparison(
    scenarios: Sequence[Scenario], sides: tuple[Side, Side], seeds: int, out_dir: Path
) -> list[ComparedRun]:
    """Each scenario, each seed, on each side; files under ``OUT/SIDE/SCENARIO/seed-N``."""
    if seeds < 1:
        raise ScenarioError(f"--seeds {seeds}: at least 1")
    if sides[0].label == sides[1].label:
        raise ScenarioError("the two sides need different labels")
    planned = []
    for scenario in scenarios:
        for seed in range(scenario.seed, scenario.seed + seeds_for(scenario, seeds)):
            for side in sides:
                variant = replace(side.flies(scenario), seed=seed)
                out = out_dir / side.label / dir_name(scenario.name) / f"seed-{seed}"
                planned.append(
                    ComparedRun(side.label, seed, PlannedRun(variant, side.firmware, out))
                )
    return planned


def seeds_for(scenario: Scenario, seeds: int) -> int:
    """How many seeds ``scenario`` is flown with: ``seeds``, but one for a replay in air
    without gusts.  A replay's sticks are the log's, so its seeds change only the simulated
    sensors' noise, which does not reach a flight in rate mode (three seeds of a real log's
    replay came out identical to the last digit) and one in ANGLE only a little.  A replay
    asks what a change does to one flight: one seed per side, the figures' tolerances
    decide."""
    if scenario.replay is not None and (scenario.wind is None or scenario.wind.gust_std_m_s == 0):
        return 1
    return seeds


@dataclass(frozen=True, slots=True)
class FigureDiff:
    """One figure on both sides, judged."""

    name: str
    unit: str
    a: tuple[float | None, ...]
    b: tuple[float | None, ...]
    change: Change
    #: One line: the values and why they count as a difference (or not).
    note: str

    @staticmethod
    def mean(values: Sequence[float | None]) -> float | None:
        known = [v for v in values if v is not None]
        return statistics.fmean(known) if known else None


@dataclass(slots=True)
class ScenarioComparison:
    """One scenario on both sides, every seed, and the verdict."""

    name: str
    change: Change
    #: One line: why (the first changed behaviour, the worst figures).
    reason: str
    figures: list[FigureDiff] = field(default_factory=list)
    #: What differs beyond the figures, one line each ("failsafe phases: A ... B ...").
    differences: list[str] = field(default_factory=list)
    a_runs: list[ScenarioResult] = field(default_factory=list)
    b_runs: list[ScenarioResult] = field(default_factory=list)
    #: The verdict fails, but the user accepted it (``--accept NAME``).
    accepted: bool = False

    @property
    def fails(self) -> bool:
        """Worse or changed and not accepted, or not flown at all (no acceptance waives
        a run that could not be judged)."""
        return self.change is Change.ERROR or (self.change.fails and not self.accepted)


def compare_results(
    planned: Sequence[ComparedRun],
    results: Sequence[ScenarioResult],
    sides: tuple[Side, Side],
    accepted: Sequence[str] = (),
) -> list[ScenarioComparison]:
    """The verdict of each scenario from its runs (``results`` in ``planned``'s order)."""
    if len(planned) != len(results):
        raise ScenarioError(f"{len(results)} results for {len(planned)} planned runs")
    grouped: dict[str, tuple[list[ScenarioResult], list[ScenarioResult]]] = {}
    for entry, result in zip(planned, results, strict=True):
        a_runs, b_runs = grouped.setdefault(entry.run.scenario.name, ([], []))
        (a_runs if entry.side == sides[0].label else b_runs).append(result)
    return [_compare_one(name, a, b, name in accepted) for name, (a, b) in grouped.items()]


def _compare_one(
    name: str, a: list[ScenarioResult], b: list[ScenarioResult], accepted: bool
) -> ScenarioComparison:
    out = ScenarioComparison(name, Change.SAME, "", a_runs=a, b_runs=b, accepted=accepted)
    runs = a + b
    if all(r.verdict is Verdict.SKIPPED for r in runs):
        out.change, out.reason = Change.SKIPPED, runs[0].reason
        return out
    broken = [r for r in runs if r.verdict in (Verdict.ERROR, Verdict.SKIPPED)]
    if broken:
        out.change = Change.ERROR
        out.reason = f"{broken[0].test_id}: {broken[0].verdict.value}: {broken[0].reason}"
        return out
    out.differences = _behaviour_differences(a, b)
    found_worse, found_better = _finding_differences(a, b, out.differences)
    out.figures = _figures(a, b)
    ended_worse = any(f.name in OUTCOME_FIGURES and f.change is Change.WORSE for f in out.figures)
    if ended_worse or any(d.startswith(BEHAVIOUR_KEYS["ended"]) for d in out.differences):
        # A figure of a flight that ended otherwise, or worse (fell instead of landing, hit
        # harder), is no improvement: less throttle time is how a fall looks.
        out.figures = [_not_comparable(f) for f in out.figures]
    new_failures = _new_failures(a, b)
    worse = [f for f in out.figures if f.change is Change.WORSE] + found_worse
    better = [f for f in out.figures if f.change is Change.BETTER] + found_better
    neutral = [f for f in out.figures if f.change is Change.CHANGED]
    behaviour_changed = len(out.differences) > len(found_worse) + len(found_better)
    out.change = _verdict(
        behaviour_changed or bool(neutral), found_worse, found_better, bool(worse), bool(better)
    )
    if new_failures:
        # A failure A never had (a crash, lost control) makes B worse, whatever else changed.
        out.change = Change.WORSE
    elif _new_failures(b, a, every_seed=True):
        out.change = Change.BETTER
    notes = [f"new failure: {name}" for name in new_failures]
    notes += [d for d in out.differences if not d.startswith("finding")] + [
        _said(f) for f in (*worse, *better, *neutral)
    ]
    out.reason = (
        "; ".join(notes[:3])
        if notes
        else f"every figure within the seeds' spread ({len(a)} seed{'s' if len(a) > 1 else ''})"
    )
    return out


def _verdict(
    changed: bool, found_worse: list[str], found_better: list[str], worse: bool, better: bool
) -> Change:
    """Behaviour first; then the analysers (a new crash makes a side worse even if it spent
    less energy getting to the ground); then the figures."""
    if changed:
        return Change.CHANGED
    if found_worse or found_better:
        if found_worse and found_better:
            return Change.CHANGED
        return Change.WORSE if found_worse else Change.BETTER
    if worse and better:
        return Change.CHANGED
    return Change.WORSE if worse else Change.BETTER if better else Change.SAME


def _new_failures(
    a: list[ScenarioResult], b: list[ScenarioResult], *, every_seed: bool = False
) -> list[str]:
    """Analysers that found a failure in B (on any seed; ``every_seed``: on each) and never in
    A, named as "crash (failure on 2 of 2 seeds)"."""
    failure = int(Severity.FAILURE)
    names = sorted({f.analyser for r in b for f in r.findings if int(f.severity) >= failure})
    out = []
    for name in names:
        if any(_severities(r).get(name, 0) >= failure for r in a):
            continue
        seeds = sum(_severities(r).get(name, 0) >= failure for r in b)
        if every_seed and seeds < len(b):
            continue
        out.append(f"{name} (failure on {seeds} of {len(b)} seed{'s' if len(b) > 1 else ''})")
    return out


def _not_comparable(figure: FigureDiff) -> FigureDiff:
    if figure.change is not Change.BETTER:
        return figure
    # Not judged: shown, but it counts neither way (the ending decides).
    return replace(
        figure, change=Change.SKIPPED, note=f"{figure.note} (B's flights ended otherwise or worse)"
    )


def _said(item: FigureDiff | str) -> str:
    return item if isinstance(item, str) else f"{item.name} {item.note}"


def _behaviour(result: ScenarioResult, key: str) -> tuple[str, ...]:
    if key == "expectations":
        # The ones that failed: "all met" is the empty tuple.
        return tuple(f"{c.expectation} failed" for c in result.checks if not c.passed)
    return tuple(result.behaviour.get(key, ()))


def _behaviour_differences(a: list[ScenarioResult], b: list[ScenarioResult]) -> list[str]:
    lines = []
    for key, label in BEHAVIOUR_KEYS.items():
        seen_a = {_behaviour(r, key) for r in a}
        seen_b = {_behaviour(r, key) for r in b}
        if seen_a.isdisjoint(seen_b):
            lines.append(f"{label}: A {_shown(seen_a, key)}; B {_shown(seen_b, key)}")
    return lines


def _shown(values: set[tuple[str, ...]], key: str = "") -> str:
    joiner = ", " if key in ("expectations", "modes") else " -> "
    empty = "all met" if key == "expectations" else "none"
    return " | ".join(joiner.join(v) or empty for v in sorted(values))


def _severities(result: ScenarioResult) -> dict[str, int]:
    return {f.analyser: int(f.severity) for f in result.findings}


def _finding_differences(
    a: list[ScenarioResult], b: list[ScenarioResult], lines: list[str]
) -> tuple[list[str], list[str]]:
    """(findings that make B worse, ... better); each also a line of ``lines``."""
    worse, better = [], []
    names = sorted({n for r in a + b for n in _severities(r)})
    for name in names:
        in_a = [_severities(r).get(name, 0) for r in a]
        in_b = [_severities(r).get(name, 0) for r in b]
        if min(in_b) > max(in_a):
            line = f"finding {name}: A {_levels(in_a)}, B {_levels(in_b)}"
            worse.append(line)
            lines.append(line)
        elif max(in_b) < min(in_a):
            line = f"finding {name}: A {_levels(in_a)}, B {_levels(in_b)}"
            better.append(line)
            lines.append(line)
    return worse, better


def _levels(values: list[int]) -> str:
    return ",".join(Severity(v).label if v else "none" for v in values)


def _figures(a: list[ScenarioResult], b: list[ScenarioResult]) -> list[FigureDiff]:
    names = [m.name for m in METRICS]
    names += sorted({n for r in a + b for n in r.metrics if n not in names})
    diffs = []
    for name in names:
        va = tuple(r.metrics.get(name) for r in a)
        vb = tuple(r.metrics.get(name) for r in b)
        if all(v is None for v in va + vb):
            continue
        diffs.append(_judge_figure(name, va, vb))
    return diffs


def _judge_figure(
    name: str, va: tuple[float | None, ...], vb: tuple[float | None, ...]
) -> FigureDiff:
    spec = metric(name)
    known_a = [v for v in va if v is not None]
    known_b = [v for v in vb if v is not None]
    shown = f"A {_range(known_a)}, B {_range(known_b)} {spec.unit}".rstrip()
    if not known_a or not known_b:
        if len(known_a) == len(va) or len(known_b) == len(vb):
            # One side always has it, the other never: a different ending (landed or not, a
            # phase reached or not).
            return FigureDiff(
                name, spec.unit, va, vb, Change.CHANGED, f"{shown} (only one side has it)"
            )
        return FigureDiff(name, spec.unit, va, vb, Change.SAME, shown)
    apart = (
        min(known_b) - max(known_a) > spec.tolerance or min(known_a) - max(known_b) > spec.tolerance
    )
    if not apart:
        return FigureDiff(name, spec.unit, va, vb, Change.SAME, shown)
    higher = statistics.fmean(known_b) > statistics.fmean(known_a)
    if spec.better == "lower":
        change = Change.WORSE if higher else Change.BETTER
    else:
        change = Change.CHANGED
    return FigureDiff(
        name,
        spec.unit,
        va,
        vb,
        change,
        f"{shown}: apart by more than {f'{spec.tolerance:g} {spec.unit}'.rstrip()} beyond the "
        "seeds' spread",
    )


def _range(values: list[float]) -> str:
    if not values:
        return "none"
    low, high = min(values), max(values)
    return f"{low:.2f}" if abs(high - low) < 0.005 else f"{low:.2f}..{high:.2f}"
