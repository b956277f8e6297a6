"""``bfsitl top``: the live dashboard (attitude, altitude, motors, RC, modes, blockers, link).

On a terminal it takes over the screen until q or Ctrl-C; a SITL started with ``--start`` is
stopped on the way out either way (``open_target`` owns it).  Without ``--uri`` or
``--start`` it attaches to the running ``bfsitl fly`` (``--attach KEY`` picks one of several;
:mod:`bfsitl.cli.attach`): it reads the FC through the SITL's second MSP port and never
writes to it, so the flight goes on undisturbed, and ends when the flight does.  When
stdout is not a terminal, or with ``--once``, it prints a single frame and exits, so the same
view can go into a file or a bug report.  Rich is an optional dependency (the ``top``
extra) and is imported only when the command runs.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import Iterator

from bfsitl.cli.attach import attached_target, flight_to_attach
from bfsitl.cli.target import Target, add_target_arguments, open_target, progress
from bfsitl.dashboard.keys import KeySource, NoKeys, TerminalKeys
from bfsitl.dashboard.loop import DEFAULT_RATE_HZ, DashboardResult, run_dashboard
from bfsitl.errors import ExtraMissingError, LinkClosedError
from bfsitl.link import DEFAULT_SITL_URI
from bfsitl.sitl.running_flights import FlightAdvert

#: A single frame should not come out empty because one reply was lost or corrupted.
ONCE_RETRIES = 2


def add_top_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    top = sub.add_parser(
        "top",
        help="live dashboard: attitude, motors, RC, modes, arming blockers, link",
        description="A live terminal view of the FC: attitude, altitude, motors, RC channels, "
        "flight modes, every arming blocker with its fix, and link statistics "
        "(updates/s, errors, MSP round trip). q or Ctrl-C quits. Prints one frame "
        "when stdout is not a terminal. Without --uri or --start it watches the running "
        "`bfsitl fly` if there is one (--attach KEY picks one of several).",
    )
    add_target_arguments(top, attach_flag=True)
    top.add_argument(
        "--rate",
        type=_positive_rate,
        default=DEFAULT_RATE_HZ,
        metavar="HZ",
        help=f"frames (and polls) per second (default {DEFAULT_RATE_HZ:g})",
    )
    top.add_argument(
        "--once",
        action="store_true",
        help="print one frame and exit (the default when stdout is not a terminal)",
    )
    top.set_defaults(func=cmd_top)


def _positive_rate(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not value > 0:
        raise argparse.ArgumentTypeError("rate must be positive")
    return value


@contextlib.contextmanager
def _terminal_keys() -> Iterator[KeySource]:
    """q from the keyboard when stdin is a terminal; otherwise only Ctrl-C quits."""
    if sys.stdin.isatty():
        with TerminalKeys(sys.stdin.fileno()) as keys:
            yield keys
    else:
        yield NoKeys()


def cmd_top(args: argparse.Namespace) -> int:
    try:
        from rich.console import Console

        from bfsitl.dashboard.live import LiveScreen, PrintOnce
    except ImportError as exc:
        raise ExtraMissingError(
            "bfsitl top needs Rich: pip install 'bfsitl[top]' (or pip install rich)"
        ) from exc
    console = Console()
    once = args.once or not console.is_terminal
    if once and not args.once:
        progress("stdout is not a terminal: printing one frame (`bfsitl telemetry` streams)")
    advert = flight_to_attach(args)
    if advert is not None:
        progress(f"attaching to {advert.describe()}")
    try:
        with _target(args, advert) as target:
            where = _where(args, target, advert)
            result: DashboardResult
            if once:
                result = run_dashboard(
                    target.client,
                    show=PrintOnce(console).show,
                    keys=NoKeys(),
                    target=where,
                    rate_hz=args.rate,
                    max_frames=1,
                    retries=ONCE_RETRIES,
                )
            else:
                with _terminal_keys() as keys, LiveScreen(console) as screen:
                    result = run_dashboard(
                        target.client, show=screen.show, keys=keys, target=where, rate_hz=args.rate
                    )
    except LinkClosedError:
        if advert is None:
            raise
        progress(f"flight {advert.key} ended (its SITL closed the connection)")
        return 0
    link = result.link
    progress(
        f"{result.frames} frame(s), {link.updates} update(s), {link.errors} error(s) "
        f"in {link.elapsed_s:.1f} s"
    )
    return 0


def _target(
    args: argparse.Namespace, advert: FlightAdvert | None
) -> contextlib.AbstractContextManager[Target]:
    if advert is None:
        return open_target(args)
    return attached_target(advert, args.timeout)


def _where(args: argparse.Namespace, target: Target, advert: FlightAdvert | None) -> str:
    """The frame's title: the address, and whose it is."""
    if advert is not None:
        return f"{advert.uri} (flight {advert.key}, UART2)"
    where = target.sitl.uri if target.sitl else (args.uri or DEFAULT_SITL_URI)
    if target.sitl is not None and target.sitl.isolated:
        where += " (started SITL, private network namespace)"
    return where
