"""Expectations on where the vehicle went and how: distances from a point, a point reached,
where it ended, ground speed, heading, the path flown.  What a mission needs judged (the FC's
own waypoints, a geofence, an orbit), on the simulated truth.

=========================================  ==================================================
key = value                                holds when
=========================================  ==================================================
``max_distance_m = D`` or ``{ value = D,   never further than D m (horizontally) from the
north_m = N, east_m = E, from_s, until_s }``  take-off point, or from (N, E), in the window
``min_distance_m = { value = D, ... }``    never closer than D m (an orbit keeps off its
                                           centre)
``reached = { north_m = N, east_m = E,     came within R m of (N, E) at some point
within_m = R }`` (``from_s``, ``until_s``)
``ends_within_m = { value = R, north_m,    the run ended within R m of (N, E)
east_m }``
``max_ground_speed_m_s = V`` (window)      never faster than V over the ground (0.5 s means)
``heading_deg = { value = H, within_deg =  the true heading stayed within W of H, over the
W, from_s, until_s }``                     window
``min_path_m = { value = P, from_s, ... }`` it flew at least P m (horizontally) in the window
=========================================  ==================================================
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bfsitl.errors import ScenarioError
from bfsitl.scenario.expect_base import Limit, check
from bfsitl.scenario.result import CheckResult
from bfsitl.scenario.trace import Trace, TraceRow

#: Ground speed is averaged over this long (a 50 Hz truth's steps are noisy to difference).
SPEED_WINDOW_S = 0.5
POINT_KEYS = {"north_m", "east_m", "within_m", "from_s", "until_s"}
HEADING_KEYS = {"value", "within_deg", "from_s", "until_s"}


def _origin(limit: Limit) -> tuple[float, float]:
    return (limit.north_m or 0.0, limit.east_m or 0.0)


def _from(point: tuple[float, float]) -> Callable[[TraceRow], float]:
    def distance(row: TraceRow) -> float:
        return math.hypot(row.north_m - point[0], row.east_m - point[1])

    return distance


def _window(
    trace: Trace, from_s: float | None, until_s: float | None, measure: Callable[[TraceRow], float]
) -> list[TraceRow]:
    return [r for r in trace.window(from_s, until_s) if math.isfinite(measure(r))]


def distance_bound(*, lowest: bool) -> Callable[[str, Limit, Trace, dict[str, Any]], CheckResult]:
    """``max_distance_m`` (``lowest`` False) and ``min_distance_m``."""

    def judge(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
        measure = _from(_origin(limit))
        rows = _window(trace, limit.from_s, limit.until_s, measure)
        if not rows:
            return check(key, limit, False, "no position in the window", None, None)
        row = (min if lowest else max)(rows, key=measure)
        value = measure(row)
        passed = value >= limit.value if lowest else value <= limit.value
        return check(
            key,
            limit,
            passed,
            f"{'came as close as' if lowest else 'went'} "
            f"{value:.2f} m (expected {'at least' if lowest else 'at most'} "
            f"{limit.value:g} m)",
            round(value, 3),
            row.time_s,
        )

    return judge


def reached(key: str, value: dict[str, float], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    point = (value["north_m"], value["east_m"])
    measure = _from(point)
    rows = _window(trace, value.get("from_s"), value.get("until_s"), measure)
    if not rows:
        return check(key, value, False, "no position in the window", None, None)
    closest = min(rows, key=measure)
    within = value["within_m"]
    first = next((r for r in rows if measure(r) <= within), None)
    if first is not None:
        return check(
            key, value, True, f"within {within:g} m first", round(measure(first), 3), first.time_s
        )
    return check(
        key,
        value,
        False,
        f"came only within {measure(closest):.2f} m",
        round(measure(closest), 3),
        closest.time_s,
    )


def ends_within(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    last = trace.rows[-1]
    off = _from(_origin(limit))(last)
    if not math.isfinite(off):
        return check(key, limit, False, "no position at the end", None, last.time_s)
    state = ("on the ground" if last.on_ground else f"at {last.alt_m:.1f} m") + (
        ", disarmed" if not last.armed else ", armed"
    )
    return check(
        key,
        limit,
        off <= limit.value,
        f"ended {off:.2f} m away ({state}; expected within {limit.value:g} m)",
        round(off, 3),
        last.time_s,
    )


def ground_speeds(rows: list[TraceRow]) -> list[tuple[TraceRow, float]]:
    """(row, horizontal speed over the SPEED_WINDOW_S before it) for each row after the
    first half second."""
    out = []
    start = 0
    for row in rows:
        while rows[start].time_s < row.time_s - SPEED_WINDOW_S:
            start += 1
        first = rows[start]
        span = row.time_s - first.time_s
        if span >= 0.8 * SPEED_WINDOW_S:
            out.append(
                (row, math.hypot(row.north_m - first.north_m, row.east_m - first.east_m) / span)
            )
    return out


def max_ground_speed(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    rows = [r for r in trace.window(limit.from_s, limit.until_s) if math.isfinite(r.north_m)]
    speeds = ground_speeds(rows)
    if not speeds:
        return check(key, limit, False, "no position in the window", None, None)
    row, fastest = max(speeds, key=lambda item: item[1])
    return check(
        key,
        limit,
        fastest <= limit.value,
        f"up to {fastest:.2f} m/s (expected at most {limit.value:g} m/s)",
        round(fastest, 3),
        row.time_s,
    )


def _heading_off(heading: float, wanted: float) -> float:
    return abs((heading - wanted + 180.0) % 360.0 - 180.0)


def heading(key: str, value: dict[str, float], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    rows = [
        r
        for r in trace.window(value.get("from_s"), value.get("until_s"))
        if math.isfinite(r.heading_deg)
    ]
    if not rows:
        return check(key, value, False, "no heading in the window", None, None)
    worst = max(rows, key=lambda r: _heading_off(r.heading_deg, value["value"]))
    off = _heading_off(worst.heading_deg, value["value"])
    return check(
        key,
        value,
        off <= value["within_deg"],
        f"the heading was {worst.heading_deg:.0f} "
        f"deg, {off:.0f} deg off (expected within {value['within_deg']:g})",
        round(worst.heading_deg, 1),
        worst.time_s,
    )


def min_path(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    rows = [r for r in trace.window(limit.from_s, limit.until_s) if math.isfinite(r.north_m)]
    if len(rows) < 2:
        return check(key, limit, False, "no positions in the window", None, None)
    path = sum(
        math.hypot(b.north_m - a.north_m, b.east_m - a.east_m)
        for a, b in zip(rows, rows[1:], strict=False)
    )
    return check(
        key,
        limit,
        path >= limit.value,
        f"flew {path:.1f} m (expected at least {limit.value:g} m)",
        round(path, 2),
        rows[-1].time_s,
    )


def parse_table(
    where: str, key: str, value: Any, allowed: set[str], required: set[str]
) -> dict[str, float]:
    """A ``{ ... }`` value of numbers with the keys ``allowed`` (``required`` among them)."""
    if not isinstance(value, dict):
        raise ScenarioError(
            f"{where}, [expect]: {key} takes a table: "
            f"{{ {', '.join(f'{k} = ...' for k in sorted(required))} }}"
        )
    unknown = set(value) - allowed
    missing = required - set(value)
    if unknown or missing:
        raise ScenarioError(
            f"{where}, [expect]: {key} takes {', '.join(sorted(allowed))} "
            f"({', '.join(sorted(required))} required)"
        )
    for name, number in value.items():
        if (
            isinstance(number, bool)
            or not isinstance(number, (int, float))
            or not math.isfinite(number)
        ):
            raise ScenarioError(f"{where}, [expect]: {key}.{name} = {number!r} must be a number")
    return {name: float(number) for name, number in value.items()}
