"""The flight plot: altitude against target, throttle, attitude, on one time axis; and, for a
flight that used position control, a top-down track (east across, north up) with the
waypoints.  matplotlib comes from :mod:`bfsitl.headless_pyplot`, on first use.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

from bfsitl.errors import BfsitlError
from bfsitl.headless_pyplot import load_pyplot
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.phase import Phase


def write_flight_plot(
    rows: Sequence[FlightRow],
    path: str | Path,
    *,
    title: str = "",
    waypoints: Sequence[tuple[float, float]] = (),
) -> Path:
    """Three stacked panels; phases shaded so take-off, hold and landing are easy to find.
    A flight with position control gets the top-down track on the right; ``waypoints``
    (north, east) are marked on it."""
    if not rows:
        raise BfsitlError("nothing to plot: the flight has no rows (it never armed)")
    plt = load_pyplot()
    t0 = rows[0].time_s
    time_s = [r.time_s - t0 for r in rows]
    horizontal = any(math.isfinite(r.target_north_m) for r in rows)
    if horizontal:
        figure = plt.figure(figsize=(16, 8))
        grid = figure.add_gridspec(3, 2, width_ratios=(1.6, 1.0))
        alt_ax = figure.add_subplot(grid[0, 0])
        thr_ax = figure.add_subplot(grid[1, 0], sharex=alt_ax)
        att_ax = figure.add_subplot(grid[2, 0], sharex=alt_ax)
        _plot_track(figure.add_subplot(grid[:, 1]), rows, waypoints)
    else:
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
    # One legend for both scales (a twin axis keeps its own lines).
    lines = thr_ax.get_lines() + motor_ax.get_lines()
    thr_ax.legend(lines, [line.get_label() for line in lines], loc="best")
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


def _plot_track(
    axis,
    rows: Sequence[FlightRow],  # type: ignore[no-untyped-def]
    waypoints: Sequence[tuple[float, float]],
) -> None:
    """Top-down: the truth's track, the FC's GPS, the waypoints numbered, the start."""
    flown = [r for r in rows if math.isfinite(r.sim_north_m)]
    if flown:
        axis.plot(
            [r.sim_east_m for r in flown], [r.sim_north_m for r in flown], label="simulated (truth)"
        )
    gps = [r for r in rows if math.isfinite(r.fc_north_m)]
    if gps:
        axis.plot(
            [r.fc_east_m for r in gps], [r.fc_north_m for r in gps], alpha=0.7, label="FC (GPS)"
        )
    if waypoints:
        axis.plot(
            [0.0] + [e for _n, e in waypoints],
            [0.0] + [n for n, _e in waypoints],
            "k--",
            alpha=0.5,
            label="planned track",
        )
        for number, (north, east) in enumerate(waypoints, start=1):
            axis.plot(east, north, "ks", markersize=6)
            axis.annotate(str(number), (east, north), textcoords="offset points", xytext=(6, 6))
    axis.plot(0.0, 0.0, "g^", markersize=9, label="take-off point")
    axis.set_xlabel("east (m)")
    axis.set_ylabel("north (m)")
    axis.set_aspect("equal", adjustable="datalim")
    axis.grid(True, alpha=0.3)
    axis.legend(loc="best")
    axis.set_title("track, seen from above")


_PHASE_COLOURS: dict[str, str] = {
    Phase.TAKEOFF: "tab:green",
    Phase.GOTO: "tab:blue",
    Phase.YAW: "tab:purple",
    Phase.LAND: "tab:red",
}


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
