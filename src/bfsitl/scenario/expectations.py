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

A replay (``[replay]``, :mod:`bfsitl.scenario.replay_spec`) has no trace of the truth: it takes
the blackbox and finding keys above and its own (``replay_targets_met``,
``min_setpoint_correlation``, ``max_gyro_off_real``: :mod:`bfsitl.scenario.expect_replay`).

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
from bfsitl.scenario import expect_flight, expect_log, expect_path, expect_replay
from bfsitl.scenario.expect_base import Limit, name_list
from bfsitl.scenario.expect_base import shown as _shown
from bfsitl.scenario.expect_flight import extreme, in_the_air, whole_run
from bfsitl.scenario.known_failures import judge_known, known_reason
from bfsitl.scenario.result import CheckResult, ScenarioResult, Verdict
from bfsitl.scenario.trace import FAILSAFE_PHASES, Trace

if TYPE_CHECKING:
    from bfsitl.scenario.spec import Scenario


_Judge = Callable[[str, Any, Trace, dict[str, Any]], CheckResult]

#: key -> (value kind, judge).  Kinds: "bool", "number", "names", "phases", "limit", "text",
#: "analysers", "severity".
_KEYS: dict[str, tuple[str, _Judge | None]] = {
    "disarmed": ("bool", expect_flight.disarmed),
    "disarmed_within_s": ("number", expect_flight.disarmed_within),
    "failsafe_phase": ("phases", expect_flight.failsafe_phase),
    "failsafe_within_s": ("number", None),  # read by failsafe_phase
    "failsafe_phase_never": ("phases", expect_flight.failsafe_never),
    "landed_within_m": ("number", expect_flight.landed_within),
    "max_touchdown_m_s": ("number", expect_flight.max_touchdown),
    "crashed": ("bool", expect_flight.crashed),
    "mode_seen": ("names", expect_flight.mode_seen),
    "mode_never": ("names", expect_flight.mode_never),
    "max_tilt_deg": (
        "limit",
        extreme(
            lambda r: r.tilt_deg, lowest=False, what="tilted", unit="deg", default_window=whole_run
        ),
    ),
    "min_alt_m": (
        "limit",
        extreme(
            lambda r: r.alt_m, lowest=True, what="down to", unit="m", default_window=in_the_air
        ),
    ),
    "max_alt_m": (
        "limit",
        extreme(lambda r: r.alt_m, lowest=False, what="up to", unit="m", default_window=whole_run),
    ),
    "max_distance_m": ("limit", expect_path.distance_bound(lowest=False)),
    "min_distance_m": ("limit", expect_path.distance_bound(lowest=True)),
    "reached": ("point", expect_path.reached),
    "ends_within_m": ("limit", expect_path.ends_within),
    "max_ground_speed_m_s": ("limit", expect_path.max_ground_speed),
    "heading_deg": ("heading", expect_path.heading),
    "min_path_m": ("limit", expect_path.min_path),
    "blackbox_phase": ("phases", expect_log.blackbox_phase),
    "blackbox_disarm_reason": ("text", expect_log.blackbox_disarm),
    "blackbox_link_lost": ("bool", expect_log.blackbox_link_lost),
    "finding": ("analysers", expect_log.finding),
    "no_finding": ("analysers", expect_log.no_finding),
    "worst_finding": ("severity", expect_log.worst_finding),
    "replay_targets_met": ("bool", expect_replay.replay_targets),
    "min_setpoint_correlation": ("number", expect_replay.min_setpoint_correlation),
    "max_gyro_off_real": ("number", expect_replay.max_gyro_off_real),
}
#: What a replay is judged by: the FC's log, the analysers, how it compared with the real
#: flight.  The replay's own keys go with a replay only.
REPLAY_ONLY_KEYS = frozenset(
    {"replay_targets_met", "min_setpoint_correlation", "max_gyro_off_real"}
)
REPLAY_KEYS = REPLAY_ONLY_KEYS | {
    "blackbox_phase",
    "blackbox_disarm_reason",
    "blackbox_link_lost",
    "finding",
    "no_finding",
    "worst_finding",
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
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
            or value < 0
        ):
            raise ScenarioError(f"{where}, [expect]: {key} must be a number >= 0, got {value!r}")
        return float(value)
    if kind == "severity":
        if value not in SEVERITY_NAMES:
            raise ScenarioError(
                f"{where}, [expect]: {key} = {value!r} is not one of {', '.join(SEVERITY_NAMES)}"
            )
        return value
    if kind == "analysers":
        listed = name_list(value) if isinstance(value, (str, list)) else []
        unknown = [n for n in listed if n not in ANALYSER_NAMES]
        if not listed or unknown:
            raise ScenarioError(
                f"{where}, [expect]: {key}: unknown analyser(s) "
                f"{', '.join(map(repr, unknown)) or repr(value)}; known: "
                f"{', '.join(ANALYSER_NAMES)}"
            )
        return value
    if kind in ("names", "phases", "text"):
        names = name_list(value) if isinstance(value, (str, list)) else None
        if not names or not all(isinstance(n, str) and n for n in names):
            raise bad
        if kind == "phases":
            unknown = [n for n in names if n not in FAILSAFE_PHASES]
            if unknown:
                raise ScenarioError(
                    f"{where}, [expect]: {key}: unknown phase(s) "
                    f"{', '.join(unknown)}; phases: "
                    f"{', '.join(FAILSAFE_PHASES)}"
                )
        if kind == "text" and not isinstance(value, str):
            raise bad
        return value
    if kind == "point":
        return expect_path.parse_table(
            where, key, value, expect_path.POINT_KEYS, {"north_m", "east_m", "within_m"}
        )
    if kind == "heading":
        return expect_path.parse_table(
            where, key, value, expect_path.HEADING_KEYS, {"value", "within_deg"}
        )
    # limit: a number, or a table with value, an optional window (and for a distance, the
    # point it is measured from)
    if isinstance(value, dict):
        allowed = [
            "value",
            "from_s",
            "until_s",
            *(("north_m", "east_m") if key in _FROM_A_POINT else ()),
        ]
        extra = set(value) - set(allowed)
        if extra or "value" not in value:
            raise ScenarioError(
                f"{where}, [expect]: {key} takes a number or "
                f"{{ {', '.join(f'{k} = ...' for k in allowed)} }}"
            )
        numbers = [value.get(k) for k in ("value", "from_s", "until_s", "north_m", "east_m")]
        for number in numbers:
            if number is not None and (
                isinstance(number, bool)
                or not isinstance(number, (int, float))
                or not math.isfinite(number)
            ):
                raise bad
        return Limit(*(float(n) if n is not None else None for n in numbers))  # type: ignore
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
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
                raise ScenarioError(
                    f"{scenario.where}, [expect]: {key} must be a table "
                    f'([expect."{key}"]) of expectations for that firmware'
                )
            for inner, inner_value in value.items():
                checked = _checked(scenario, f"{key}.{inner}", inner, inner_value)
                if key == generation:
                    own[inner] = checked
            continue
        out[key] = _checked(scenario, key, key, value)
    out.update(own)
    if "failsafe_within_s" in out and "failsafe_phase" not in out:
        raise ScenarioError(
            f"{scenario.where}, [expect]: failsafe_within_s needs "
            f"failsafe_phase (the phase to reach)"
        )
    needs_fault = {"disarmed_within_s", "failsafe_within_s"} & set(out)
    if needs_fault and not scenario.faults:
        raise ScenarioError(
            f"{scenario.where}, [expect]: {', '.join(sorted(needs_fault))} "
            f"count from the first fault, and there is none"
        )
    return out


