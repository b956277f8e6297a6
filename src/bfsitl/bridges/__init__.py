"""Byte relays that let outside tools reach a SITL's UART: what both bridges share.

Two bridges live here: :mod:`bfsitl.bridges.websocket_relay` (the web Betaflight Configurator
speaks WebSocket) and :mod:`bfsitl.bridges.pty_relay` (tools that only open serial devices).
Both carry bytes unchanged to the SITL's TCP port; this module holds what they share: the
upstream address, connecting to it, and watching the client's bytes for trouble.

Facts that shape it (``docs/firmware-findings.md``, ``drivers/serial_tcp.c``):

* The SITL serves one TCP client per UART, but it does not refuse a second one at connect
  time: the kernel completes the handshake, then the SITL's I/O thread (``dyad``, polling every
  10 ms) accepts and closes it at once.  A connection that ends within
  :data:`REFUSAL_PROBE_S` without a byte is therefore "another client holds the port".  Right
  after our own previous client left, the SITL may not have noticed that close yet, so a
  refused connection is retried for :attr:`Upstream.busy_wait_s` before giving up.
* It closes a client that has been idle for 120 s, and a SITL process exits on every reboot
  (``save``, MSP_REBOOT): the upstream connection is made per client, and again after it ends.
* Its receive ring is 1400 bytes with no overflow check, and it drops (v1) or hangs on (v2)
  requests with payloads over 192 bytes: :class:`RequestWatch` warns about both.
"""

from __future__ import annotations

import select
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass

from bfsitl.errors import (
    BridgeError,
    LinkError,
    ListenAddressInUseError,
    UpstreamBusyError,
    UpstreamUnreachableError,
)
from bfsitl.link.tcp_link import SocketFactory, connect_tcp
from bfsitl.protocol.msp_frame import MAX_REQUEST_PAYLOAD, MspFrame, MspParser

__all__ = [
    "REFUSAL_PROBE_S",
    "SITL_RX_RING_BYTES",
    "BridgeError",
    "ListenAddressInUseError",
    "RequestWatch",
    "SessionStats",
    "Upstream",
    "UpstreamBusyError",
    "UpstreamUnreachableError",
    "check_listen_port",
    "connect_upstream",
    "describe_listener",
]

#: How long a fresh connection is watched for the SITL's "second client" close.  The SITL's
#: I/O thread wakes every 10 ms; 0.1 s leaves room for a loaded 2-core machine.
REFUSAL_PROBE_S = 0.1
#: Pause between two connection attempts while the SITL still counts the previous client.
_BUSY_RETRY_INTERVAL_S = 0.15
#: The SITL's TCP receive ring (``RX_BUFFER_SIZE`` in ``serial_tcp.h``), unchecked for overflow.
SITL_RX_RING_BYTES = 1400


@dataclass(frozen=True, slots=True)
class Upstream:
    """Where a bridge sends its bytes: a SITL UART's TCP port, possibly inside a namespace.

    ``socket_factory`` makes the (unconnected) socket: ``IsolatedNetwork.socket`` for a SITL
    in a private namespace, so the connection is made from inside it.  ``prepare`` runs before
    every connection attempt; a bridge that started its SITL passes a function that restarts it
    after a reboot ended the process (and refused connections are then retried for
    ``busy_wait_s``, since the socket closes a moment before the process is gone).
    """

    host: str = "127.0.0.1"
    port: int = 5761
    socket_factory: SocketFactory | None = None
    prepare: Callable[[], None] | None = None
    connect_timeout_s: float = 2.0
    busy_wait_s: float = 1.5

    @property
    def uri(self) -> str:
        return f"tcp://{self.host}:{self.port}"


def connect_upstream(upstream: Upstream) -> socket.socket:
    """A connected, blocking TCP socket to the SITL, proven not to be refused as a second client.

    Raises :class:`UpstreamUnreachableError` when nothing listens and
    :class:`UpstreamBusyError` when another client keeps the port for longer than
    ``busy_wait_s``.  Bytes the SITL sends during the probe stay in the socket (peeked).
    """
    deadline_s = time.monotonic() + upstream.busy_wait_s
    while True:
        if upstream.prepare is not None:
            upstream.prepare()
        try:
            sock = _connect_once(upstream)
        except UpstreamUnreachableError:
            # A SITL we manage may be between its reboot's exit and our restart: the socket
            # closes a moment before the process ends, and prepare() sees it running.
            if upstream.prepare is None or time.monotonic() >= deadline_s:
                raise
            time.sleep(_BUSY_RETRY_INTERVAL_S)
            continue
        if not _closed_at_once(sock):
            return sock
        sock.close()
        if time.monotonic() >= deadline_s:
            raise UpstreamBusyError(
                f"the SITL at {upstream.uri} accepted and at once closed our connection: "
                f"another client holds its UART (the SITL serves one TCP client per port). "
                f"Close the other program (bfsitl telemetry, a Configurator, another bridge) "
                f"and connect again."
            )
        time.sleep(_BUSY_RETRY_INTERVAL_S)


