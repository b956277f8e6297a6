"""Analysers that always watch: every flight, every scenario run and any blackbox log gets
the same checks (a crash, a hard landing, a fly-away, lost control, oscillation, saturated
motors, a failsafe, a GPS glitch, excursions), each with a severity and its evidence,
whether or not anything asked (:mod:`bfsitl.analysis.analysers` lists them)."""

from bfsitl.analysis.analysers import ANALYSERS, Analyser, Analysis, analyse
from bfsitl.analysis.findings import Finding, Severity, finding_from_dict, worst
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.track import (
    Track,
    TrackPoint,
    point_from_row,
    track_from_blackbox,
    track_from_rows,
)
from bfsitl.analysis.watch import FlightWatch, combine

__all__ = [
    "ANALYSERS",
    "Analyser",
    "Analysis",
    "Finding",
    "FlightWatch",
    "Limits",
    "Severity",
    "Track",
    "TrackPoint",
    "analyse",
    "combine",
    "finding_from_dict",
    "point_from_row",
    "track_from_blackbox",
    "track_from_rows",
    "worst",
]
