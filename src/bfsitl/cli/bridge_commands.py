"""``bfsitl configurator`` and ``bfsitl serial-bridge``: let outside tools reach a SITL.

Both relay bytes to the SITL's UART1 (TCP 5761): the first for the web Betaflight
Configurator (WebSocket), the second for anything that opens serial devices (a pty with a
stable symlink).  Target selection is that of the other commands: ``--uri tcp://HOST:PORT`` for
a running SITL, or ``--start`` for one started in its own network namespace, which the bridge
then reaches through the namespace while listening on the host.

A started SITL's probe client is closed at once: the SITL serves one TCP client per UART, and
that slot belongs to the bridge's clients.  A reboot from the Configurator ends a SITL process;
the bridge restarts a SITL it started when the next client connects.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import sys
from collections.abc import Callable, Iterator
from urllib.parse import urlsplit

from bfsitl.bridges import Upstream, connect_upstream
from bfsitl.cli.arg_types import port_number
from bfsitl.cli.target import add_target_arguments, progress
from bfsitl.errors import BridgeError, UpstreamBusyError
from bfsitl.link import DEFAULT_SITL_URI
from bfsitl.sitl.process import SITL_HOST, SITL_MSP_PORT, SitlProcess

EXIT_OK = 0


def add_configurator_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from bfsitl.bridges.websocket_relay import DEFAULT_PORT

    parser = sub.add_parser(
        "configurator",
        help="WebSocket bridge for the web Betaflight Configurator",
        description="Serve a WebSocket on 127.0.0.1 that relays bytes to the SITL's UART1 "
        "(subprotocol binary; wsSerial for Configurators before 2026.6.1), one "
        "client at a time. In the Configurator's Connect menu pick \"Betaflight "
        'SITL" (ws://127.0.0.1:6761, the default port) or, with Expert Mode on '
        '(Options), "Manual Selection" and the printed URL. Only the '
        "Configurator's own pages may connect (see --allow-origin). Stop with "
        "Ctrl-C.",
    )
    parser.add_argument(
        "--port",
        type=port_number,
        default=DEFAULT_PORT,
        help=f"WebSocket port on 127.0.0.1 (default {DEFAULT_PORT})",
    )
    add_allow_origin_argument(parser)
    add_target_arguments(parser)
    parser.set_defaults(func=cmd_configurator)


def add_serial_bridge_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    parser = sub.add_parser(
        "serial-bridge",
        help="virtual serial port (pty) relayed to the SITL",
        description="Create a pseudo-terminal in raw mode relayed to the SITL's UART1, so tools "
        "that only open serial devices (pyserial, terminal monitors, "
        "serial:// URIs) reach the SITL. Stop with Ctrl-C; the symlink is removed.",
    )
    parser.add_argument(
        "--link",
        metavar="PATH",
        default=None,
        help="create a symlink PATH to the pty (a stable name; an existing "
        "symlink is replaced, any other file is left alone and refused)",
    )
    add_target_arguments(parser)
    parser.set_defaults(func=cmd_serial_bridge)


# --- commands ------------------------------------------------------------------------------


def add_allow_origin_argument(parser: argparse.ArgumentParser) -> None:
    """``--allow-origin``, shared by every command that serves a WebSocket."""
    parser.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="also accept WebSocket clients from this web page origin "
        "(scheme://host[:port], repeatable; '*' for any). By default only "
        "the Configurator's and Foxglove's apps, pages on localhost or "
        "127.0.0.1, and clients that send no Origin (scripts) are served",
    )


def cmd_configurator(args: argparse.Namespace) -> int:
    from bfsitl.bridges.origin_policy import OriginPolicy
    from bfsitl.bridges.websocket_relay import WebSocketRelay, connect_hint

    origins = OriginPolicy.with_extra(args.allow_origin)
    with _upstream(args) as upstream:
        relay = WebSocketRelay(upstream, port=args.port, origins=origins, on_event=progress)

        def listening(url: str) -> None:
            progress(f"relaying WebSocket clients to {upstream.uri}; Ctrl-C stops")
            progress(connect_hint(url))
            print(url, flush=True)

        async def serve() -> None:
            await relay.serve(started=listening)

        with _stopped_by_ctrl_c():
            asyncio.run(serve())
    return EXIT_OK


def cmd_serial_bridge(args: argparse.Namespace) -> int:
    from bfsitl.bridges.pty_relay import PtyRelay

    with _upstream(args) as upstream:
        relay = PtyRelay(upstream, link_path=args.link, on_event=progress)
        with relay as endpoint, _stopped_by_ctrl_c():
            progress(f"pty {endpoint.device} relayed to {upstream.uri}; Ctrl-C stops")
            print(endpoint.path, flush=True)
            relay.serve()
    return EXIT_OK


# --- helpers -------------------------------------------------------------------------------


@contextlib.contextmanager
def _upstream(args: argparse.Namespace) -> Iterator[Upstream]:
    """Where to relay: a SITL started here (stopped afterwards, always) or one at ``--uri``."""
    if getattr(args, "start", False):
        sitl = SitlProcess(
            args.firmware, workdir=args.workdir, isolate=not args.no_isolate, progress=progress
        )
        with sitl:
            yield sitl_upstream(sitl)
        progress("SITL stopped")
        return
    upstream = _upstream_from_uri(args.uri or DEFAULT_SITL_URI)
    _check_reachable(upstream)
    yield upstream


def sitl_upstream(sitl: SitlProcess) -> Upstream:
    """The upstream for a SITL we started: its client slot freed for the bridge's clients,
    reached through its network (namespace), restarted when a reboot ended it."""
    _free_client_slot(sitl)
    if sitl.network is None:
        raise BridgeError("the SITL has not been started")
    return Upstream(
        SITL_HOST,
        SITL_MSP_PORT,
        socket_factory=sitl.network.socket,
        prepare=_restart_when_exited(sitl),
    )


def _upstream_from_uri(uri: str) -> Upstream:
    parts = urlsplit(uri)
    if parts.scheme != "tcp":
        raise BridgeError(
            f"{uri!r}: the bridges relay to a SITL's TCP port; give --uri tcp://HOST:PORT "
            f"(e.g. {DEFAULT_SITL_URI}), or --start. A real board on serial:// needs no bridge."
        )
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or port is None:
        raise BridgeError(f"{uri!r}: a tcp URI needs a host and a port, e.g. {DEFAULT_SITL_URI}")
    return Upstream(parts.hostname, port)


def _check_reachable(upstream: Upstream) -> None:
    """Fail at start, not at the first client, when no SITL listens; a busy one only warns."""
    try:
        connect_upstream(upstream).close()
    except UpstreamBusyError as exc:
        progress(f"warning: {exc}")


def _free_client_slot(sitl: SitlProcess) -> None:
    if sitl.client is not None:
        sitl.client.close()
        sitl.client = None


def _restart_when_exited(sitl: SitlProcess) -> Callable[[], None]:
    """Before each connection: a reboot (Configurator save, CLI exit) ended the process."""

    def prepare() -> None:
        if sitl.running:
            return
        progress("the SITL process has exited (a reboot ends it); restarting it")
        sitl.restart_after_reboot()
        _free_client_slot(sitl)

    return prepare


@contextlib.contextmanager
def _stopped_by_ctrl_c() -> Iterator[None]:
    """Ctrl-C is how a bridge is meant to stop: a clean exit, not an interruption.  SIGTERM
    and SIGHUP arrive the same way (:mod:`bfsitl.stop_signals`), so the symlink and a started
    SITL are cleaned up whichever stops it."""
    try:
        yield
    except KeyboardInterrupt:
        print(file=sys.stderr)
        progress("stopping")
