"""Attach to a running flight: find it, and reach its SITL's second MSP port.

The SITL serves one TCP client per UART and a flight holds UART1, so ``bfsitl fly`` has the
FC serve MSP on UART2 as well and advertises where (:mod:`bfsitl.sitl.running_flights`).
A command that watches (``bfsitl top``) picks the flight here and connects to UART2, from
inside the SITL's private network namespace when it has one: a small agent joins that
namespace (``nsenter``, :class:`~bfsitl.sitl.network.IsolatedNetwork` with ``join_pid``)
and hands back a socket that lives there, as the Configurator bridge does in-process.
Closing the target ends that agent only, never the flight.
"""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Callable, Iterator

from bfsitl.cli.target import Target
from bfsitl.errors import AttachError, LinkClosedError, LinkError, MspError
from bfsitl.fc.msp_client import MspClient
from bfsitl.link import SocketFactory, open_link
from bfsitl.sitl.network import IsolatedNetwork
from bfsitl.sitl.running_flights import FlightAdvert, FlightRegistry, choose_flight

#: Joins the namespace of a pid and makes sockets there (tests pass a fake).
JoinNetwork = Callable[[int], contextlib.AbstractContextManager[SocketFactory]]


def flight_to_attach(
    args: argparse.Namespace, registry: FlightRegistry | None = None
) -> FlightAdvert | None:
    """The running flight the command is to watch, or None for its usual target.

    ``--uri`` and ``--start`` say where already: None.  ``--attach KEY`` is that flight,
    ``--attach`` alone the one running.  With neither, the one running flight is chosen; with
    none running, None (the default address, as before flights advertised themselves).

    Raises:
        AttachError: ``--attach`` and no flight runs, no flight has that key, or several
            run and none was chosen (the message lists them).
    """
    if getattr(args, "uri", None) or getattr(args, "start", False):
        return None
    wanted = getattr(args, "attach", None)
    flights = (registry or FlightRegistry()).running()
    if wanted is None and not flights:
        return None
    return choose_flight(flights, wanted or None)


@contextlib.contextmanager
def _joined(netns_pid: int) -> Iterator[SocketFactory]:
    with IsolatedNetwork(join_pid=netns_pid) as network:
        yield network.socket


@contextlib.contextmanager
def attached_target(
    advert: FlightAdvert, timeout_s: float, *, join: JoinNetwork | None = None
) -> Iterator[Target]:
    """A client on the flight's UART2 while the block runs; the flight is not touched.

    Raises:
        AttachError: Nothing listens there (the flight is ending), or another client holds
            the port (a Configurator, another ``bfsitl top``).
        SitlError: The flight's network namespace cannot be entered.
    """
    join = join or _joined
    with contextlib.ExitStack() as stack:
        factory = (
            stack.enter_context(join(advert.netns_pid)) if advert.netns_pid is not None else None
        )
        try:
            link = open_link(advert.uri, timeout_s=timeout_s, socket_factory=factory)
        except LinkError as exc:
            raise AttachError(
                f"flight {advert.key} advertises {advert.uri}, but it cannot be reached "
                f"({exc}); it may be ending: try again"
            ) from exc
        client = stack.enter_context(MspClient(link, timeout_s=timeout_s))
        _check_not_refused(client, advert)
        yield Target(client, None)


def _check_not_refused(client: MspClient, advert: FlightAdvert) -> None:
    """The SITL takes a second client on a UART and closes it at once: one read says so."""
    try:
        client.api_version()
    except LinkClosedError as exc:
        raise AttachError(
            f"flight {advert.key}'s second MSP port ({advert.uri}) closed our connection: "
            f"another client holds it (a Configurator through --configurator, another "
            f"`bfsitl top`); close that one and try again"
        ) from exc
    except MspError:
        pass  # no reply yet: the dashboard shows it and keeps asking
