"""A scenario's plot: height, distance from home, tilt and the FC's failsafe phase on one time
axis, the faults marked, the span while armed shaded: what a person checks a verdict
against."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from bfsitl.headless_pyplot import load_pyplot
from bfsitl.scenario.trace import FAILSAFE_PHASES, Trace


def write_scenario_plot(trace: Trace, path: Path, *, title: str = "") -> Path:
    plt = load_pyplot()
    rows = trace.rows
    t = [r.time_s for r in rows]
    figure, axes = plt.subplots(
        4, 1, figsize=(9, 8), sharex=True, gridspec_kw={"height_ratios": [3, 2, 2, 2]}
    )
    panels = (
        ("height (m)", [r.alt_m for r in rows]),
        ("from home (m)", [r.distance_m for r in rows]),
        ("tilt (deg)", [r.tilt_deg for r in rows]),
    )
    for axis, (label, values) in zip(axes, panels, strict=False):
        axis.plot(t, values, linewidth=1.2)
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    phases = [r.failsafe_phase if r.failsafe_phase is not None else float("nan") for r in rows]
    axes[3].step(t, phases, where="post", color="tab:red", linewidth=1.2)
    axes[3].set_yticks(range(len(FAILSAFE_PHASES)))
    axes[3].set_yticklabels(FAILSAFE_PHASES, fontsize=7)
    axes[3].set_ylabel("failsafe")
    axes[3].set_xlabel("simulation time from arming (s)")
    axes[3].grid(alpha=0.3)
    for axis in axes:
        armed = [r.time_s for r in rows if r.armed]
        if armed:
            axis.axvspan(armed[0], armed[-1], color="tab:green", alpha=0.06, linewidth=0)
        _mark_faults(axis, trace.fault_times_s, "tab:orange", "--", named=axis is axes[0])
        if trace.crash is not None:
            axis.axvline(trace.crash[0], color="black", linestyle=":", linewidth=1)
    return _finish(plt, figure, axes, path, title)


#: Each side's colours, one shade per seed, and its line style: B dashed over A's solid
#: lines, so A shows where the two match.
SIDE_STYLES = (
    (("tab:blue", "#6baed6", "#08519c", "#9ecae1"), "-"),
    (("tab:orange", "#fdae6b", "#a63603", "#fdd0a2"), "--"),
)
#: The plot ends this long after the last run touched down for good (25 s of flat lines on
#: the ground hide the flight); a disarm after that is written at the edge.
AFTER_TOUCHDOWN_S = 3.0


def write_overlay_plot(
    sides: Sequence[tuple[str, Sequence[Trace]]], path: Path, *, title: str = ""
) -> Path:
    """Every seed of each side of one scenario on one time axis (seconds from arming): height,
    distance from home, tilt, the motors' mean command with the throttle stick, and the
    failsafe phase; the faults marked; cut once every run is at rest (``bfsitl scenario
    compare`` overlays side A's and side B's)."""
    plt = load_pyplot()
    figure, axes = plt.subplots(
        5, 1, figsize=(9, 9.5), sharex=True, gridspec_kw={"height_ratios": [3, 2, 2, 2, 2]}
    )
    for (label, traces), (shades, style) in zip(sides, SIDE_STYLES, strict=False):
        for seed, trace in enumerate(traces):
            rows = trace.rows
            t = [r.time_s for r in rows]
            colour = shades[seed % len(shades)]
            named = f"{label} ({len(traces)} seed{'s' if len(traces) != 1 else ''})"
            line = {"color": colour, "linestyle": style, "linewidth": 1.1}
            panels = (
                [r.alt_m for r in rows],
                [r.distance_m for r in rows],
                [r.tilt_deg for r in rows],
            )
            for axis, values in zip(axes, panels, strict=False):
                axis.plot(t, values, label=named if seed == 0 else None, **line)
            axes[3].plot(t, [100 * r.motor_share for r in rows], **line)
            axes[3].plot(t, [100 * r.throttle_share for r in rows], **{**line, "linewidth": 0.6})
            phases = [
                r.failsafe_phase if r.failsafe_phase is not None else float("nan") for r in rows
            ]
            axes[4].step(t, phases, where="post", **line)
    faults = fault_times_s([trace for _, traces in sides for trace in traces])
    labels = ("height (m)", "from home (m)", "tilt (deg)", "motors, throttle (%)", "failsafe")
    for axis, label in zip(axes, labels, strict=True):
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
        _mark_faults(axis, faults, "tab:red", ":", named=axis is axes[0])
    axes[3].annotate(
        "thick: motors' mean command; thin: throttle stick",
        (0.01, 0.97),
        xycoords="axes fraction",
        fontsize=7,
        va="top",
    )
    axes[4].set_yticks(range(len(FAILSAFE_PHASES)))
    axes[4].set_yticklabels(FAILSAFE_PHASES, fontsize=7)
    axes[4].set_xlabel("simulation time from arming (s)")
    end_s = _landed_s([trace for _, traces in sides for trace in traces])
    if end_s is not None:
        axes[4].set_xlim(right=end_s)
        later = [
            f"{label.split(':')[0]} disarmed at {disarm_s:.1f} s"
            for label, traces in sides
            for disarm_s in sorted({_disarm_s(trace) or 0.0 for trace in traces})
            if disarm_s > end_s
        ]
        if later:
            axes[4].annotate(
                "; ".join(later) + " (cut)",
                (0.99, 0.97),
                xycoords="axes fraction",
                fontsize=7,
                ha="right",
                va="top",
            )
    axes[0].legend(loc="upper left", fontsize=8)
    return _finish(plt, figure, axes, path, title)


def fault_times_s(traces: Sequence[Trace]) -> list[float]:
    """When each fault came, from the first run that had faults: every run injects them at
    the same time from arming, give or take a control step, so a union of every run's times
    would draw one fault as several."""
    return next((list(t.fault_times_s) for t in traces if t.fault_times_s), [])


def _mark_faults(  # type: ignore[no-untyped-def]
    axis, times_s: Sequence[float], colour: str, style: str, *, named: bool
) -> None:
    """A line at each fault; on the top panel (``named``) its number."""
    for number, fault_s in enumerate(times_s, start=1):
        axis.axvline(fault_s, color=colour, linestyle=style, linewidth=1)
        if named:
            axis.annotate(
                f"fault {number}",
                (fault_s, 1.0),
                xycoords=("data", "axes fraction"),
                fontsize=8,
                color=colour,
                va="top",
            )


def _landed_s(traces: Sequence[Trace]) -> float | None:
    """When the last of ``traces`` touched down for good, plus :data:`AFTER_TOUCHDOWN_S`;
    None when one ends in the air (the plot keeps every row)."""
    ends = []
    for trace in traces:
        if not trace.rows:
            continue
        if not trace.rows[-1].on_ground:
            return None
        flying = [r.time_s for r in trace.rows if not r.on_ground]
        ends.append((flying[-1] if flying else 0.0) + AFTER_TOUCHDOWN_S)
    end_s = max(ends, default=None)
    if end_s is None or all(end_s >= trace.rows[-1].time_s for trace in traces if trace.rows):
        return None
    return end_s


def _disarm_s(trace: Trace) -> float | None:
    """When the FC disarmed for good (None: it did not)."""
    armed = [r.time_s for r in trace.rows if r.armed]
    if not armed or armed[-1] >= trace.rows[-1].time_s:
        return None
    later = [r.time_s for r in trace.rows if r.time_s > armed[-1]]
    return later[0] if later else None


def _finish(plt, figure, axes, path: Path, title: str) -> Path:  # type: ignore[no-untyped-def]
    """Title, layout, the PNG written, the figure closed (matplotlib keeps every open one)."""
    if title:
        axes[0].set_title(title)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path
