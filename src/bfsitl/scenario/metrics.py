"""A scenario run in numbers and in words, for comparing builds (``bfsitl scenario
compare``): the figures a firmware change can move (where it landed, how hard, how tilted,
how soon each failsafe phase came, how well it held, how far and how hard it flew) and the
behaviour it can change (the failsafe's phases, the modes, how it ended, what the analysers
found).

They are read from the analysers' track of the run (the truth, on the trace's clock: seconds
from arming) and the trace (when the faults came), and written to ``result.json``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from bfsitl.analysis.ground_contact import touchdowns
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.series import held_points
from bfsitl.analysis.track import Track
from bfsitl.scenario.trace import Trace, phase_name

if TYPE_CHECKING:
    from bfsitl.analysis import Finding
    from bfsitl.replay.compare import ReplayComparison


@dataclass(frozen=True, slots=True)
class Metric:
    """How a figure is compared between builds."""

    name: str
    unit: str
    #: "lower": less is better; None: neither (a change is a change in behaviour).
    better: str | None
    #: The smallest difference that counts, beyond the seeds' own spread.
    tolerance: float
    description: str


#: Every figure a run gives, in the order they are shown.
METRICS: tuple[Metric, ...] = (
    Metric(
        "landed_distance_m",
        "m",
        "lower",
        1.0,
        "where it came to rest, from the take-off point (None: it did not)",
    ),
    Metric(
        "touchdown_m_s", "m/s", "lower", 0.3, "the hardest ground contact after flying (None: none)"
    ),
    Metric("max_tilt_deg", "deg", "lower", 3.0, "the most tilt in the air"),
    Metric("fault_to_disarm_s", "s", None, 0.3, "from the first fault to the FC disarming"),
    Metric(
        "hold_rms_m",
        "m",
        "lower",
        0.05,
        "position (3-D) off the target in the autopilot's holds, RMS",
    ),
    Metric("path_m", "m", None, 3.0, "the horizontal path flown"),
    Metric(
        "throttle_s",
        "s",
        "lower",
        1.0,
        "the motors' mean command integrated over the armed time: an energy proxy "
        "without a battery model",
    ),
)
#: A replay's figures (``[replay]`` scenarios), per axis: how the replaying quad followed its
#: own setpoint and how far it flew from the real flight.
REPLAY_AXES = ("roll", "pitch", "yaw")
REPLAY_METRICS: tuple[Metric, ...] = (
    *(
        metric
        for axis in REPLAY_AXES
        for metric in (
            Metric(
                f"{axis}_tracking_dps",
                "deg/s",
                "lower",
                1.0,
                f"{axis}: the gyro off the FC's own setpoint, RMS",
            ),
            Metric(
                f"{axis}_overshoot_pct",
                "%",
                "lower",
                2.0,
                f"{axis}: the step response's overshoot (setpoint to gyro)",
            ),
            Metric(f"{axis}_rise_ms", "ms", None, 2.0, f"{axis}: the step response's rise time"),
            Metric(
                f"{axis}_off_real",
                "",
                None,
                0.02,
                f"{axis}: the gyro off the real flight's (RMS of the difference over RMS)",
            ),
        )
    ),
    Metric("motor_mean_pct", "%", "lower", 0.5, "the motors' mean command over the replay"),
)
METRICS = (*METRICS, *REPLAY_METRICS)
#: ``fault_to_PHASE_s`` metrics: one per failsafe phase reached (tolerance 0.3 s).
PHASE_METRIC_TOLERANCE_S = 0.3


@dataclass(slots=True)
class RunMetrics:
    """A run's figures (None: not applicable) and its behaviour in words."""

    values: dict[str, float | None] = field(default_factory=dict)
    #: ``phases``: the failsafe's phases in the order first entered; ``modes``: the flight
    #: modes seen; ``ended``: how it ended; ``findings``: analyser -> severity.
    behaviour: dict[str, list[str]] = field(default_factory=dict)

    def as_dict(self) -> dict[str, object]:
        return {
            "values": {k: (round(v, 4) if v is not None else None) for k, v in self.values.items()},
            "behaviour": self.behaviour,
        }


def metric(name: str) -> Metric:
    """The named metric; ``fault_to_<PHASE>_s`` for any phase."""
    for known in METRICS:
        if known.name == name:
            return known
    if name.startswith("fault_to_") and name.endswith("_s"):
        phase = name[len("fault_to_") : -2]
        return Metric(
            name,
            "s",
            None,
            PHASE_METRIC_TOLERANCE_S,
            f"from the first fault to the failsafe's {phase}",
        )
    raise KeyError(name)


