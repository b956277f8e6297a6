"""A scenario's plot: height, distance from home, tilt and the FC's failsafe phase on one time
axis, the faults marked, the span while armed shaded: what a person checks a verdict
against."""

from __future__ import annotations

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
        for number, fault_s in enumerate(trace.fault_times_s, start=1):
            axis.axvline(fault_s, color="tab:orange", linestyle="--", linewidth=1)
            if axis is axes[0]:
                axis.annotate(
                    f"fault {number}",
                    (fault_s, 1.0),
                    xycoords=("data", "axes fraction"),
                    fontsize=8,
                    color="tab:orange",
                    va="top",
                )
        if trace.crash is not None:
            axis.axvline(trace.crash[0], color="black", linestyle=":", linewidth=1)
    return _finish(plt, figure, axes, path, title)


def write_overlay_plot(traces: list[tuple[str, Trace]], path: Path, *, title: str = "") -> Path:
    """Several runs of one scenario on one time axis (seconds from arming): height, distance
    from home, tilt and the failsafe phase, one colour per run (``bfsitl scenario compare``
    overlays side A's and side B's)."""
    plt = load_pyplot()
    figure, axes = plt.subplots(
        4, 1, figsize=(9, 8), sharex=True, gridspec_kw={"height_ratios": [3, 2, 2, 2]}
    )
    colours = ("tab:blue", "tab:orange", "tab:green", "tab:red")
    for number, (label, trace) in enumerate(traces):
        rows = trace.rows
        t = [r.time_s for r in rows]
        colour = colours[number % len(colours)]
        panels = ([r.alt_m for r in rows], [r.distance_m for r in rows], [r.tilt_deg for r in rows])
        for axis, values in zip(axes, panels, strict=False):
            axis.plot(t, values, linewidth=1.2, color=colour, label=label)
        phases = [r.failsafe_phase if r.failsafe_phase is not None else float("nan") for r in rows]
        axes[3].step(t, phases, where="post", color=colour, linewidth=1.2)
    for axis, label in zip(
        axes, ("height (m)", "from home (m)", "tilt (deg)", "failsafe"), strict=True
    ):
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    axes[3].set_yticks(range(len(FAILSAFE_PHASES)))
    axes[3].set_yticklabels(FAILSAFE_PHASES, fontsize=7)
    axes[3].set_xlabel("simulation time from arming (s)")
    axes[0].legend(loc="best", fontsize=8)
    return _finish(plt, figure, axes, path, title)


def _finish(plt, figure, axes, path: Path, title: str) -> Path:  # type: ignore[no-untyped-def]
    """Title, layout, the PNG written, the figure closed (matplotlib keeps every open one)."""
    if title:
        axes[0].set_title(title)
    figure.tight_layout()
    path = Path(path)
    figure.savefig(path, dpi=90)
    plt.close(figure)
    return path
