"""``bfsitl log check``: the analysers that watch every flight, on blackbox logs (a SITL's or
a real flight's)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from bfsitl.cli.log_fit_command import add_log_fit_parser
from bfsitl.cli.log_replay_command import add_log_replay_parser

EXIT_OK = 0
EXIT_FOUND = 1
EXIT_UNREADABLE = 2
FAIL_ON_CHOICES = ("info", "warning", "failure", "never")


def add_log_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    log = sub.add_parser(
        "log",
        help="check blackbox logs with bfsitl's analysers, fit a vehicle profile to one, or "
        "replay one through the firmware",
        description="The FC's own blackbox logs (.BFL, .BBL, .BF: from a SITL run or a real "
        "flight), read with the decoder scenario runs use.",
    )
    actions = log.add_subparsers(dest="log_action", metavar="ACTION", required=True)
    check = actions.add_parser(
        "check",
        help="run every analyser on each log in the files",
        description="Run the analysers that watch every bfsitl flight on each log in the "
        "files: a crash the FC disarmed for, an impact, lost control (the gyro "
        "against its setpoint, the attitude), oscillation, saturated motors, the "
        "failsafe's phases. A blackbox log has no GPS track and no simulated "
        "truth, so the analysers that need them are listed as not watched; a "
        "bfsitl flight log (flight.csv) has the truth and gets them all. Exit 0 "
        "when nothing reached --fail-on, 1 when something did, 2 when a file "
        "could not be read.",
        epilog="Examples:\n  bfsitl log check scenario-runs/4.6.0-gps-lockstep/rc-loss-hover-drop"
        "/blackbox/LOG00001.BF\n  bfsitl log check LOG00007.BFL --json | jq .\n"
        "  bfsitl log check --list",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    check.add_argument(
        "files", nargs="*", metavar="FILE", help="blackbox files, or bfsitl flight logs (.csv)"
    )
    check.add_argument(
        "--fail-on",
        choices=FAIL_ON_CHOICES,
        default="failure",
        help="exit 1 when a finding is at least this severe (default failure)",
    )
    check.add_argument(
        "--json",
        action="store_true",
        help="print one JSON object: each log's findings and analysers",
    )
    check.add_argument(
        "--list", action="store_true", help="list the analysers and what each looks for, then exit"
    )
    check.set_defaults(func=cmd_log_check)
    add_log_fit_parser(actions)
    add_log_replay_parser(actions)


def _entry(
    path: Path,
    index: int,
    firmware: str,
    frames: int,
    duration_s: float,
    disarm_reason: str | None,
    truncated: bool,
    analysis: Any,
) -> dict[str, Any]:
    """One log's line of the output: what it is and what the analysers found."""
    return {
        "file": str(path),
        "log": index,
        "firmware": firmware,
        "frames": frames,
        "duration_s": round(duration_s, 3),
        "disarm_reason": disarm_reason,
        "truncated": truncated,
        "findings": [f.as_dict() for f in analysis.findings],
        "watched": analysis.watched,
        "skipped": analysis.skipped,
        "_findings": analysis.findings,
    }


def _checked(path: Path) -> list[dict[str, Any]]:
    """Each log in ``path``: what it is and what the analysers found."""
    from bfsitl.analysis import analyse, track_from_blackbox, track_from_rows
    from bfsitl.blackbox import decode_blackbox
    from bfsitl.records.csv_log import read_flight_rows

    if path.suffix.lower() == ".csv":
        rows = read_flight_rows(path)
        return [
            _entry(
                path,
                1,
                "bfsitl flight log",
                len(rows),
                rows[-1].time_s - rows[0].time_s if rows else 0.0,
                None,
                False,
                analyse(track_from_rows(rows, label=str(path))),
            )
        ]
    return [
        _entry(
            path,
            log.index,
            log.firmware_revision,
            len(log.frames),
            log.duration_s,
            log.disarm_reason_name,
            log.truncated,
            analyse(track_from_blackbox(log)),
        )
        for log in decode_blackbox(path)
    ]


def cmd_log_check(args: argparse.Namespace) -> int:
    from bfsitl.analysis import ANALYSERS, Severity
    from bfsitl.errors import BfsitlError

    if args.list:
        for analyser in ANALYSERS:
            print(f"{analyser.name:<20} {analyser.what}")
        return EXIT_OK
    if not args.files:
        print(
            "bfsitl: error: give one or more blackbox files (LOG00001.BFL, ...), or --list",
            file=sys.stderr,
        )
        return EXIT_UNREADABLE
    threshold = None if args.fail_on == "never" else Severity.parse(args.fail_on)
    logs: list[dict[str, Any]] = []
    unreadable: list[dict[str, str]] = []
    for name in args.files:
        try:
            logs.extend(_checked(Path(name)))
        except BfsitlError as exc:
            unreadable.append({"file": name, "error": str(exc)})
            if not args.json:
                print(f"bfsitl: error: {exc}", file=sys.stderr)
    found = any(
        threshold is not None and f.severity >= threshold for log in logs for f in log["_findings"]
    )
    if args.json:
        print(
            json.dumps(
                {
                    "logs": [{k: v for k, v in log.items() if k != "_findings"} for log in logs],
                    "unreadable": unreadable,
                },
                indent=2,
            )
        )
    else:
        for log in logs:
            _print_log(log)
    if unreadable:
        return EXIT_UNREADABLE
    return EXIT_FOUND if found else EXIT_OK


def _print_log(log: dict[str, Any]) -> None:
    ended = log["disarm_reason"] or "no disarm event"
    cut = ", cut short" if log["truncated"] else ""
    print(
        f"{log['file']} log {log['log']}: {log['firmware'] or 'unknown firmware'}, "
        f"{log['frames']} frames over {log['duration_s']:.2f} s, disarmed: {ended}{cut}"
    )
    if not log["_findings"]:
        print(f"  nothing found ({len(log['watched'])} analysers watched)")
    for finding in log["_findings"]:
        print(f"  {finding.line()}")
    if log["skipped"]:
        print(
            "  not watched: "
            + "; ".join(f"{name} ({why})" for name, why in sorted(log["skipped"].items()))
        )
