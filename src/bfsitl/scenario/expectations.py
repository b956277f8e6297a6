"""Expectations: the ``[expect]`` keys, and how each is judged on a run's trace.

Times are simulation seconds from arming; "the fault" is the first one injected.

=============================  ===============================================================
key = value                    holds when
=============================  ===============================================================
``disarmed = true|false``      the FC is (not) armed at the end
``disarmed_within_s = T``      the FC disarmed within T s of the fault
``failsafe_phase = P | [P..]`` the FC's failsafe went through P (each, in that order; live,
                               from MSP_DEBUG with ``debug_mode = FAILSAFE``)
``failsafe_within_s = T``      ... and reached the first of them within T s of the fault
``failsafe_phase_never = P``   ... and never entered P
``landed_within_m = R``        at the end it rests on the ground, disarmed, within R m
                               (horizontally) of the take-off point
``max_touchdown_m_s = V``      it met the ground at no more than V m/s
``crashed = true|false``       bfsitl's crash detection fired (tipped over, or hit the ground
                               faster than 2.5 m/s) or did not
``mode_seen = M | [M..]``      the FC reported flight mode M (MSP names: FAILSAFE, ANGLE,
                               GPS RESCUE, ...) at some point
``mode_never = M | [M..]``     it never did
``max_tilt_deg = X``           never tilted beyond X deg (default window: the whole run)
``min_alt_m = Y``              never lower than Y m (default window: from reaching the
                               take-off altitude to the fault, or the end)
``max_alt_m = Y``              never higher than Y m (whole run)
``max_distance_m = D``         never further than D m from the take-off point (whole run);
                               this and the keys of where it went (a point reached, where it
                               ended, ground speed, heading, the path): see
                               :mod:`bfsitl.scenario.expect_path`
``blackbox_phase = P | [P..]`` the FC's own blackbox log shows failsafe phase P (each)
``blackbox_disarm_reason = N`` the blackbox's disarm event gives reason N (FAILSAFE, SWITCH,
                               GPS_RESCUE, ...)
``blackbox_link_lost = true``  the blackbox shows the flight channels invalid at some point
                               (``rxFlightChannelsValid``: what the FC made of its receiver)
``finding = A | [A..]``        the analyser(s) A reported something (``crash``,
                               ``motor_saturation``, ...: :mod:`bfsitl.analysis.analysers`)
``no_finding = A | [A..]``     they reported nothing
``worst_finding = S``          no finding is worse than S (``none``, ``info``, ``warning``,
                               ``failure``)
=============================  ===============================================================

Expectations that hold for one firmware generation only go in ``[expect."4.6"]`` or
``[expect.master]`` (a GPS Rescue is the FC's GPS RESCUE mode on 4.6.0, and an autopilot
mission, AUTOPILOT, on master).  The four "never" limits also take a window:
``min_alt_m = { value = 1.5, from_s = 4, until_s = 12 }``.  A failed check's message names the
expectation, the measured value and the time it was measured.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from bfsitl.analysis import ANALYSERS, Severity
from bfsitl.errors import ScenarioError
from bfsitl.mission.loop import CRASH_TILT_DEG, CRASH_TOUCHDOWN_M_S
from bfsitl.scenario import expect_path
from bfsitl.scenario.expect_base import Limit
from bfsitl.scenario.expect_base import check as _check
from bfsitl.scenario.expect_base import shown as _shown
from bfsitl.scenario.result import CheckResult
from bfsitl.scenario.trace import FAILSAFE_PHASES, Trace, TraceRow, phase_name

if TYPE_CHECKING:
    from bfsitl.scenario.spec import Scenario


# -- judging -------------------------------------------------------------------------------------
def _disarmed(key: str, value: bool, trace: Trace, _expect: dict[str, Any]) -> CheckResult:
    last = trace.rows[-1]
    state = "armed" if last.armed else "disarmed"
    return _check(key, value, (not last.armed) == value, f"the FC was {state} at the end",
                  state, last.time_s)


def _first_disarm(trace: Trace, after_s: float) -> TraceRow | None:
    return next((r for r in trace.rows if r.time_s >= after_s and not r.armed), None)


def _disarmed_within(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    fault_s = trace.first_fault_s
    if fault_s is None:
        return _check(key, value, False, "no fault was injected", None, None)
    row = _first_disarm(trace, fault_s)
    if row is None:
        return _check(key, value, False,
                      f"still armed {trace.end_s - fault_s:.2f} s after the fault (the end)",
                      None, trace.end_s)
    after = row.time_s - fault_s
    return _check(key, value, after <= value,
                  f"disarmed {after:.2f} s after the fault (expected within {value:g} s)",
                  round(after, 3), row.time_s)


def _names(value: str | list[str]) -> list[str]:
    return [value] if isinstance(value, str) else list(value)


def _phase_sequence(seen: list[tuple[float, str]], wanted: list[str]
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


def _failsafe_phase(key: str, value: str | list[str], trace: Trace,
                    expect: dict[str, Any]) -> CheckResult:
    seen = _live_phases(trace)
    if not seen:
        return _check(key, value, False, "the FC's failsafe phase was never read (MSP_DEBUG)",
                      None, None)
    found, missing = _phase_sequence(seen, _names(value))
    path = " -> ".join(f"{name} ({t:.2f} s)" for t, name in seen)
    if missing is not None:
        return _check(key, value, False, f"never reached {missing} in order; the phases were "
                      f"{path}", seen[-1][1], None)
    within = expect.get("failsafe_within_s")
    fault_s = trace.first_fault_s
    if within is not None and fault_s is not None:
        first_s = found[0][0]
        after = first_s - fault_s
        return _check(key, value, 0 <= after <= within,
                      f"{found[0][1]} {after:.2f} s after the fault (expected within "
                      f"{within:g} s); the phases were {path}", round(after, 3), first_s)
    return _check(key, value, True, f"the phases were {path}", found[-1][1], found[-1][0])


def _failsafe_never(key: str, value: str | list[str], trace: Trace,
                    _e: dict[str, Any]) -> CheckResult:
    banned = set(_names(value))
    for t, name in _live_phases(trace):
        if name in banned:
            return _check(key, value, False, f"the FC entered {name}", name, t)
    return _check(key, value, True, "never entered", None, None)


def _landed_within(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    last = trace.rows[-1]
    distance = last.distance_m
    if last.armed or not last.on_ground:
        where = "still armed" if last.armed else "not on the ground"
        return _check(key, value, False, f"{where} at the end, {distance:.2f} m from the "
                      f"take-off point", round(distance, 3), last.time_s)
    return _check(key, value, distance <= value,
                  f"landed {distance:.2f} m from the take-off point (expected within "
                  f"{value:g} m)", round(distance, 3), last.time_s)


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


def _max_touchdown(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    touchdowns = _touchdowns(trace)
    if not touchdowns:
        return _check(key, value, False, "it never came down", None, None)
    t, speed = max(touchdowns, key=lambda item: item[1])
    return _check(key, value, speed <= value,
                  f"met the ground at {speed:.2f} m/s (expected at most {value:g} m/s)",
                  round(speed, 3), t)


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


def _crashed(key: str, value: bool, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    crash = crash_of(trace)
    if crash is None:
        return _check(key, value, not value, "no crash: never tipped over, never met the "
                      f"ground faster than {CRASH_TOUCHDOWN_M_S:g} m/s", "no", None)
    t, why = crash
    return _check(key, value, value, f"crashed: {why}", "yes", t)


def _mode_seen(key: str, value: str | list[str], trace: Trace,
               _e: dict[str, Any]) -> CheckResult:
    missing = []
    first: dict[str, float] = {}
    for name in _names(value):
        row = next((r for r in trace.rows if name in r.modes), None)
        if row is None:
            missing.append(name)
        else:
            first[name] = row.time_s
    every = sorted({m for r in trace.rows for m in r.modes})
    if missing:
        return _check(key, value, False, f"never saw {', '.join(missing)} (modes seen: "
                      f"{', '.join(every) or 'none'})", None, None)
    name, at = min(first.items(), key=lambda item: item[1])
    return _check(key, value, True, f"first seen: {name}", name, at)


def _mode_never(key: str, value: str | list[str], trace: Trace,
                _e: dict[str, Any]) -> CheckResult:
    banned = set(_names(value))
    for row in trace.rows:
        hit = banned.intersection(row.modes)
        if hit:
            return _check(key, value, False, f"the FC reported {', '.join(sorted(hit))}",
                          sorted(hit)[0], row.time_s)
    return _check(key, value, True, "never reported", None, None)


def _extreme(measure: Callable[[TraceRow], float], *, lowest: bool, what: str, unit: str,
             default_window: Callable[[Trace], tuple[float | None, float | None]]
             ) -> Callable[[str, Limit, Trace, dict[str, Any]], CheckResult]:
    def judge(key: str, limit: Limit, trace: Trace, _e: dict[str, Any]) -> CheckResult:
        from_s, until_s = limit.from_s, limit.until_s
        if from_s is None and until_s is None:
            from_s, until_s = default_window(trace)
        rows = [r for r in trace.window(from_s, until_s) if math.isfinite(measure(r))]
        if not rows:
            return _check(key, limit, False, "no samples in the window", None, None)
        pick = min if lowest else max
        row = pick(rows, key=measure)
        value = measure(row)
        passed = value >= limit.value if lowest else value <= limit.value
        bound = "at least" if lowest else "at most"
        return _check(key, limit, passed, f"{what} {value:.2f} {unit} (expected {bound} "
                      f"{limit.value:g} {unit})", round(value, 3), row.time_s)
    return judge


def _whole_run(_trace: Trace) -> tuple[float | None, float | None]:
    return None, None


def _in_the_air(trace: Trace) -> tuple[float | None, float | None]:
    start = trace.takeoff_done_s if trace.takeoff_done_s is not None else math.inf
    return start, trace.first_fault_s


def _blackbox_phase(key: str, value: str | list[str], trace: Trace,
                    _e: dict[str, Any]) -> CheckResult:
    if not trace.blackbox:
        return _check(key, value, False, "no blackbox log was written or decoded", None, None)
    seen: list[tuple[float, str]] = []
    for log in trace.blackbox:
        start = log.frames[0].time_s if log.frames else 0.0
        seen.extend((t - start, phase_name(int(p))) for t, p in log.phase_changes())
    found, missing = _phase_sequence(seen, _names(value))
    path = " -> ".join(f"{name} ({t:.2f} s)" for t, name in seen) or "none"
    if missing is not None:
        return _check(key, value, False, f"the blackbox never shows {missing} in order; its "
                      f"phases were {path}", seen[-1][1] if seen else None, None)
    return _check(key, value, True, f"the blackbox's phases were {path} (seconds from its "
                  f"first frame)", found[-1][1], found[-1][0])


def _blackbox_link_lost(key: str, value: bool, trace: Trace,
                        _e: dict[str, Any]) -> CheckResult:
    if not trace.blackbox:
        return _check(key, value, False, "no blackbox log was written or decoded", None, None)
    for log in trace.blackbox:
        start = log.frames[0].time_s if log.frames else 0.0
        for frame in log.frames:
            if frame.rx_flight_channels_valid is False:
                at = frame.time_s - start
                return _check(key, value, value, f"the blackbox shows the flight channels "
                              f"invalid from {at:.2f} s after its first frame (receiver "
                              f"signal {'on' if frame.rx_signal_received else 'lost'})",
                              round(at, 3), None)
    return _check(key, value, not value, "the blackbox shows the link valid throughout",
                  None, None)


def _blackbox_disarm(key: str, value: str, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    reasons = [log.disarm_reason_name for log in trace.blackbox
               if log.disarm_reason_name is not None]
    if not reasons:
        return _check(key, value, False, "no disarm event in the blackbox", None, None)
    return _check(key, value, value in reasons, f"the blackbox's disarm reason was "
                  f"{', '.join(reasons)}", reasons[-1], None)


def _found(trace: Trace, name: str) -> str:
    finding = next((f for f in trace.findings if f.analyser == name), None)
    return "nothing" if finding is None else f"{finding.severity.label}: {finding.summary}"


def _finding(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]
             ) -> CheckResult:
    names = _names(value)
    missing = [n for n in names if not any(f.analyser == n for f in trace.findings)]
    seen = "; ".join(f"{n}: {_found(trace, n)}" for n in names)
    first = next((f for f in trace.findings if f.analyser in names), None)
    return _check(key, value, not missing,
                  (f"{', '.join(missing)} found nothing; " if missing else "") + seen,
                  first.severity.label if first else None, first.time_s if first else None)


def _no_finding(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]
                ) -> CheckResult:
    found = [f for f in trace.findings if f.analyser in _names(value)]
    if not found:
        return _check(key, value, True, "none of them found anything", None, None)
    return _check(key, value, False, "; ".join(f"{f.analyser}: {f.severity.label}: "
                                               f"{f.summary}" for f in found),
                  found[0].severity.label, found[0].time_s)


def _worst_finding(key: str, value: str, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    allowed = 0 if value == "none" else int(Severity.parse(value))
    worse = [f for f in trace.findings if f.severity > allowed]
    if not worse:
        worst = trace.findings[0].severity.label if trace.findings else "none"
        return _check(key, value, True, f"the worst finding was {worst}", worst, None)
    return _check(key, value, False, f"{worse[0].analyser} found {worse[0].severity.label}: "
                  f"{worse[0].summary}", worse[0].severity.label, worse[0].time_s)


_Judge = Callable[[str, Any, Trace, dict[str, Any]], CheckResult]

#: key -> (value kind, judge).  Kinds: "bool", "number", "names", "phases", "limit", "text",
#: "analysers", "severity".
_KEYS: dict[str, tuple[str, _Judge | None]] = {
    "disarmed": ("bool", _disarmed),
    "disarmed_within_s": ("number", _disarmed_within),
    "failsafe_phase": ("phases", _failsafe_phase),
    "failsafe_within_s": ("number", None),  # read by failsafe_phase
    "failsafe_phase_never": ("phases", _failsafe_never),
    "landed_within_m": ("number", _landed_within),
    "max_touchdown_m_s": ("number", _max_touchdown),
    "crashed": ("bool", _crashed),
    "mode_seen": ("names", _mode_seen),
    "mode_never": ("names", _mode_never),
    "max_tilt_deg": ("limit", _extreme(lambda r: r.tilt_deg, lowest=False, what="tilted",
                                       unit="deg", default_window=_whole_run)),
    "min_alt_m": ("limit", _extreme(lambda r: r.alt_m, lowest=True, what="down to",
                                    unit="m", default_window=_in_the_air)),
    "max_alt_m": ("limit", _extreme(lambda r: r.alt_m, lowest=False, what="up to", unit="m",
                                    default_window=_whole_run)),
    "max_distance_m": ("limit", expect_path.distance_bound(lowest=False)),
    "min_distance_m": ("limit", expect_path.distance_bound(lowest=True)),
    "reached": ("point", expect_path.reached),
    "ends_within_m": ("limit", expect_path.ends_within),
    "max_ground_speed_m_s": ("limit", expect_path.max_ground_speed),
    "heading_deg": ("heading", expect_path.heading),
    "min_path_m": ("limit", expect_path.min_path),
    "blackbox_phase": ("phases", _blackbox_phase),
    "blackbox_disarm_reason": ("text", _blackbox_disarm),
    "blackbox_link_lost": ("bool", _blackbox_link_lost),
    "finding": ("analysers", _finding),
    "no_finding": ("analysers", _no_finding),
    "worst_finding": ("severity", _worst_finding),
}
ANALYSER_NAMES = tuple(a.name for a in ANALYSERS)
#: Limits measured from a point (the take-off point unless north_m / east_m say).
_FROM_A_POINT = ("max_distance_m", "min_distance_m", "ends_within_m")
SEVERITY_NAMES = ("none", *(s.label for s in Severity))
EXPECTATION_KEYS = tuple(sorted(_KEYS))


def _parse(where: str, key: str, value: Any) -> Any:
    """The value checked and normalised for its key's kind."""
    kind = _KEYS[key][0]
    bad = ScenarioError(f"{where}, [expect]: {key} = {value!r} is not valid ({kind})")
    if kind == "bool":
        if not isinstance(value, bool):
            raise ScenarioError(f"{where}, [expect]: {key} must be true or false")
        return value
    if kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value < 0:
            raise ScenarioError(f"{where}, [expect]: {key} must be a number >= 0, "
                                f"got {value!r}")
        return float(value)
    if kind == "severity":
        if value not in SEVERITY_NAMES:
            raise ScenarioError(f"{where}, [expect]: {key} = {value!r} is not one of "
                                f"{', '.join(SEVERITY_NAMES)}")
        return value
    if kind == "analysers":
        listed = _names(value) if isinstance(value, (str, list)) else []
        unknown = [n for n in listed if n not in ANALYSER_NAMES]
        if not listed or unknown:
            raise ScenarioError(f"{where}, [expect]: {key}: unknown analyser(s) "
                                f"{', '.join(map(repr, unknown)) or repr(value)}; known: "
                                f"{', '.join(ANALYSER_NAMES)}")
        return value
    if kind in ("names", "phases", "text"):
        names = _names(value) if isinstance(value, (str, list)) else None
        if not names or not all(isinstance(n, str) and n for n in names):
            raise bad
        if kind == "phases":
            unknown = [n for n in names if n not in FAILSAFE_PHASES]
            if unknown:
                raise ScenarioError(f"{where}, [expect]: {key}: unknown phase(s) "
                                    f"{', '.join(unknown)}; phases: "
                                    f"{', '.join(FAILSAFE_PHASES)}")
        if kind == "text" and not isinstance(value, str):
            raise bad
        return value
    if kind == "point":
        return expect_path.parse_table(where, key, value, expect_path.POINT_KEYS,
                                       {"north_m", "east_m", "within_m"})
    if kind == "heading":
        return expect_path.parse_table(where, key, value, expect_path.HEADING_KEYS,
                                       {"value", "within_deg"})
    # limit: a number, or a table with value, an optional window (and for a distance, the
    # point it is measured from)
    if isinstance(value, dict):
        allowed = ["value", "from_s", "until_s", *(("north_m", "east_m") if key in
                                                   _FROM_A_POINT else ())]
        extra = set(value) - set(allowed)
        if extra or "value" not in value:
            raise ScenarioError(f"{where}, [expect]: {key} takes a number or "
                                f"{{ {', '.join(f'{k} = ...' for k in allowed)} }}")
        numbers = [value.get(k) for k in ("value", "from_s", "until_s", "north_m", "east_m")]
        for number in numbers:
            if number is not None and (isinstance(number, bool)
                                       or not isinstance(number, (int, float))
                                       or not math.isfinite(number)):
                raise bad
        return Limit(*(float(n) if n is not None else None for n in numbers))  # type: ignore
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise bad
    return Limit(float(value))


