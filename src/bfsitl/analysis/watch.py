"""The analysers as a flight's companion: :class:`FlightWatch` takes each row as it is flown
(a record sink's place, see :class:`~bfsitl.records.outputs.FlightOutputs`) and gives the
findings at the end; :func:`combine` merges what several sources saw of one flight (bfsitl's
record and the FC's blackbox), keeping each analyser's worst."""

from __future__ import annotations

from typing import TYPE_CHECKING

from bfsitl.analysis.analysers import Analysis, analyse
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.track import Track, point_from_row

if TYPE_CHECKING:
    from bfsitl.mission.flight_row import FlightRow
    from bfsitl.mission.vehicle import FlightSample


#: A hard landing this close to a crash is the crash, seen by another source.
SAME_IMPACT_S = 1.0


class FlightWatch:
    """Collects a flight's points as they come; :meth:`analysis` runs every analyser."""

    def __init__(self, *, label: str = "", limits: Limits | None = None) -> None:
        self.track = Track("flight", label=label)
        self.limits = limits or Limits()

    def add(
        self,
        row: FlightRow,
        sample: FlightSample | None = None,
        *,
        time_s: float | None = None,
        failsafe_phase: int | None = None,
    ) -> None:
        self.track.points.append(
            point_from_row(row, sample, time_s=time_s, failsafe_phase=failsafe_phase)
        )

    def analysis(self) -> Analysis:
        return analyse(self.track, self.limits)


def combine(*analyses: Analysis) -> Analysis:
    """One analysis of one flight from several sources: each analyser's worst finding (the
    first source wins a tie), watched by any, skipped only where none could run it."""
    merged = Analysis()
    best: dict[str, int] = {}
    for analysis in analyses:
        for name in analysis.watched:
            if name not in merged.watched:
                merged.watched.append(name)
        for finding in analysis.findings:
            index = best.get(finding.analyser)
            if index is None:
                best[finding.analyser] = len(merged.findings)
                merged.findings.append(finding)
            elif finding.severity > merged.findings[index].severity:
                merged.findings[index] = finding
    for analysis in analyses:
        for name, why in analysis.skipped.items():
            if name not in merged.watched and name not in merged.skipped:
                merged.skipped[name] = why
    crash = next((f for f in merged.findings if f.analyser == "crash"), None)
    if crash is not None:
        # One impact seen twice: the crash, and the log's accelerometer peak of it (the
        # sources' clocks differ by the log's start, a few tenths of a second).
        merged.findings = [
            f
            for f in merged.findings
            if not (f.analyser == "hard_landing" and abs(f.time_s - crash.time_s) <= SAME_IMPACT_S)
        ]
    merged.findings.sort(key=lambda f: (-f.severity, f.time_s))
    return merged