def _checked(scenario: Scenario, shown: str, key: str, value: Any) -> Any:
    if key not in _KEYS:
        raise ScenarioError(
            f"{scenario.where}, [expect]: unknown key {shown!r}; known: "
            f"{', '.join(EXPECTATION_KEYS)} (and the tables "
            f"{', '.join(GENERATION_TABLES)})"
        )
    if scenario.replay is not None and key not in REPLAY_KEYS:
        raise ScenarioError(
            f"{scenario.where}, [expect]: {shown} is about a flight bfsitl flies; a replay "
            f"is judged by {', '.join(sorted(REPLAY_KEYS))}"
        )
    if scenario.replay is None and key in REPLAY_ONLY_KEYS:
        raise ScenarioError(
            f"{scenario.where}, [expect]: {shown} compares a replay with the real flight; "
            "it needs a [replay] table"
        )
    return _parse(scenario.where, key, value)


def check_expectations(scenario: Scenario) -> None:
    for generation in (None, *GENERATION_TABLES):
        parsed_expectations(scenario, generation)


def judge(scenario: Scenario, trace: Trace, generation: str | None = None) -> list[CheckResult]:
    """Every expectation of ``scenario`` (and of ``generation``'s own table) judged on
    ``trace``, in the file's order."""
    expect = parsed_expectations(scenario, generation)
    if not trace.rows and trace.replay is None:
        return [
            CheckResult(_shown(k, v), False, f"{_shown(k, v)}: nothing was recorded")
            for k, v in expect.items()
            if _KEYS[k][1] is not None
        ]
    results = []
    for key, value in expect.items():
        judge_key = _KEYS[key][1]
        if judge_key is not None:
            results.append(judge_key(key, value, trace, expect))
    return results


def settle_verdict(
    result: ScenarioResult, scenario: Scenario, trace: Trace, generation: str
) -> None:
    """``result``'s checks, verdict and reason: the expectations judged on ``trace``, then
    the known failures on the findings (a known defect that happened, with every expectation
    met, is a known failure, never a pass)."""
    checks = judge(scenario, trace, generation)
    known_checks, happened = judge_known(scenario.known_failures, generation, result.findings)
    result.checks = checks + known_checks
    failed = [c for c in result.checks if not c.passed]
    if failed:
        result.verdict, result.reason = Verdict.FAILED, failed[0].message
    elif happened:
        result.verdict, result.reason = Verdict.KNOWN, known_reason(happened)
    else:
        result.verdict = Verdict.PASSED
        result.reason = f"all {len(checks)} expectations met"