def _connect_once(upstream: Upstream) -> socket.socket:
    try:
        sock = connect_tcp(
            upstream.host,
            upstream.port,
            connect_timeout_s=upstream.connect_timeout_s,
            socket_factory=upstream.socket_factory,
            hint="Use --start to have the bridge start one, or --uri tcp://HOST:PORT for one "
            "that is running.",
        )
    except LinkError as exc:
        raise UpstreamUnreachableError(str(exc)) from exc
    sock.settimeout(None)
    return sock


def _closed_at_once(sock: socket.socket) -> bool:
    """Whether the peer ended the connection within the probe window, before sending a byte."""
    readable, _, _ = select.select([sock], [], [], REFUSAL_PROBE_S)
    if not readable:
        return False
    try:
        return sock.recv(1, socket.MSG_PEEK) == b""
    except OSError:  # reset: refused just the same
        return True


def describe_listener(port: int) -> str:
    """Who holds TCP ``port`` on this host, for an "address in use" message."""
    from bfsitl.sitl.ports import find_port_holders

    try:
        holders = find_port_holders([port], [])
    except OSError:
        holders = []
    if not holders:
        return f"tcp {port} is in use (its holder is not visible: `ss -ltnp` may tell)"
    return "; ".join(dict.fromkeys(holder.describe() for holder in holders))


@dataclass(slots=True)
class SessionStats:
    """One client's time on the bridge: who, how many bytes each way, and why it ended."""

    client: str
    started_s: float
    bytes_to_fc: int = 0
    bytes_to_client: int = 0
    ended_s: float | None = None
    end_reason: str = ""
    #: Bytes of an MSP frame the client began but never finished (0: it ended cleanly).
    torn_frame_bytes: int = 0

    @property
    def duration_s(self) -> float:
        end_s = self.ended_s if self.ended_s is not None else time.monotonic()
        return end_s - self.started_s

    def summary(self) -> str:
        text = (
            f"{self.client}: {self.bytes_to_fc} B to the FC, {self.bytes_to_client} B back "
            f"in {self.duration_s:.1f} s ({self.end_reason or 'still open'})"
        )
        if self.torn_frame_bytes:
            text += (
                f"; it left in the middle of an MSP frame ({self.torn_frame_bytes} B sent): "
                f"the FC may take the next client's first request as the rest of it and "
                f"drop it (clients retry reads)"
            )
        return text


class RequestWatch:
    """Follows the bytes a client sends to the FC, to warn about what the SITL mishandles.

    It never changes the bytes: the relay stays transparent (CLI text, garbage and all); it
    only reports requests the firmware drops or hangs on, bursts that can overflow the SITL's
    receive ring, and a frame left unfinished when the client goes.
    """

    def __init__(self) -> None:
        self._parser = MspParser()
        self._warned_burst = False

    def feed(self, data: bytes) -> list[str]:
        """Look at one chunk on its way to the FC; return warnings (usually none)."""
        warnings = []
        if len(data) > SITL_RX_RING_BYTES and not self._warned_burst:
            self._warned_burst = True
            warnings.append(
                f"client wrote {len(data)} B at once; the SITL's receive ring holds "
                f"{SITL_RX_RING_BYTES} B without an overflow check, so part of it may be lost"
            )
        for event in self._parser.feed(data):
            if isinstance(event, MspFrame) and len(event.payload) > MAX_REQUEST_PAYLOAD:
                warnings.append(
                    f"client sent MSP command {event.command} with a {len(event.payload)}-byte "
                    f"payload; Betaflight 4.6 drops v1 requests over {MAX_REQUEST_PAYLOAD} B "
                    f"and its MSP port hangs on such v2 requests until reboot"
                )
        return warnings

    @property
    def torn_frame_bytes(self) -> int:
        """Bytes of an unfinished frame at the end of what was sent so far."""
        return self._parser.pending_bytes


def check_listen_port(host: str, port: int, option: str) -> None:
    """Fail before a slow start, not after it, when a port a server will listen on is taken.

    Raises :class:`ListenAddressInUseError` naming the holder and ``option`` (the
    command-line option that moves the port).
    """
    import errno

    with socket.socket() as probe:
        try:
            probe.bind((host, port))
        except OSError as exc:
            if exc.errno != errno.EADDRINUSE:
                raise
            raise ListenAddressInUseError(
                f"cannot listen on {host}:{port}: {describe_listener(port)}. Stop it, or "
                f"pick another port with {option}."
            ) from exc
