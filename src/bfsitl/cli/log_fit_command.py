"""``bfsitl log fit``: a vehicle profile from a real flight's blackbox log, with its report."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.cli.arg_types import number_in, out_dir_problem, whole_number_at_least

if TYPE_CHECKING:
    from bfsitl.fit import LogFit

EXIT_OK = 0
EXIT_UNTRUSTED = 1
EXIT_UNREADABLE = 2


def add_log_fit_parser(actions: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    fit = actions.add_parser(
        "fit",
        help="identify a quad's physics from its blackbox log and write a vehicle profile",
        description="Identify the physics of the quad that flew LOG: the motors' lag, each "
        "axis' control effectiveness, the thrust-to-weight ratio and the hover command. The "
        "first 70 %% of the flight is fitted and the rest scored: the logged motor commands "
        "are flown by the embedded physics, reset to the logged rates every 0.5 s, and the "
        "error is compared with predicting no change ('hold') and with each shipped profile. "
        "Writes the profile (--vehicle takes it), fit-report.json and fit-report.png to "
        "--out. A log gives ratios, not the parts: state the all-up mass. The best log is a "
        "calm flight with sharp stick moves on each axis and a punch-out, logged at 1 kHz or "
        "more. Exit 0 when the profile replays roll and pitch in at most half of hold's "
        "error, 1 when it does not (the profile is written and marked untrusted), 2 when "
        "the log cannot be fitted.",
        epilog="Examples:\n  bfsitl log fit LOG00007.BFL --mass-g 650\n"
        "  bfsitl log fit btfl_002.bbl --index 3 --mass-g 640 --base 5inch-freestyle "
        "--out my-quad\n  bfsitl fly --vehicle my-quad/btfl_002-fit.toml",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    fit.add_argument("file", metavar="LOG", help="a blackbox file (.BFL, .BBL, .BF)")
    fit.add_argument(
        "--mass-g",
        type=number_in(1.0, 100000.0, "g"),
        required=True,
        help="the quad's all-up mass with its battery, grams",
    )
    fit.add_argument(
        "--index",
        type=whole_number_at_least(1),
        default=None,
        help="which log in the file (1 is the first; default: the longest)",
    )
    fit.add_argument(
        "--base",
        default=None,
        metavar="PROFILE",
        help="the shipped profile whose frame, props and drag the fit keeps (default: the "
        "one nearest in mass; `bfsitl vehicle list` names them)",
    )
    fit.add_argument("--name", default=None, help="the profile's name (default: LOG's name-fit)")
    fit.add_argument(
        "--out",
        type=Path,
        default=Path("fit"),
        help="folder for the profile and the report (default ./fit)",
    )
    fit.set_defaults(func=cmd_log_fit)


def cmd_log_fit(args: argparse.Namespace) -> int:
    from bfsitl.errors import BfsitlError
    from bfsitl.fit.fit_log import fit_log, pick_log
    from bfsitl.fit.fit_report import trusted, write_report_json, write_report_png
    from bfsitl.vehicles import shipped_profiles, write_profile

    base = None
    if args.base is not None:
        profiles = shipped_profiles()
        if args.base not in profiles:
            print(
                f"bfsitl: error: --base {args.base!r} is not a shipped profile; choose one of "
                + ", ".join(sorted(profiles)),
                file=sys.stderr,
            )
            return EXIT_UNREADABLE
        base = profiles[args.base]
    if args.name is not None and (not args.name.strip() or any(c in args.name for c in "/\\")):
        print(f"bfsitl: error: --name {args.name!r} must be a plain name", file=sys.stderr)
        return EXIT_UNREADABLE
    # Checked before the fit, which takes a while: a bad --out says so at once; the folder
    # is made only when there is a fit to write (a log that cannot be fitted leaves nothing).
    problem = out_dir_problem(args.out)
    if problem is not None:
        print(f"bfsitl: error: cannot make the folder --out {args.out}: {problem}", file=sys.stderr)
        return EXIT_UNREADABLE
    print(f"bfsitl: reading {args.file} ...", file=sys.stderr)
    try:
        log = pick_log(Path(args.file), args.index)
        print(f"bfsitl: fitting {log.path.name} log {log.index} ...", file=sys.stderr)
        fit = fit_log(log, mass_g=args.mass_g, base=base, name=args.name)
    except BfsitlError as exc:
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_UNREADABLE
    profile_path = args.out / f"{fit.spec.name}.toml"
    try:
        args.out.mkdir(parents=True, exist_ok=True)
        write_profile(fit.spec, profile_path)
        write_report_json(fit, args.out / "fit-report.json", profile_path)
        write_report_png(fit, args.out / "fit-report.png")
    except OSError as exc:
        print(f"bfsitl: error: cannot write the fit to {args.out}: {exc}", file=sys.stderr)
        return EXIT_UNREADABLE
    _print_summary(fit, profile_path, args.out)
    if not trusted(fit):
        print(
            "bfsitl: the fitted profile does not replay this log: its roll and pitch errors are "
            "not below half of hold's, so the log's rates follow something the physics lacks "
            "(fast forward flight, prop wash) more than the motors. Fit a calmer flight with "
            "sharp stick moves; the profile is written for inspection only.",
            file=sys.stderr,
        )
        return EXIT_UNTRUSTED
    return EXIT_OK


def _fmt_triple(values: tuple[float, float, float]) -> str:
    return " / ".join(f"{v:.2f}" for v in values)


def _print_summary(fit: LogFit, profile_path: Path, out: Path) -> None:
    from bfsitl.fit.rotation import AXES

    rotation, thrust = fit.rotation, fit.thrust
    data = fit.data
    print(
        f"{data.label}: {data.firmware or 'unknown firmware'}, {data.usable_s:.1f} s usable at "
        f"{1.0 / data.dt_s:.0f} Hz; fitted on {len(fit.train_windows)} windows, scored on "
        f"{len(fit.test_windows)}"
    )
    print(
        f"  motor time constant   {rotation.time_constant_s * 1000:.1f} ms (the gyro "
        f"{rotation.delay_s * 1000:.0f} ms behind)"
    )
    tw = thrust.thrust_to_weight
    print(
        f"  thrust-to-weight      {tw.value:.2f} +- {tw.std:.2f} (read at the hover, with "
        f"{fit.base.name}'s curve shape)"
    )
    print(
        f"  hover command         logged {fit.hover_logged:.1%}, fitted model {fit.hover_model:.1%}"
    )
    for index, name in enumerate(AXES):
        axis = rotation.axis(index)
        print(
            f"  {name + ' effectiveness':<21} {axis.effectiveness.value:.0f} +- "
            f"{axis.effectiveness.std:.0f} rad/s^2 per rotor's full thrust"
        )
    noise = fit.noise
    print(
        f"  noise floor           gyro {_fmt_triple(noise.gyro_deg_s)} deg/s, accel "
        f"{noise.accel_up_g:.3f} g RMS above {noise.above_hz:.0f} Hz, as logged (after the "
        "FC's filters)"
    )
    closest_name, closest = fit.closest_shipped
    print("  replay error over signal (roll / pitch / yaw / vertical acceleration):")
    for label, result in (
        ("fitted", fit.fitted),
        (f"{closest_name} (unfitted)", closest),
        ("hold (no change)", fit.hold),
    ):
        roll, pitch, yaw = result.rates
        print(f"    {label:<28} {roll:.2f} / {pitch:.2f} / {yaw:.2f} / {result.accel_up:.2f}")
    for note in fit.notes:
        print(f"  note: {note}")
    print(f"wrote {profile_path}, {out / 'fit-report.json'}, {out / 'fit-report.png'}")