def run_metrics(track: Track, trace: Trace, findings: list[Finding]) -> RunMetrics:
    """The figures and behaviour of a run (``track`` from its FlightWatch, ``trace`` its
    trace)."""
    points = track.points
    out = RunMetrics()
    values = out.values
    last = points[-1] if points else None
    rested = last is not None and last.airborne is False and math.isfinite(last.north_m)
    values["landed_distance_m"] = last.distance_m if rested and last is not None else None
    contacts = touchdowns(track)
    values["touchdown_m_s"] = max((t.speed_m_s for t in contacts), default=None)
    tilts = [p.tilt_deg for p in points if p.airborne and math.isfinite(p.tilt_deg)]
    values["max_tilt_deg"] = max(tilts, default=None)
    fault_s = trace.first_fault_s
    disarm = next(
        (p.time_s for p in points if fault_s is not None and p.time_s >= fault_s and not p.armed),
        None,
    )
    values["fault_to_disarm_s"] = (
        disarm - fault_s if disarm is not None and fault_s is not None else None
    )
    held = _held_errors(track)
    values["hold_rms_m"] = math.sqrt(sum(e * e for e in held) / len(held)) if held else None
    values["path_m"] = _path_m(track)
    values["throttle_s"] = _throttle_s(track)
    phases: list[str] = []
    for point in points:
        if point.failsafe_phase is None or point.failsafe_phase == 0:
            continue
        name = phase_name(point.failsafe_phase)
        if name not in phases:
            phases.append(name)
            if fault_s is not None:
                values[f"fault_to_{name}_s"] = point.time_s - fault_s
    modes = sorted({mode for p in points for mode in p.modes})
    out.behaviour = {
        "phases": phases,
        "modes": modes,
        "ended": [_ending(track)],
        "findings": [f"{f.analyser}:{f.severity.label}" for f in findings],
    }
    return out


def replay_metrics(comparison: ReplayComparison, findings: list[Finding]) -> RunMetrics:
    """A replay's figures (:data:`REPLAY_METRICS`) from its log against the real one, over
    the span they were compared (up to where the real quad lost control)."""
    out = RunMetrics()
    traces = comparison.replay
    span = slice(comparison.replay_start, comparison.replay_start + comparison.samples)
    for index, axis in enumerate(comparison.axes):
        tracking = None
        if traces.setpoint_dps is not None and comparison.samples:
            off = traces.gyro_dps[index, span] - traces.setpoint_dps[index, span]
            tracking = math.sqrt(float(np.mean(off**2)))
        step = axis.replay_step
        out.values[f"{axis.axis}_tracking_dps"] = _finite(tracking)
        # A step response that never rises (an axis that turns the wrong way, one that never
        # reaches 90 %) has no finite figure: None, so a comparison sees that only one side
        # has it.
        out.values[f"{axis.axis}_overshoot_pct"] = _finite(step.overshoot_pct if step else None)
        out.values[f"{axis.axis}_rise_ms"] = _finite(step.rise_time_ms if step else None)
        out.values[f"{axis.axis}_off_real"] = _finite(axis.gyro_error)
    levels = traces.motor_level
    out.values["motor_mean_pct"] = _finite(
        100.0 * float(np.mean(levels[span])) if levels is not None and comparison.samples else None
    )
    out.behaviour = {"findings": [f"{f.analyser}:{f.severity.label}" for f in findings]}
    return out


def _finite(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def _held_errors(track: Track) -> list[float]:
    """The 3-D error in the autopilot's holds (height alone where no position target)."""
    errors: list[float] = []
    for point in held_points(track, Limits().hold_settle_s):
        if not math.isfinite(point.target_alt_m):
            continue
        vertical = point.alt_m - point.target_alt_m
        horizontal = 0.0
        if math.isfinite(point.target_north_m) and math.isfinite(point.north_m):
            horizontal = math.hypot(
                point.north_m - point.target_north_m, point.east_m - point.target_east_m
            )
        errors.append(math.hypot(vertical, horizontal))
    return errors


def _path_m(track: Track) -> float | None:
    placed = [p for p in track.points if math.isfinite(p.north_m) and math.isfinite(p.east_m)]
    if len(placed) < 2:
        return None
    return sum(
        math.hypot(b.north_m - a.north_m, b.east_m - a.east_m)
        for a, b in zip(placed, placed[1:], strict=False)
    )


def _throttle_s(track: Track) -> float | None:
    total, known = 0.0, False
    for a, b in zip(track.points, track.points[1:], strict=False):
        if a.armed and a.motors:
            total += sum(a.motors) / len(a.motors) * (b.time_s - a.time_s)
            known = True
    return total if known else None


def _ending(track: Track) -> str:
    if not track.points:
        return "nothing recorded"
    last = track.points[-1]
    where = "on the ground" if last.airborne is False else "in the air"
    if last.airborne is False and math.isfinite(last.tilt_deg) and last.tilt_deg >= 60.0:
        where = "tipped over on the ground"
    return f"{'armed' if last.armed else 'disarmed'} {where}"
