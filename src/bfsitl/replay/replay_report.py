"""A replay's report: a JSON of every figure (the log, what flew it, the settings carried and
not, the comparison per axis against the targets) and a PNG of the two flights overlaid with
their step responses side by side.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from bfsitl.atomic_file import write_atomically
from bfsitl.replay.compare import AXES, AxisComparison, ReplayComparison
from bfsitl.replay.replay_log import Replay
from bfsitl.replay.step_response import StepResponse
from bfsitl.replay.sticks import IDENTITY_RC_LINES

#: The targets a replay is held to (issue "your quad in the simulator"): the setpoints agree,
#: and each axis rises and overshoots as the real quad did.
MIN_SETPOINT_CORRELATION = 0.99
MAX_RISE_TIME_DIFFERENCE = 0.20
MAX_OVERSHOOT_DIFFERENCE_PCT = 5.0


def axis_targets(axis: AxisComparison) -> dict[str, bool | None]:
    """Each target met (True), missed (False) or not measurable (None: nothing logged).  A
    real step response the replay has none of (its gyro never followed its setpoint) misses
    both step targets."""
    correlation = axis.setpoint_correlation
    if axis.real_step is not None and axis.replay_step is None:
        return {
            "setpoint": None if correlation is None else correlation >= MIN_SETPOINT_CORRELATION,
            "rise_time": False,
            "overshoot": False,
        }
    rise, overshoot = axis.rise_time_ratio, axis.overshoot_difference_pct
    return {
        "setpoint": None
        if correlation is None or math.isnan(correlation)
        else correlation >= MIN_SETPOINT_CORRELATION,
        "rise_time": None if rise is None else abs(rise - 1.0) <= MAX_RISE_TIME_DIFFERENCE,
        "overshoot": None if overshoot is None else abs(overshoot) <= MAX_OVERSHOOT_DIFFERENCE_PCT,
    }


def targets_met(comparison: ReplayComparison) -> bool | None:
    """All measurable targets met on every axis; None when none could be measured."""
    verdicts = [v for axis in comparison.axes for v in axis_targets(axis).values() if v is not None]
    return all(verdicts) if verdicts else None


def _number(value: float | None, digits: int = 4) -> float | None:
    if value is None or not math.isfinite(value):
        return None
    return round(float(value), digits)


def _step(step: StepResponse | None) -> dict[str, Any] | None:
    if step is None:
        return None
    return {
        "rise_time_ms": _number(step.rise_time_ms, 2),
        "overshoot_pct": _number(step.overshoot_pct, 2),
        "settling_time_ms": _number(step.settling_time_ms, 2),
        "steady_level": _number(step.steady_level, 3),
        "windows": step.windows,
    }


def report_dict(replay: Replay) -> dict[str, Any]:
    log, flight, comparison, stream = replay.log, replay.flight, replay.comparison, replay.stream
    return {
        "log": {
            "file": log.path.name,
            "index": log.index,
            "firmware": log.firmware_revision,
            "craft": log.headers.get("Craft name", "").strip(),
            "duration_s": _number(log.duration_s, 3),
        },
        "replay": {
            "firmware": flight.firmware,
            "vehicle": replay.vehicle,
            "frames_sent": flight.frames_sent,
            "frame_interval_ms": _number(stream.frame_interval_s * 1000, 3),
            "frame_interval_from": stream.interval_source,
            "fc_counted_frames_as_sent": flight.receiver_frames,
            "deflection_scale": _number(stream.deflection_scale, 5),
            "flown_s": _number(flight.flown_s, 3),
            "wall_s": _number(flight.wall_s, 3),
            "blackbox": flight.blackbox.name,
        },
        "settings": {
            "carried": [
                {"header": c.header, "value": c.value, "cli": list(c.cli_lines)}
                for c in replay.settings.carried
            ],
            "not_carried": [
                {"header": n.header, "value": n.value, "why": n.why}
                for n in replay.settings.not_carried
            ],
            "stick_path": list(IDENTITY_RC_LINES),
        },
        "comparison": comparison_dict(comparison),
        "targets": {
            "min_setpoint_correlation": MIN_SETPOINT_CORRELATION,
            "max_rise_time_difference": MAX_RISE_TIME_DIFFERENCE,
            "max_overshoot_difference_pct": MAX_OVERSHOOT_DIFFERENCE_PCT,
            "met": targets_met(comparison),
        },
    }


def comparison_dict(comparison: ReplayComparison) -> dict[str, Any]:
    """The per-axis figures of one comparison (a replay against the real flight, or two
    replays against each other)."""
    return {
        "offset_s": _number(comparison.offset_s, 4),
        "overlap_s": _number(comparison.overlap_s, 3),
        "rate_hz": _number(comparison.rate_hz, 1),
        "real_lost_control_s": _number(comparison.lost_control_s, 3),
        "axes": {
            axis.axis: {
                "setpoint_correlation": _number(axis.setpoint_correlation),
                "setpoint_rms_ratio": _number(axis.setpoint_rms_ratio),
                "gyro_correlation": _number(axis.gyro_correlation),
                "gyro_error": _number(axis.gyro_error),
                "real_step": _step(axis.real_step),
                "replay_step": _step(axis.replay_step),
                "rise_time_ratio": _number(axis.rise_time_ratio),
                "overshoot_difference_pct": _number(axis.overshoot_difference_pct, 2),
                "targets": axis_targets(axis),
            }
            for axis in comparison.axes
        },
        "motor_correlation": _number(comparison.motor_correlation),
        "motor_level_difference_pct": _number(comparison.motor_level_difference_pct, 2),
    }


def write_report_json(replay: Replay, path: Path) -> None:
    write_atomically(path, (json.dumps(report_dict(replay), indent=2) + "\n").encode())


def write_report_png(
    replay: Replay,
    path: Path,
    *,
    labels: tuple[str, str] = ("real", "replay"),
    title: str | None = None,
) -> None:
    """Per axis, the real flight's setpoint and gyro against the replay's on one time base
    (the real log's), with both step responses beside them; the mean motor command below."""
    write_comparison_png(
        replay.comparison,
        path,
        labels=labels,
        title=title
        or f"{replay.log.path.name} log {replay.log.index} ({replay.log.firmware_revision}) "
        f"replayed on {replay.flight.firmware} with {replay.vehicle}",
    )


def write_comparison_png(
    comparison: ReplayComparison, path: Path, *, labels: tuple[str, str], title: str
) -> None:
    """Two logs compared (:func:`~bfsitl.replay.compare.compare_logs`: a real flight and its
    replay, or two replays A and B), drawn as :func:`write_report_png` says."""
    from bfsitl.headless_pyplot import load_pyplot

    plt = load_pyplot()
    real, sim = comparison.real, comparison.replay
    a = slice(comparison.real_start, comparison.real_start + comparison.samples)
    b = slice(comparison.replay_start, comparison.replay_start + comparison.samples)
    time_s = real.time_s[a]
    fig, grid = plt.subplots(
        4, 2, figsize=(13, 10), gridspec_kw={"width_ratios": [3, 1]}, squeeze=False
    )
    for row, axis in enumerate(comparison.axes):
        trace = grid[row][0]
        if real.setpoint_dps is not None:
            trace.plot(
                time_s, real.setpoint_dps[row, a], color="0.6", lw=0.8, label=f"{labels[0]} set"
            )
        if sim.setpoint_dps is not None:
            trace.plot(
                time_s, sim.setpoint_dps[row, b], color="tab:orange", lw=0.8, ls="--",
                label=f"{labels[1]} set",
            )  # fmt: skip
        trace.plot(time_s, real.gyro_dps[row, a], color="black", lw=0.8, label=f"{labels[0]} gyro")
        trace.plot(time_s, sim.gyro_dps[row, b], color="tab:red", lw=0.8, label=f"{labels[1]} gyro")
        trace.set_ylabel(f"{AXES[row]} deg/s")
        trace.set_title(_axis_title(axis), fontsize=9, loc="left")
        steps = grid[row][1]
        for step, color, label in (
            (axis.real_step, "black", labels[0]),
            (axis.replay_step, "tab:red", labels[1]),
        ):
            if step is not None:
                steps.plot(step.time_s * 1000, step.response, color=color, lw=1, label=label)
        steps.axhline(1.0, color="0.8", lw=0.8)
        steps.set_title(f"{AXES[row]} step response", fontsize=9, loc="left")
    grid[0][0].legend(loc="upper right", fontsize=7, ncol=4)
    grid[0][1].legend(loc="lower right", fontsize=7)
    motors = grid[3][0]
    if real.motor_level is not None:
        motors.plot(time_s, 100 * real.motor_level[a], color="black", lw=0.8, label=labels[0])
    if sim.motor_level is not None:
        motors.plot(time_s, 100 * sim.motor_level[b], color="tab:red", lw=0.8, label=labels[1])
    motors.set_ylabel("mean motor %")
    motors.set_xlabel(
        f"{labels[0]} log time, s ({labels[1]} aligned by {comparison.offset_s:+.3f} s)"
    )
    motors.legend(loc="upper right", fontsize=7)
    grid[3][1].set_axis_off()
    grid[2][1].set_xlabel("ms")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _axis_title(axis: AxisComparison) -> str:
    parts = []
    if axis.setpoint_correlation is not None:
        parts.append(f"setpoint r {axis.setpoint_correlation:.3f}")
    parts.append(f"gyro r {axis.gyro_correlation:.2f}, error {axis.gyro_error:.2f}")
    if axis.real_step is not None and axis.replay_step is not None:
        parts.append(
            f"rise {axis.real_step.rise_time_ms:.0f} -> {axis.replay_step.rise_time_ms:.0f} ms, "
            f"overshoot {axis.real_step.overshoot_pct:.0f} -> "
            f"{axis.replay_step.overshoot_pct:.0f} %"
        )
    return f"{axis.axis}: " + "; ".join(parts)


def write_ab_report_json(
    a: Replay, b: Replay, b_against_a: ReplayComparison, sides: dict[str, Any], path: Path
) -> None:
    """Two replays of one log (A, B: another build or other settings) and B against A."""
    report = {
        "log": report_dict(a)["log"],
        **{
            name: {
                **sides[name],
                "firmware": side.flight.firmware,
                "fc_counted_frames_as_sent": side.flight.receiver_frames,
                "targets_met": targets_met(side.comparison),
            }
            for name, side in (("a", a), ("b", b))
        },
        "b_against_a": comparison_dict(b_against_a),
    }
    write_atomically(path, (json.dumps(report, indent=2) + "\n").encode())
