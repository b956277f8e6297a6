"""Expectations on how the flight went: disarms, the failsafe's phases, touchdowns and
crashes, flight modes, and the limits on tilt and height (the table in
:mod:`bfsitl.scenario.expectations`).  Each judge takes the key, its parsed value, the trace and
the whole ``[expect]`` table."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from bfsitl.mission.crash_check import CRASH_TILT_DEG, CRASH_TOUCHDOWN_M_S
from bfsitl.scenario.expect_base import Limit, check, name_list
from bfsitl.scenario.result import CheckResult
from bfsitl.scenario.trace import Trace, TraceRow, phase_name


def disarmed(key: str, value: bool, trace: Trace, _expect: dict[str, Any]) -> CheckResult:
    last = trace.rows[-1]
    state = "armed" if last.armed else "disarmed"
    return check(
        key, value, (not last.armed) == value, f"the FC was {state} at the end", state, last.time_s
    )


def _first_disarm(trace: Trace, after_s: float) -> TraceRow | None:
    return next((r for r in trace.rows if r.time_s >= after_s and not r.armed), None)


def disarmed_within(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    fault_s = trace.first_fault_s
    if fault_s is None:
        return check(key, value, False, "no fault was injected", None, None)
    row = _first_disarm(trace, fault_s)
    if row is None:
        return check(
            key,
            value,
            False,
            f"still armed {trace.end_s - fault_s:.2f} s after the fault (the end)",
            None,
            trace.end_s,
        )
    after = row.time_s - fault_s
    return check(
        key,
        value,
        after <= value,
        f"disarmed {after:.2f} s after the fault (expected within {value:g} s)",
        round(after, 3),
        row.time_s,
    )


def phase_sequence(
    seen: list[tuple[float, str]], wanted: list[str]
) -> tuple[list[tuple[float, str]], str | None]:
    """The times the wanted phases were reached, in order; the first missing one."""
    found: list[tuple[float, str]] = []
    start = 0
    for name in wanted:
        index = next((i for i in range(start, len(seen)) if seen[i][1] == name), None)
        if index is None:
            return found, name
        found.append(seen[index])
        start = index
    return found, None


def _live_phases(trace: Trace) -> list[tuple[float, str]]:
    changes: list[tuple[float, str]] = []
    for row in trace.rows:
        if row.failsafe_phase is None:
            continue
        name = phase_name(row.failsafe_phase)
        if not changes or changes[-1][1] != name:
            changes.append((row.time_s, name))
    return changes


def failsafe_phase(
    key: str, value: str | list[str], trace: Trace, expect: dict[str, Any]
) -> CheckResult:
    seen = _live_phases(trace)
    if not seen:
        return check(
            key, value, False, "the FC's failsafe phase was never read (MSP_DEBUG)", None, None
        )
    found, missing = phase_sequence(seen, name_list(value))
    path = " -> ".join(f"{name} ({t:.2f} s)" for t, name in seen)
    if missing is not None:
        return check(
            key,
            value,
            False,
            f"never reached {missing} in order; the phases were {path}",
            seen[-1][1],
            None,
        )
    within = expect.get("failsafe_within_s")
    fault_s = trace.first_fault_s
    if within is not None and fault_s is not None:
        first_s = found[0][0]
        after = first_s - fault_s
        return check(
            key,
            value,
            0 <= after <= within,
            f"{found[0][1]} {after:.2f} s after the fault (expected within "
            f"{within:g} s); the phases were {path}",
            round(after, 3),
            first_s,
        )
    return check(key, value, True, f"the phases were {path}", found[-1][1], found[-1][0])


def failsafe_never(
    key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]
) -> CheckResult:
    banned = set(name_list(value))
    for t, name in _live_phases(trace):
        if name in banned:
            return check(key, value, False, f"the FC entered {name}", name, t)
    return check(key, value, True, "never entered", None, None)


def landed_within(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    last = trace.rows[-1]
    distance = last.distance_m
    if last.armed or not last.on_ground:
        where = "still armed" if last.armed else "not on the ground"
        return check(
            key,
            value,
            False,
            f"{where} at the end, {distance:.2f} m from the take-off point",
            round(distance, 3),
            last.time_s,
        )
    return check(
        key,
        value,
        distance <= value,
        f"landed {distance:.2f} m from the take-off point (expected within {value:g} m)",
        round(distance, 3),
        last.time_s,
    )


def _touchdowns(trace: Trace) -> list[tuple[float, float]]:
    """(time, downward speed) of each arrival on the ground after having been airborne."""
    out: list[tuple[float, float]] = []
    airborne = False
    previous: TraceRow | None = None
    for row in trace.rows:
        if not row.on_ground and row.alt_m > 0.3:
            airborne = True
        elif row.on_ground and airborne:
            speed = -min(row.climb_m_s, previous.climb_m_s if previous else 0.0)
            out.append((row.time_s, max(0.0, speed)))
            airborne = False
        previous = row
    return out


def max_touchdown(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    touchdowns = _touchdowns(trace)
    if not touchdowns:
        return check(key, value, False, "it never came down", None, None)
    t, speed = max(touchdowns, key=lambda item: item[1])
    return check(
        key,
        value,
        speed <= value,
        f"met the ground at {speed:.2f} m/s (expected at most {value:g} m/s)",
        round(speed, 3),
        t,
    )


def crash_of(trace: Trace) -> tuple[float, str] | None:
    """The first crash: the autopilot's own detection, or (once nobody flies) the same
    rules on the truth: tipped over, or met the ground too fast."""
    if trace.crash is not None:
        return trace.crash
    for row in trace.rows:
        if row.tilt_deg > CRASH_TILT_DEG:
            return row.time_s, f"tipped over ({row.tilt_deg:.0f} deg from level)"
    for t, speed in _touchdowns(trace):
        if speed > CRASH_TOUCHDOWN_M_S:
            return t, f"hit the ground at {speed:.1f} m/s"
    return None


def crashed(key: str, value: bool, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    crash = crash_of(trace)
    if crash is None:
        return check(
            key,
            value,
            not value,
            "no crash: never tipped over, never met the "
            f"ground faster than {CRASH_TOUCHDOWN_M_S:g} m/s",
            "no",
            None,
        )
    t, why = crash
    return check(key, value, value, f"crashed: {why}", "yes", t)


def mode_seen(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    missing = []
    first: dict[str, float] = {}
    for name in name_list(value):
        row = next((r for r in trace.rows if name in r.modes), None)
        if row is None:
            missing.append(name)
        else:
            first[name] = row.time_s
    every = sorted({m for r in trace.rows for m in r.modes})
    if missing:
        return check(
            key,
            value,
            False,
            f"never saw {', '.join(missing)} (modes seen: {', '.join(every) or 'none'})",
            None,
            None,
        )
    name, at = min(first.items(), key=lambda item: item[1])
    return check(key, value, True, f"first seen: {name}", name, at)


def mode_never(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    banned = set(name_list(value))
    for row in trace.rows:
        hit = banned.intersection(row.modes)
        if hit:
            return check(
                key,
                value,
                False,
                f"the FC reported {', '.join(sorted(hit))}",
                sorted(hit)[0],
                row.time_s,
            )
    return check(key, value, True, "never reported", None, None)


def extreme(
    measure: Callable[[TraceRow], float],
    *,
    lowest: bool,
    what: str,
    unit: str,
    default_window: Callable[[Trace], tuple[float | None, float | None]],
) -> Callable[[str, Limit, Trace, dict[str, Any]], CheckResult]:
    def judge(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
        from_s, until_s = limit.from_s, limit.until_s
        if from_s is None and until_s is None:
            from_s, until_s = default_window(trace)
        rows = [r for r in trace.window(from_s, until_s) if math.isfinite(measure(r))]
        if not rows:
            return check(key, limit, False, "no samples in the window", None, None)
        pick = min if lowest else max
        row = pick(rows, key=measure)
        value = measure(row)
        passed = value >= limit.value if lowest else value <= limit.value
        bound = "at least" if lowest else "at most"
        return check(
            key,
            limit,
            passed,
            f"{what} {value:.2f} {unit} (expected {bound} {limit.value:g} {unit})",
            round(value, 3),
            row.time_s,
        )

    return judge


def whole_run(_trace: Trace) -> tuple[float | None, float | None]:
    return None, None


def in_the_air(trace: Trace) -> tuple[float | None, float | None]:
    start = trace.takeoff_done_s if trace.takeoff_done_s is not None else math.inf
    return start, trace.first_fault_s
