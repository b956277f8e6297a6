"""The fit's report: a JSON of every figure (fitted values with their uncertainty, the scores
against the shipped profiles and "hold") and a PNG of the replayed traces on windows the fit
did not see.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from bfsitl.atomic_file import write_atomically
from bfsitl.fit.fit_log import LogFit
from bfsitl.fit.replay import SCORE_CUTOFF_HZ
from bfsitl.fit.rotation import AXES, AxisFit
from bfsitl.fit.windows import TRAIN_SHARE, WINDOW_S

#: The fitted profile is trusted when it replays roll and pitch at most this share of "hold"'s
#: error: a model that predicts barely better than no change has not found the quad.
TRUSTED_SHARE_OF_HOLD = 0.5
#: How many of the scored windows the plot shows.
PLOTTED_WINDOWS = 8


def trusted(fit: LogFit) -> bool:
    """Whether the fitted profile replays roll and pitch well enough to be used (see
    :data:`TRUSTED_SHARE_OF_HOLD`)."""
    return all(
        fit.fitted.rates[axis] <= TRUSTED_SHARE_OF_HOLD * fit.hold.rates[axis] for axis in (0, 1)
    )


def _axis(axis: AxisFit) -> dict[str, Any]:
    return {
        "effectiveness_rad_s2": axis.effectiveness.as_dict(),
        "offset_per_thrust_rad_s2": axis.offset_per_thrust,
        "damping_per_s": axis.damping_per_s,
        "trim_rad_s2": axis.trim_rad_s2,
        "coupling": axis.coupling,
        "spin_up_rad_s": axis.spin_up,
    }


def _number(value: float) -> float | None:
    return value if math.isfinite(value) else None


def report_dict(fit: LogFit, profile_path: Path | None) -> dict[str, Any]:
    """Every figure of the fit, as JSON-ready values."""
    data = fit.data
    rotation, thrust = fit.rotation, fit.thrust
    closest_name, closest = fit.closest_shipped
    return {
        "log": data.label,
        "firmware": data.firmware,
        "craft": data.craft,
        "log_interval_ms": data.dt_s * 1000.0,
        "usable_s": data.usable_s,
        "gaps_s": data.gaps_s,
        "window_s": WINDOW_S,
        "train_share": TRAIN_SHARE,
        "train_windows": len(fit.train_windows),
        "test_windows": len(fit.test_windows),
        "base_profile": fit.base.name,
        "profile": str(profile_path) if profile_path else None,
        "trusted": trusted(fit),
        "fitted": {
            "motor_time_constant_ms": rotation.time_constant_s * 1000.0,
            "gyro_delay_ms": rotation.delay_s * 1000.0,
            "thrust_to_weight": thrust.thrust_to_weight.as_dict(),
            "thrust_curve_beta": thrust.beta,
            "thrust_span_g": list(thrust.span_g),
            "accel_explained": thrust.explained,
            "props_out": rotation.props_out,
            **{name: _axis(rotation.axis(i)) for i, name in enumerate(AXES)},
            "train_error": dict(zip(AXES, rotation.train_error, strict=True)),
        },
        "hover_command": {"logged": fit.hover_logged, "model": fit.hover_model},
        "noise_floor": {
            "above_hz": fit.noise.above_hz,
            "gyro_deg_s": [_number(v) for v in fit.noise.gyro_deg_s],
            "accel_up_g": _number(fit.noise.accel_up_g),
            "calm_s": fit.noise.calm_s,
            "as_logged": "after the FC's own gyro and accelerometer filters",
        },
        "profile_figures": {
            "mass_g": fit.spec.mass_g,
            "max_thrust_g": fit.spec.max_thrust_g,
            "motor_time_constant_ms": fit.spec.motor_time_constant_ms,
            "inertia_kg_m2": list(fit.spec.inertia_kg_m2),
            "rotor_inertia_kg_m2": fit.spec.rotor_inertia_kg_m2,
        },
        "score": {
            "cutoff_hz": SCORE_CUTOFF_HZ,
            "fitted": fit.fitted.as_dict(),
            "hold": fit.hold.as_dict(),
            "closest_shipped": {"name": closest_name, **closest.as_dict()},
            "shipped": {name: s.as_dict() for name, s in fit.shipped.items()},
        },
        "notes": fit.notes,
    }


def write_report_json(fit: LogFit, path: Path, profile_path: Path | None) -> None:
    write_atomically(path, (json.dumps(report_dict(fit, profile_path), indent=2) + "\n").encode())


def write_report_png(fit: LogFit, path: Path) -> None:
    """Logged against replayed: roll, pitch, yaw and the vertical acceleration on the first
    scored windows, laid end to end."""
    from bfsitl.headless_pyplot import load_pyplot

    plt = load_pyplot()
    shown = min(PLOTTED_WINDOWS, len(fit.test_windows))
    replayed = fit.replayed
    fig, axes = plt.subplots(4, 1, figsize=(11, 9), sharex=True)
    for row in range(shown):
        start = fit.test_windows.starts[row]
        time_s = fit.data.time_s[start + 1 : start + 1 + fit.test_windows.length]
        first = row == 0
        traces = (
            (replayed.logged_rates, "black", "logged"),
            (replayed.predicted_rates, "tab:red", "replayed (fitted)"),
        )
        for axis in range(3):
            for rates, color, label in traces:
                axes[axis].plot(
                    time_s,
                    np.degrees(rates[axis, row]),
                    color=color,
                    lw=1,
                    label=label if first else None,
                )
        axes[3].plot(time_s, replayed.logged_accel_up_g[row], color="black", lw=1)
        axes[3].plot(time_s, replayed.predicted_accel_up_g[row], color="tab:red", lw=1)
    scores = fit.fitted.rates
    for axis, name in enumerate(AXES):
        axes[axis].set_ylabel(f"{name} deg/s")
        axes[axis].set_title(
            f"{name}: error {scores[axis]:.2f} of the signal (hold {fit.hold.rates[axis]:.2f})",
            fontsize=9,
            loc="left",
        )
    axes[3].set_ylabel("up g")
    axes[3].set_title(
        f"vertical acceleration: error {fit.fitted.accel_up:.2f} (hold {fit.hold.accel_up:.2f})",
        fontsize=9,
        loc="left",
    )
    axes[3].set_xlabel(f"log time, s ({WINDOW_S:g} s windows the fit did not see)")
    axes[0].legend(loc="upper right", fontsize=8)
    fig.suptitle(f"{fit.data.label}: open-loop replay of the fitted {fit.spec.name}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
