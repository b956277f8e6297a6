"""The ``bfsitl`` command.

Exit codes: 0 success, 1 a bfsitl error (the one-line reason is printed), 2 bad usage,
130 interrupted (Ctrl-C, SIGTERM or SIGHUP: all three stop cleanly, see
bfsitl.stop_signals).  Progress goes to stderr, results to stdout.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from bfsitl.cli import render
from bfsitl.cli.arg_types import number_in
from bfsitl.cli.bridge_commands import add_configurator_parser, add_serial_bridge_parser
from bfsitl.cli.doctor import add_doctor_parser
from bfsitl.cli.firmware_command import add_firmware_parser
from bfsitl.cli.fly_parser import add_fly_parser
from bfsitl.cli.log_command import add_log_parser
from bfsitl.cli.scenario_command import add_scenario_parser
from bfsitl.cli.sim_command import add_sim_parser
from bfsitl.cli.target import add_target_arguments, open_target, progress
from bfsitl.cli.top_command import add_top_parser
from bfsitl.cli.vehicle_command import add_vehicle_parser
from bfsitl.errors import BfsitlError, CliError
from bfsitl.fc.cli_session import CliSession
from bfsitl.fc.identity import read_identity
from bfsitl.fc.telemetry_poller import TelemetryPoller
from bfsitl.stop_signals import how_stopped, stop_signals_interrupt
from bfsitl.toml_file import read_text_file
from bfsitl.version import __version__

EXIT_OK = 0
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130


# --- commands ------------------------------------------------------------------------------


def cmd_status(args: argparse.Namespace) -> int:
    with open_target(args) as target:
        client = target.client
        identity = read_identity(client)
        telemetry = client.telemetry()
        status = telemetry.status
        if args.json:
            print(
                json.dumps(
                    {
                        "identity": identity.as_dict(),
                        "sitl_conventions": render.conventions_text(identity),
                        "sensors": list(status.sensors),
                        "cycle_time_us": status.cycle_time_us,
                        "cpu_load_percent": status.cpu_load_percent,
                        "armed": status.armed,
                        "flight_modes": list(telemetry.flight_modes),
                        "arming_blockers": [
                            {
                                "name": b.cli_name,
                                "bit": b.bit,
                                "meaning": b.meaning,
                                "fix": b.fix,
                                "firmware_source": b.source,
                            }
                            for b in status.arming_blockers
                        ],
                        "attitude_deg": [
                            telemetry.attitude.roll_deg,
                            telemetry.attitude.pitch_deg,
                            telemetry.attitude.yaw_deg,
                        ],
                        "altitude_m": telemetry.altitude.altitude_m,
                    }
                )
            )
        else:
            print(render.status_report(identity, telemetry))
    return EXIT_OK


def cmd_telemetry(args: argparse.Namespace) -> int:
    as_json = args.json or not sys.stdout.isatty()
    with open_target(args) as target, TelemetryPoller(target.client, rate_hz=args.rate) as poller:
        started_s = time.monotonic()
        sequence = 0
        if not as_json:
            print(render.TELEMETRY_HEADER)
        while args.duration is None or time.monotonic() - started_s < args.duration:
            snapshot = poller.wait_next(sequence, timeout_s=2.0)
            if poller.fatal_error is not None:
                raise poller.fatal_error
            if snapshot is None:
                progress("no telemetry for 2 s; still trying")
                continue
            sequence = poller.sequence
            t_s = snapshot.received_at_s - started_s
            if as_json:
                print(json.dumps(render.telemetry_record(t_s, snapshot)), flush=True)
            else:
                # One line redrawn in place: a live view that does not scroll.
                print("\r" + render.telemetry_row(t_s, snapshot), end="", flush=True)
        stats = poller.stats()
    if not as_json:
        print()
    progress(
        f"{stats.updates} updates in {stats.elapsed_s:.1f} s ({stats.rate_hz:.1f}/s), "
        f"{stats.errors} errors"
    )
    if stats.updates == 0:
        # Nothing was measured: a script piping this must not take silence for success.
        progress("no telemetry update arrived; `bfsitl status` tells what the FC answers")
        return EXIT_ERROR
    return EXIT_OK


def cmd_cli(args: argparse.Namespace) -> int:
    if args.file:
        commands = read_text_file(Path(args.file), "command", CliError).splitlines()
    else:
        commands = [" ".join(args.command)] if args.command else ["status"]
    with open_target(args) as target:
        with CliSession(target.client.link) as cli:
            for line in commands:
                line = line.strip()
                if not line or line.startswith("#"):
                    continue
                word = line.split()[0].lower()
                if word == "save":
                    restart = target.sitl.restart_after_reboot if target.sitl else None
                    print(cli.save(restart=restart))
                    if target.sitl is None:
                        progress(
                            "saved; the FC reboots (a SITL process exits and must be restarted)"
                        )
                    return EXIT_OK
                if word == "exit":
                    print(cli.leave())
                    return EXIT_OK
                print(cli.run(line, check=not args.keep_going))
    return EXIT_OK


def cmd_backup(args: argparse.Namespace) -> int:
    with open_target(args) as target:
        with CliSession(target.client.link) as cli:
            path = cli.backup(args.file)
    progress(f"wrote `diff all` to {path}")
    return EXIT_OK


# --- parser --------------------------------------------------------------------------------


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="bfsitl",
        description="Fly a real Betaflight flight controller in software-in-the-loop "
        "simulation, from Python. Talks MSP and the CLI to a SITL or a real board.",
        epilog="Examples:\n"
        "  bfsitl fly --plot flight.png     take off to 2 m, hold 10 s, land; plot it\n"
        "  bfsitl status --start            start a SITL, show who it is and what "
        "blocks arming\n"
        "  bfsitl telemetry --rate 20 --duration 5\n"
        "  bfsitl cli get small_angle\n"
        "  bfsitl backup my-quad.txt --uri serial:///dev/ttyACM0\n"
        "  bfsitl sim --duration 10 --json  physics against a SITL, health once a second\n"
        "  bfsitl scenario run --junit r.xml   the shipped failsafe/fault library\n"
        "  bfsitl doctor                    firmware, ports, a live probe, blockers\n"
        "  bfsitl top --start               live dashboard: attitude, motors, RC, "
        "blockers, link\n"
        "  bfsitl configurator --start      the web Configurator reaches the SITL at "
        "ws://127.0.0.1:6761\n"
        "  bfsitl serial-bridge --start --link /tmp/ttyBF   a pty for serial-only tools",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"bfsitl {__version__}")
    sub = parser.add_subparsers(dest="command_name", metavar="COMMAND", required=True)

    status = sub.add_parser(
        "status",
        help="identity, sensors, arming blockers explained",
        description="Show the FC's identity, sensors, loop time, flight "
        "modes and every arming blocker with its fix.",
    )
    add_target_arguments(status)
    status.add_argument("--json", action="store_true", help="one JSON object")
    status.set_defaults(func=cmd_status)

    telemetry = sub.add_parser(
        "telemetry",
        help="stream attitude, altitude, RC, motors, arming state",
        description="Poll telemetry (one MSP_MULTIPLE_MSP round trip per update). A live line "
        "on a terminal; JSON lines otherwise or with --json.",
    )
    add_target_arguments(telemetry)
    telemetry.add_argument(
        "--rate",
        type=_rate,
        default=10.0,
        metavar="HZ",
        help="updates per second, or 'max' (default 10)",
    )
    telemetry.add_argument(
        "--duration",
        type=number_in(0, None, "s", above_low=True),
        default=None,
        metavar="S",
        help="stop after S seconds (default: until Ctrl-C)",
    )
    telemetry.add_argument("--json", action="store_true", help="JSON lines even on a terminal")
    telemetry.set_defaults(func=cmd_telemetry)

    cli = sub.add_parser(
        "cli",
        help="run Betaflight CLI commands",
        description="Run CLI commands (default: status) and print their output. 'save' writes "
        "and reboots; with --start the SITL is restarted afterwards.",
    )
    add_target_arguments(cli)
    cli.add_argument("command", nargs="*", help="one command, e.g. get small_angle")
    cli.add_argument("--file", help="a file of commands, one per line ('#' comments allowed)")
    cli.add_argument(
        "--keep-going", action="store_true", help="print ###ERROR output instead of stopping at it"
    )
    cli.set_defaults(func=cmd_cli)

    backup = sub.add_parser(
        "backup",
        help="save `diff all` to a file",
        description="Write the FC's `diff all` to FILE (atomically).",
    )
    backup.add_argument("file", help="where to write the backup")
    add_target_arguments(backup)
    backup.set_defaults(func=cmd_backup)

    add_fly_parser(sub)
    add_sim_parser(sub)
    add_scenario_parser(sub)
    add_doctor_parser(sub)
    add_top_parser(sub)
    add_configurator_parser(sub)
    add_serial_bridge_parser(sub)
    add_firmware_parser(sub)
    add_log_parser(sub)
    add_vehicle_parser(sub)
    return parser


def _rate(text: str) -> float | None:
    if text == "max":
        return None
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or 'max'") from None
    if value <= 0:
        raise argparse.ArgumentTypeError("rate must be positive")
    return value


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if (
        getattr(args, "file", None)
        and getattr(args, "command", None)
        and args.command_name == "cli"
    ):
        parser.error("give either COMMAND or --file, not both")
    try:
        with stop_signals_interrupt():
            return int(args.func(args))
    except KeyboardInterrupt as exc:
        print(file=sys.stderr)
        progress(f"interrupted ({how_stopped(exc)})")
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # `bfsitl scenario list | head`: the reader has all it wants; stop quietly, and keep
        # Python from complaining again when it flushes stdout at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK
    except BfsitlError as exc:
        # The first line is the reason; details (log tails) follow on the next lines.
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_ERROR
    except OSError as exc:
        print(f"bfsitl: error: {exc}", file=sys.stderr)
        return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
