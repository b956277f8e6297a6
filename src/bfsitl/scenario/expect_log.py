"""Expectations on what the FC's blackbox log shows and what the analysers found (the
table in :mod:`bfsitl.scenario.expectations`)."""

from __future__ import annotations

from typing import Any

from bfsitl.analysis import Severity
from bfsitl.scenario.expect_base import check, name_list
from bfsitl.scenario.expect_flight import phase_sequence
from bfsitl.scenario.result import CheckResult
from bfsitl.scenario.trace import Trace, phase_name


def blackbox_phase(
    key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]
) -> CheckResult:
    if not trace.blackbox:
        return check(key, value, False, "no blackbox log was written or decoded", None, None)
    seen: list[tuple[float, str]] = []
    for log in trace.blackbox:
        start = log.frames[0].time_s if log.frames else 0.0
        seen.extend((t - start, phase_name(int(p))) for t, p in log.phase_changes())
    found, missing = phase_sequence(seen, name_list(value))
    path = " -> ".join(f"{name} ({t:.2f} s)" for t, name in seen) or "none"
    if missing is not None:
        return check(
            key,
            value,
            False,
            f"the blackbox never shows {missing} in order; its phases were {path}",
            seen[-1][1] if seen else None,
            None,
        )
    return check(
        key,
        value,
        True,
        f"the blackbox's phases were {path} (seconds from its first frame)",
        found[-1][1],
        found[-1][0],
    )


def blackbox_link_lost(key: str, value: bool, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    if not trace.blackbox:
        return check(key, value, False, "no blackbox log was written or decoded", None, None)
    for log in trace.blackbox:
        start = log.frames[0].time_s if log.frames else 0.0
        for frame in log.frames:
            if frame.rx_flight_channels_valid is False:
                at = frame.time_s - start
                return check(
                    key,
                    value,
                    value,
                    f"the blackbox shows the flight channels "
                    f"invalid from {at:.2f} s after its first frame (receiver "
                    f"signal {'on' if frame.rx_signal_received else 'lost'})",
                    round(at, 3),
                    None,
                )
    return check(key, value, not value, "the blackbox shows the link valid throughout", None, None)


def blackbox_disarm(key: str, value: str, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    reasons = [
        log.disarm_reason_name for log in trace.blackbox if log.disarm_reason_name is not None
    ]
    if not reasons:
        return check(key, value, False, "no disarm event in the blackbox", None, None)
    return check(
        key,
        value,
        value in reasons,
        f"the blackbox's disarm reason was {', '.join(reasons)}",
        reasons[-1],
        None,
    )


def _found(trace: Trace, name: str) -> str:
    finding = next((f for f in trace.findings if f.analyser == name), None)
    return "nothing" if finding is None else f"{finding.severity.label}: {finding.summary}"


def finding(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    wanted = name_list(value)
    missing = [n for n in wanted if not any(f.analyser == n for f in trace.findings)]
    seen = "; ".join(f"{n}: {_found(trace, n)}" for n in wanted)
    first = next((f for f in trace.findings if f.analyser in wanted), None)
    return check(
        key,
        value,
        not missing,
        (f"{', '.join(missing)} found nothing; " if missing else "") + seen,
        first.severity.label if first else None,
        first.time_s if first else None,
    )


def no_finding(key: str, value: str | list[str], trace: Trace, _e: dict[str, Any]) -> CheckResult:
    found = [f for f in trace.findings if f.analyser in name_list(value)]
    blind = [name for name in name_list(value) if name in trace.unwatched]
    if not found and blind:
        why = "; ".join(f"{name}: {trace.unwatched[name]}" for name in blind)
        return check(key, value, False, f"could not watch this run ({why})", None, None)
    if not found:
        return check(key, value, True, "none of them found anything", None, None)
    return check(
        key,
        value,
        False,
        "; ".join(f"{f.analyser}: {f.severity.label}: {f.summary}" for f in found),
        found[0].severity.label,
        found[0].time_s,
    )


def worst_finding(key: str, value: str, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    allowed = 0 if value == "none" else int(Severity.parse(value))
    worse = [f for f in trace.findings if f.severity > allowed]
    if not worse:
        worst = trace.findings[0].severity.label if trace.findings else "none"
        return check(key, value, True, f"the worst finding was {worst}", worst, None)
    return check(
        key,
        value,
        False,
        f"{worse[0].analyser} found {worse[0].severity.label}: {worse[0].summary}",
        worse[0].severity.label,
        worse[0].time_s,
    )
