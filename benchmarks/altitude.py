"""Altitude controllers on the real Betaflight SITL: a 0 -> 2 m step, a hold, a landing.

For each controller (default: the tutorial's PID, then the cascade) a fresh isolated SITL with
the embedded physics is started (:class:`bfsitl.mission.FlightSession`), the default mission is
flown (:func:`bfsitl.mission.fly`: arm, take off to ``--target``, hold ``--hold``
seconds, land, disarm) and the step response of the take-off and hold is measured on the
simulated truth (:func:`bfsitl.control.metrics.step_response`):

* rise time 10 -> 90 %, overshoot, settling time to +-``--band`` that stays settled,
* steady-state RMS error over the last 5 s of the hold, and its mean (the bias),
* the largest roll/pitch the FC reported, the landing's outcome, and the wall time from the
  start of the session to ARMED.

The controllers see only what a real board reports (the FC's barometric altitude: whole
pascals, ~8 cm steps, low-pass filtered, ~0.2 s late); the truth is only used to judge them.
``--plot PATH`` writes both altitude traces (truth solid, FC reading dotted) against the target.
``--firmware PATH_OR_NAME`` (repeatable) flies the same on each firmware (default: the one
``bfsitl fly`` finds, 4.6.0 from the package); the table has a block per firmware, named as the
firmware reported itself.
Run: ``python benchmarks/altitude.py [--repeats 1] [--firmware master] [--plot altitude.png]``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from dataclasses import asdict, dataclass, field

from bfsitl.backend.options import DEFAULT_BARO_NOISE_PA, Timing, World, fly_sensors
from bfsitl.control import LandingController, make_controller
from bfsitl.control.metrics import StepMetrics, step_response
from bfsitl.mission import FlightRow, FlightSession, MissionPlan, SessionConfig, fly
from bfsitl.mission.session import SitlLaunch

DEFAULT_CONTROLLERS = ("tutorial-pid", "cascade", "fused")
STEADY_WINDOW_S = 5.0


@dataclass
class Run:
    controller: str
    firmware: str
    outcome: str
    reason: str
    armed_after_s: float | None
    metrics: StepMetrics | None
    wall_s: float
    # (seconds since the take-off command, truth m, FC m) for the plot; not in the JSON.
    trace: list[tuple[float, float, float]] = field(default_factory=list, repr=False)


def fly_once(
    controller_name: str,
    plan: MissionPlan,
    band_m: float,
    speed: float,
    baro_noise_pa: float = DEFAULT_BARO_NOISE_PA,
    firmware: str | None = None,
) -> Run:
    controller = make_controller(controller_name, {})
    landing = LandingController(hover_from=controller)
    started = time.monotonic()
    config = SessionConfig(
        timing=Timing(speed=speed),
        sitl=SitlLaunch(firmware=firmware),
        world=World(sensors=fly_sensors(baro_noise_std_pa=baro_noise_pa)),
    )
    with FlightSession(config, progress=_progress) as session:
        result = fly(session, plan, controller, landing=landing)
        assert session.sitl is not None
        firmware_name = session.sitl.profile.firmware_version
    flown = [r for r in result.rows if r.phase in ("takeoff", "hold")]
    return Run(
        controller=controller_name,
        firmware=firmware_name,
        outcome=result.outcome.value,
        reason=result.reason,
        armed_after_s=result.armed_after_s,
        metrics=_metrics(flown, plan, band_m),
        wall_s=time.monotonic() - started,
        trace=_trace(flown),
    )


def _metrics(rows: list[FlightRow], plan: MissionPlan, band_m: float) -> StepMetrics | None:
    if len(rows) < 10:
        return None
    return step_response(
        [r.time_s for r in rows],
        [r.sim_alt_m for r in rows],
        target_m=plan.target_alt_m,
        band_m=band_m,
        steady_window_s=min(STEADY_WINDOW_S, plan.hold_s),
        roll_deg=[r.roll_deg for r in rows],
        pitch_deg=[r.pitch_deg for r in rows],
    )


def _trace(rows: list[FlightRow]) -> list[tuple[float, float, float]]:
    if not rows:
        return []
    t0 = rows[0].time_s
    return [(r.time_s - t0, r.sim_alt_m, r.fc_alt_m) for r in rows]


def _progress(message: str) -> None:
    print(f"  {message}", file=sys.stderr)


def _median(values: list[float]) -> float:
    finite = [v for v in values if v is not None]
    return statistics.median(finite) if finite else math.nan


def table(runs: list[Run], band_m: float) -> str:
    header = (
        f"{'firmware':<16} {'controller':<13} {'runs':>4} {'landed':>6} {'rise s':>7} "
        f"{'overshoot %':>11} {'settle s':>8} {'RMS cm':>7} {'bias cm':>7} "
        f"{'max att deg':>11} {'armed after s':>13}"
    )
    lines = [header, "-" * len(header)]
    for firmware, name in dict.fromkeys((r.firmware, r.controller) for r in runs):
        mine = [r for r in runs if r.controller == name and r.firmware == firmware]
        done = [r.metrics for r in mine if r.metrics is not None]

        def med(attribute: str, scale: float = 1.0, done: list[StepMetrics] = done) -> float:
            return _median([getattr(m, attribute) * scale for m in done])

        landed = sum(r.outcome == "landed" for r in mine)
        armed = _median([r.armed_after_s for r in mine if r.armed_after_s is not None])
        lines.append(
            f"{firmware:<16} {name:<13} {len(mine):>4} {landed:>6} {med('rise_time_s'):>7.2f} "
            f"{med('overshoot_pct'):>11.1f} {med('settling_time_s'):>8.2f} "
            f"{med('steady_state_rms_m', 100):>7.1f} "
            f"{med('steady_state_mean_error_m', 100):>+7.1f} "
            f"{med('max_attitude_deg'):>11.1f} {armed:>13.1f}"
        )
    lines.append(
        f"(medians over the runs; settle = inside +-{band_m * 100:.0f} cm for good, inf "
        f"= never; RMS and bias over the last {STEADY_WINDOW_S:.0f} s of the hold, "
        f"simulated truth vs target)"
    )
    return "\n".join(lines)


def plot(runs: list[Run], plan: MissionPlan, band_m: float, path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(10, 5))
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    names = list(dict.fromkeys((r.firmware, r.controller) for r in runs))
    for run in runs:
        if not run.trace:
            continue
        key = (run.firmware, run.controller)
        colour = colours[names.index(key) % len(colours)]
        label = (
            f"{run.firmware} {run.controller}"
            if len({r.firmware for r in runs}) > 1
            else run.controller
        )
        t = [p[0] for p in run.trace]
        axis.plot(t, [p[1] for p in run.trace], color=colour, label=f"{label} (truth)")
        axis.plot(
            t,
            [p[2] for p in run.trace],
            ":",
            color=colour,
            alpha=0.8,
            label=f"{label} (FC reading)",
        )
    axis.axhline(plan.target_alt_m, color="k", linestyle="--", linewidth=1, label="target")
    for edge in (plan.target_alt_m - band_m, plan.target_alt_m + band_m):
        axis.axhline(edge, color="grey", linewidth=0.5)
    axis.set_xlabel("time since the take-off command (s, simulation)")
    axis.set_ylabel("altitude above take-off (m)")
    firmwares = ", ".join(dict.fromkeys(r.firmware for r in runs))
    axis.set_title(
        f"0 -> {plan.target_alt_m:g} m step and {plan.hold_s:g} s hold, Betaflight {firmwares} SITL"
    )
    handles, labels = axis.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))
    axis.legend(unique.values(), unique.keys(), loc="lower right", fontsize=8)
    axis.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--controllers",
        default=",".join(DEFAULT_CONTROLLERS),
        help="comma-separated controller names (default: %(default)s)",
    )
    parser.add_argument("--target", type=float, default=2.0, help="step height, m")
    parser.add_argument("--hold", type=float, default=12.0, help="hold time, s")
    parser.add_argument("--band", type=float, default=0.05, help="settling band, m")
    parser.add_argument("--repeats", type=int, default=1, help="flights per controller")
    parser.add_argument(
        "--speed", type=float, default=1.0, help="simulation speed x real time (default 1)"
    )
    parser.add_argument(
        "--baro-noise-pa",
        type=float,
        default=DEFAULT_BARO_NOISE_PA,
        help="barometer noise std, Pa (default %(default)s, as `bfsitl fly`; "
        "0 gives the FC a whole-pascal staircase)",
    )
    parser.add_argument(
        "--firmware",
        action="append",
        metavar="PATH_OR_NAME",
        help="SITL binary or cached build name, repeatable (default: the one `bfsitl fly` uses)",
    )
    parser.add_argument("--plot", metavar="PATH", help="write the altitude traces as a PNG")
    parser.add_argument("--json", action="store_true", help="print the runs as JSON")
    args = parser.parse_args(argv)
    plan = MissionPlan(target_alt_m=args.target, hold_s=args.hold)
    runs: list[Run] = []
    for firmware in args.firmware or [None]:
        for _ in range(max(1, args.repeats)):
            for name in args.controllers.split(","):
                print(f"{name}: flying on {firmware or 'the default firmware'}", file=sys.stderr)
                run = fly_once(
                    name.strip(), plan, args.band, args.speed, args.baro_noise_pa, firmware
                )
                print(f"{name}: {run.outcome} ({run.reason}), {run.wall_s:.0f} s", file=sys.stderr)
                runs.append(run)
    if args.json:
        print(
            json.dumps(
                [{k: v for k, v in asdict(r).items() if k != "trace"} for r in runs],
                indent=2,
                default=str,
            )
        )
    print(table(runs, args.band), file=sys.stderr if args.json else sys.stdout)
    if args.plot:
        plot(runs, plan, args.band, args.plot)
        print(f"plot written to {args.plot}", file=sys.stderr)
    return 0 if all(r.outcome == "landed" for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
