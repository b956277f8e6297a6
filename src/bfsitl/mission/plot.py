"""The flight plot: altitude against target, throttle, attitude, on one time axis.

matplotlib is imported here only, with the non-interactive Agg backend, so a headless machine
(CI, SSH) can write PNGs and nothing else in bfsitl pays for the import.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bfsitl.errors import BfsitlError, ExtraMissingError
from bfsitl.mission.flight_log import FlightRow


def _pyplot():  # type: ignore[no-untyped-def]
    try:
        import matplotlib
    except ImportError as exc:
        raise ExtraMissingError(
            "plots need matplotlib, a dependency of bfsitl that is missing here: "
            "pip install matplotlib"
        ) from exc
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def write_flight_plot(rows: Sequence[FlightRow], path: str | Path, *, title: str = "") -> Path:
    """Three stacked panels; phases shaded so take-off, hold and landing are easy to find."""
    if not rows:
        raise BfsitlError("nothing to plot: the flight has no rows (it never armed)")
    plt = _pyplot()
    t0 = rows[0].time_s
    time_s = [r.time_s - t0 for r in rows]
    figure, (alt_ax, thr_ax, att_ax) = plt.subplots(3, 1, sharex=True, figsize=(10, 8))
    alt_ax.plot(time_s, [r.target_alt_m for r in rows], "k--", label="target")
    alt_ax.plot(time_s, [r.sim_alt_m for r in rows], label="simulated (truth)")
    alt_ax.plot(time_s, [r.fc_alt_m for r in rows], alpha=0.7, label="FC (MSP_ALTITUDE)")
    alt_ax.set_ylabel("altitude (m)")
    alt_ax.legend(loc="best")
    thr_ax.plot(time_s, [r.rc_throttle_us for r in rows], label="RC throttle")
    thr_ax.set_ylabel("throttle (us)")
    motor_ax = thr_ax.twinx()
    mean_motor = [(r.motor1 + r.motor2 + r.motor3 + r.motor4) / 4 for r in rows]
    motor_ax.plot(time_s, mean_motor, color="tab:orange", alpha=0.6, label="mean motor")
    motor_ax.set_ylabel("motor command (0..1)")
    att_ax.plot(time_s, [r.roll_deg for r in rows], label="roll")
    att_ax.plot(time_s, [r.pitch_deg for r in rows], label="pitch")
    att_ax.set_ylabel("attitude (deg)")
    att_ax.set_xlabel("time since armed (s, simulation)")
    att_ax.legend(loc="best")
    _shade_phases(time_s, rows, (alt_ax, thr_ax, att_ax))
    for axis in (alt_ax, thr_ax, att_ax):
        axis.grid(True, alpha=0.3)
    if title:
        figure.suptitle(title)
    figure.tight_layout()
    out = Path(path)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(out, dpi=100)
    except OSError as exc:
        raise BfsitlError(f"cannot write the plot {out}: {exc}") from exc
    finally:
        plt.close(figure)
    return out


_PHASE_COLOURS = {"takeoff": "tab:green", "goto": "tab:blue", "land": "tab:red"}


def _shade_phases(time_s: list[float], rows: Sequence[FlightRow], axes: tuple) -> None:
    start = 0
    for index in range(1, len(rows) + 1):
        if index == len(rows) or rows[index].phase != rows[start].phase:
            colour = _PHASE_COLOURS.get(rows[start].phase)
            if colour is not None:
                end = time_s[min(index, len(rows) - 1)]
                for axis in axes:
                    axis.axvspan(time_s[start], end, color=colour, alpha=0.07)
            start = index
