"""The analysers of a target held: ``altitude_excursion``, ``position_excursion`` and
``altitude_estimate`` (the table in :mod:`bfsitl.analysis.analysers`), graded against a
warning and a failure bound."""

from __future__ import annotations

import math
from collections.abc import Callable

from bfsitl.analysis.findings import Finding, Severity
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.series import (
    evidence_of,
    finite,
    held_points,
    require,
)
from bfsitl.analysis.track import Track, TrackPoint


def _graded(value: float, bounds: tuple[float, float]) -> Severity | None:
    if value >= bounds[1]:
        return Severity.FAILURE
    if value >= bounds[0]:
        return Severity.WARNING
    return None


def _worst_graded(
    points: list[TrackPoint], off: Callable[[TrackPoint], float], bounds: tuple[float, float]
) -> tuple[TrackPoint, float, Severity] | None:
    """The point farthest off, how far, and its grade; None when none reaches a bound."""
    if not points:
        return None
    worst = max(points, key=off)
    severity = _graded(off(worst), bounds)
    return None if severity is None else (worst, off(worst), severity)


def altitude_excursion(track: Track, limits: Limits) -> Finding | None:
    require(track, "alt_m", "target_alt_m", "phase")
    held = [
        p
        for p in held_points(track, limits.hold_settle_s)
        if finite(p.target_alt_m) and finite(p.alt_m)
    ]
    graded = _worst_graded(
        held, lambda p: abs(p.alt_m - p.target_alt_m), limits.altitude_excursion_m
    )
    if graded is None:
        return None
    worst, error, severity = graded
    return Finding(
        "altitude_excursion",
        severity,
        f"{error:.1f} m {'above' if worst.alt_m > worst.target_alt_m else 'below'} "
        f"the held {worst.target_alt_m:.1f} m",
        worst.time_s,
        error,
        "m",
        {"target_alt_m": worst.target_alt_m, "sample": evidence_of(worst)},
        track.source,
    )


def position_excursion(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m", "target_north_m", "phase")
    held = [
        p
        for p in held_points(track, limits.hold_settle_s)
        if finite(p.target_north_m) and finite(p.north_m)
    ]
    graded = _worst_graded(
        held,
        lambda p: math.hypot(p.north_m - p.target_north_m, p.east_m - p.target_east_m),
        limits.position_excursion_m,
    )
    if graded is None:
        return None
    worst, off, severity = graded
    return Finding(
        "position_excursion",
        severity,
        f"{off:.1f} m off the held position",
        worst.time_s,
        off,
        "m",
        {
            "target_north_m": worst.target_north_m,
            "target_east_m": worst.target_east_m,
            "sample": evidence_of(worst),
        },
        track.source,
    )


def altitude_estimate(track: Track, limits: Limits) -> Finding | None:
    require(track, "alt_m", "fc_alt_m", "airborne")
    flying = [
        p for p in track.points if p.armed and p.airborne and finite(p.fc_alt_m) and finite(p.alt_m)
    ]
    graded = _worst_graded(flying, lambda p: abs(p.fc_alt_m - p.alt_m), limits.altitude_estimate_m)
    if graded is None:
        return None
    worst, error, severity = graded
    return Finding(
        "altitude_estimate",
        severity,
        f"the FC's altitude {error:.1f} m off the truth ({worst.fc_alt_m:.1f} m "
        f"against {worst.alt_m:.1f} m)",
        worst.time_s,
        error,
        "m",
        {"fc_alt_m": worst.fc_alt_m, "sample": evidence_of(worst)},
        track.source,
    )
