"""Where a scenario run's wall time goes: start-up, arming, the flight, stopping, the
blackbox, the analysers, the plots and the files, each timed as it happens.

A lockstep flight is many times faster than real time; a run is more than its flight, and a
suite is as fast as its runs.  ``bfsitl scenario run --timings`` and
``benchmarks/scenarios.py`` print :func:`timings_table`: per run and summed, so what to make
faster is measured, not guessed.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

#: The phases in the order a run goes through them (a replay: its log read, then its flight).
PHASES = (
    "prepare",  # the FC's configuration made (once per build and configuration; cached)
    "start-up",  # the SITL booted (configured already, or provisioned and rebooted)
    "arming",
    "flight",  # the autopilot and the watch: what simulated time costs
    "stop",  # the SITL stopped, the flight's own files closed
    "log read",  # a replay's log decoded and checked
    "blackbox",  # the FC's log copied out and decoded
    "analysers",  # findings, figures and expectations
    "plots",
    "files",  # trace.csv, a replay's report (result.json comes after the timings)
)


@dataclass
class Stopwatch:
    """Adds up the wall seconds spent in each phase (:data:`PHASES`); ``clock`` is injected
    so tests can count without waiting."""

    clock: Callable[[], float] = time.perf_counter
    spans_s: dict[str, float] = field(default_factory=dict)

    @contextlib.contextmanager
    def span(self, phase: str) -> Iterator[None]:
        started = self.clock()
        try:
            yield
        finally:
            self.spans_s[phase] = self.spans_s.get(phase, 0.0) + self.clock() - started


def timings_table(runs: Sequence[tuple[str, dict[str, float], float]]) -> list[str]:
    """Lines of a table: a row per run (its label, its phases' seconds, its simulated
    seconds) and their sum, each phase with its share of the wall time.  A row's "wall s" is
    the sum of its phases: a run's own wall time also holds finding its firmware and writing
    its result.json."""
    phases = [p for p in PHASES if any(p in spans for _, spans, _ in runs)]
    width = max([len(label) for label, _, _ in runs] + [5])
    head = f"{'run':<{width}} " + " ".join(f"{p:>9}" for p in phases)
    lines = [f"{head} {'wall s':>8} {'sim s':>7} {'speed':>7}"]
    totals: dict[str, float] = {}
    simulated = 0.0
    for label, spans, sim_s in runs:
        lines.append(_row(label, width, phases, spans, sim_s))
        for phase, seconds in spans.items():
            totals[phase] = totals.get(phase, 0.0) + seconds
        simulated += sim_s
    if len(runs) > 1:
        lines.append(_row("sum", width, phases, totals, simulated))
    wall = sum(totals.values())
    if wall > 0:
        shares = " ".join(f"{100 * totals.get(p, 0.0) / wall:>8.0f}%" for p in phases)
        lines.append(f"{'share':<{width}} {shares}")
    return lines


def _row(label: str, width: int, phases: list[str], spans: dict[str, float], sim_s: float) -> str:
    wall = sum(spans.values())
    cells = " ".join(f"{spans.get(p, 0.0):>9.2f}" for p in phases)
    speed = f"{sim_s / wall:>6.1f}x" if wall > 0 else f"{'-':>7}"
    return f"{label:<{width}} {cells} {wall:>8.2f} {sim_s:>7.1f} {speed}"