#: ``[expect."4.6"]`` and ``[expect.master]``: what only one firmware generation does.
GENERATION_TABLES = ("4.6", "master")


def parsed_expectations(scenario: Scenario, generation: str | None = None) -> dict[str, Any]:
    """The scenario's ``[expect]`` table, every key known and every value checked; with a
    ``generation``, its own table's keys added (they win over the common ones)."""
    out: dict[str, Any] = {}
    own: dict[str, Any] = {}
    for key, value in scenario.expect:
        if key in GENERATION_TABLES:
            if not isinstance(value, dict):
                raise ScenarioError(f"{scenario.where}, [expect]: {key} must be a table "
                                    f"([expect.\"{key}\"]) of expectations for that firmware")
            for inner, inner_value in value.items():
                checked = _checked(scenario, f"{key}.{inner}", inner, inner_value)
                if key == generation:
                    own[inner] = checked
            continue
        out[key] = _checked(scenario, key, key, value)
    out.update(own)
    if "failsafe_within_s" in out and "failsafe_phase" not in out:
        raise ScenarioError(f"{scenario.where}, [expect]: failsafe_within_s needs "
                            f"failsafe_phase (the phase to reach)")
    needs_fault = {"disarmed_within_s", "failsafe_within_s"} & set(out)
    if needs_fault and not scenario.faults:
        raise ScenarioError(f"{scenario.where}, [expect]: {', '.join(sorted(needs_fault))} "
                            f"count from the first fault, and there is none")
    return out


def _checked(scenario: Scenario, shown: str, key: str, value: Any) -> Any:
    if key not in _KEYS:
        raise ScenarioError(f"{scenario.where}, [expect]: unknown key {shown!r}; known: "
                            f"{', '.join(EXPECTATION_KEYS)} (and the tables "
                            f"{', '.join(GENERATION_TABLES)})")
    return _parse(scenario.where, key, value)


def check_expectations(scenario: Scenario) -> None:
    for generation in (None, *GENERATION_TABLES):
        parsed_expectations(scenario, generation)


def judge(scenario: Scenario, trace: Trace, generation: str | None = None
          ) -> list[CheckResult]:
    """Every expectation of ``scenario`` (and of ``generation``'s own table) judged on
    ``trace``, in the file's order."""
    expect = parsed_expectations(scenario, generation)
    if not trace.rows:
        return [CheckResult(_shown(k, v), False, f"{_shown(k, v)}: nothing was recorded")
                for k, v in expect.items() if _KEYS[k][1] is not None]
    results = []
    for key, value in expect.items():
        judge_key = _KEYS[key][1]
        if judge_key is not None:
            results.append(judge_key(key, value, trace, expect))
    return results
