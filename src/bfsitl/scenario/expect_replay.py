"""Expectations on how a replay compared with the real flight (``[replay]`` scenarios; the
table in :mod:`bfsitl.scenario.expectations`).

=================================  ==========================================================
key = value                        holds when
=================================  ==========================================================
``replay_targets_met = true``      every measurable target of ``bfsitl log replay`` is met
                                   (setpoint r >= 0.99, rise time within 20 %, overshoot
                                   within 5 points, on each axis) or, with false, one is not
``min_setpoint_correlation = R``   every axis' setpoint follows the real one's with a
                                   correlation of at least R (the log must hold setpoints)
``max_gyro_off_real = E``          every axis' gyro is off the real flight's by at most E
                                   (RMS of the difference over RMS of the real gyro)
=================================  ==========================================================
"""

from __future__ import annotations

import math
from typing import Any

from bfsitl.replay.replay_report import axis_targets, targets_met
from bfsitl.scenario.expect_base import check
from bfsitl.scenario.result import CheckResult
from bfsitl.scenario.trace import Trace

NOT_A_REPLAY = "this run replayed no log"


def replay_targets(key: str, value: bool, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    comparison = trace.replay
    if comparison is None:
        return check(key, value, False, NOT_A_REPLAY, None, None)
    met = targets_met(comparison)
    if met is None:
        said = "no target could be measured (the log holds no setpoints)"
        return check(key, value, False, said, None, None)
    missed = [
        f"{axis.axis} {name}"
        for axis in comparison.axes
        for name, verdict in axis_targets(axis).items()
        if verdict is False
    ]
    said = "every target met" if met else f"missed: {', '.join(missed)}"
    return check(key, value, met == value, said, str(met).lower(), None)


def min_setpoint_correlation(
    key: str, value: float, trace: Trace, _e: dict[str, Any]
) -> CheckResult:
    comparison = trace.replay
    if comparison is None:
        return check(key, value, False, NOT_A_REPLAY, None, None)
    held = [axis for axis in comparison.axes if axis.setpoint_correlation is not None]
    if not held:
        return check(key, value, False, "the log holds no setpoints to compare", None, None)
    # A setpoint that never moved has no correlation (NaN): that axis cannot be judged, and
    # says so rather than passing or failing by the order of the axes.
    flat = [axis.axis for axis in held if math.isnan(axis.setpoint_correlation or 0.0)]
    measured = [(axis.setpoint_correlation or 0.0, axis.axis) for axis in held]
    measured = [(r, name) for r, name in measured if not math.isnan(r)]
    unjudged = f"; {', '.join(flat)} never moved (not judged)" if flat else ""
    if not measured:
        return check(key, value, False, f"no setpoint moved{unjudged}", None, None)
    worst, axis = min(measured)
    said = f"the lowest is {worst:.4f} ({axis}){unjudged}"
    return check(key, value, worst >= value, said, round(worst, 4), None)


def max_gyro_off_real(key: str, value: float, trace: Trace, _e: dict[str, Any]) -> CheckResult:
    comparison = trace.replay
    if comparison is None:
        return check(key, value, False, NOT_A_REPLAY, None, None)
    worst, axis = max((axis.gyro_error, axis.axis) for axis in comparison.axes)
    return check(
        key, value, worst <= value, f"the largest is {worst:.3f} ({axis})", round(worst, 3), None
    )
