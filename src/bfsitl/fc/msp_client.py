"""Synchronous MSP client: requests matched to replies in order, over any :class:`Link`.

Why it is built this way (facts in ``docs/firmware-findings.md``):

* MSP has no sequence numbers and the FC answers strictly in request order, so outstanding
  requests sit in a FIFO and a reply resolves the oldest entry with the same command.  A reply
  for a later entry means the earlier request was lost (a bad checksum gets no reply at all).
* The FC handles one packet per serial tick (100 Hz by default), so throughput comes from
  keeping a few requests in flight (:meth:`MspClient.pipeline`), never from waiting harder.
* The SITL's TCP receive ring is 1400 bytes with no overflow check, and a real UART has 256
  bytes: the bytes in flight are capped (:attr:`MspClient.max_in_flight_bytes`).
* Only reads are retried: re-sending a ``SET`` or ``EEPROM_WRITE`` whose reply was lost could
  apply it twice.
* A port left in CLI mode echoes MSP bytes as text; a timeout looks for that and says so.
* The SITL's TCP thread (``lib/main/dyad``) sleeps in ``select`` for up to 10 ms and only
  watches for write-readiness if it had output queued before it slept, so a reply the FC
  produces meanwhile waits for the next incoming byte or the timeout.  While waiting for a
  reply, the client therefore sends one ``0x00`` every millisecond (:data:`WAKE_BYTE`): the
  MSP parser discards it in its idle state (only ``$``, ``#``, ``R`` and ``0x02`` mean
  anything there), and its arrival makes the thread flush the reply at once.  Measured in
  ``benchmarks/telemetry.py``.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, Protocol, TypeVar

from bfsitl.errors import LinkClosedError, MspDecodeError, MspErrorReply, MspTimeoutError
from bfsitl.fc.telemetry import TELEMETRY_COMMANDS, Telemetry, telemetry_from_payloads
from bfsitl.link.base import Link
from bfsitl.link.serial_link import SerialLink
from bfsitl.link.tcp_link import TcpLink
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import (
    ChecksumFailure,
    Direction,
    MspFrame,
    MspParser,
    encode_request,
)

DEFAULT_TIMEOUT_S = 0.5
#: Sent while waiting on a SITL TCP link to make its I/O thread flush replies (see above).
WAKE_BYTE = b"\x00"
#: How often to send it: well under the SITL's 10 ms select timeout.
DEFAULT_WAKE_INTERVAL_S = 0.001
DEFAULT_RETRIES = 2
#: What a SITL's TCP port and a real UART take in flight (each link says which applies).
TCP_MAX_IN_FLIGHT_BYTES = TcpLink.max_in_flight_bytes
SERIAL_MAX_IN_FLIGHT_BYTES = SerialLink.max_in_flight_bytes

#: Commands that change state although their name has no SET in it.
_MUTATING_COMMANDS = frozenset({
    MspCommand.REBOOT, MspCommand.EEPROM_WRITE, MspCommand.ACC_CALIBRATION,
    MspCommand.MAG_CALIBRATION, MspCommand.RESET_CONF, MspCommand.DATAFLASH_ERASE,
    MspCommand.COPY_PROFILE, MspCommand.SELECT_SETTING, MspCommand.CALCULATE_SIMPLIFIED_PID,
    MspCommand.CALCULATE_SIMPLIFIED_GYRO, MspCommand.CALCULATE_SIMPLIFIED_DTERM,
    MspCommand.OSD_CHAR_WRITE, MspCommand.DISPLAYPORT, MspCommand.MSP2_BETAFLIGHT_BIND,
    MspCommand.MSP2_SEND_DSHOT_COMMAND, MspCommand.CAMERA_CONTROL,
})

T = TypeVar("T")


class _Encodable(Protocol):
    COMMAND: ClassVar[int]

    def encode(self) -> bytes: ...


def is_idempotent(command: int) -> bool:
    """Whether repeating ``command`` is harmless (a read)."""
    try:
        name = MspCommand(command).name
    except ValueError:
        return False  # unknown: assume it changes something
    return "SET" not in name and command not in _MUTATING_COMMANDS


@dataclass(frozen=True, slots=True)
class MspRequest:
    """One request: a command id and its payload."""

    command: int
    payload: bytes = b""


@dataclass(slots=True, eq=False)  # identity: the FIFO finds and removes entries
class _Pending:
    """A request on the wire, in the FIFO of outstanding requests."""

    request: MspRequest
    frame_size: int
    #: When the reply could start to be late: sent, or became the oldest live request (the
    #: FC answers in order, so a request queued behind others is not late yet).
    clock_start_s: float
    index: int
    #: A later reply (or a corrupted reply to it) proved that no reply will come.
    lost: bool = False
    #: Timed out, but its reply may still arrive late: kept in place to absorb that reply so
    #: it is not taken for a later request's.  Ghosts expire at ``clock_start_s``.
    ghost: bool = False
    #: Wake bytes sent just before this frame: they sit in the FC's receive ring in front of
    #: it and leave it in the same serial tick.
    wake_bytes_before: int = 0


@dataclass(slots=True)
class ClientStats:
    """Counters since the client was made."""

    requests: int = 0
    replies: int = 0
    error_replies: int = 0
    timeouts: int = 0
    retries: int = 0
    lost_requests: int = 0
    late_replies: int = 0
    stray_replies: int = 0
    checksum_failures: int = 0


class MspClient:
    """Talks MSP to one flight controller over one link.

    Thread-safe: each exchange holds a lock, so an RC thread and a telemetry thread can share
    a client (their requests are serialised, not interleaved).

    Every request raises :class:`MspErrorReply` for an error frame (``!``: unknown to the FC,
    or refused in its state), :class:`MspTimeoutError` when no reply comes (retries
    included), :class:`MspDecodeError` for a reply that does not decode as asked, and
    :class:`LinkError` when the link fails.

    Args:
        link: The open transport (:func:`~bfsitl.link.open_link`); closed with the client.
        timeout_s: Seconds to wait for each reply.
        retries: How many times a read that got no reply is sent again; writes never are.
        max_in_flight_bytes: Bytes of requests in flight at most; None: the link's budget.
        wake_interval_s: Seconds between wake bytes (:data:`WAKE_BYTE`) while waiting;
            "auto" when the link says its peer needs them (a SITL's TCP port), None never.
        clock: The clock timeouts count on, seconds (simulation time in lockstep).
    """

    def __init__(
        self,
        link: Link,
        *,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        max_in_flight_bytes: int | None = None,
        wake_interval_s: float | None | Literal["auto"] = "auto",
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        if wake_interval_s == "auto":
            wake_interval_s = DEFAULT_WAKE_INTERVAL_S if link.wants_wake_bytes else None
        self.wake_interval_s: float | None = wake_interval_s
        self.timeout_s = timeout_s
        self.retries = retries
        if max_in_flight_bytes is None:
            max_in_flight_bytes = link.max_in_flight_bytes
        self.max_in_flight_bytes = max_in_flight_bytes
        self.stats = ClientStats()
        self._clock = clock
        self._parser = MspParser()
        self._lock = threading.RLock()
        self._box_ids: tuple[int, ...] | None = None
        self._ghosts: list[_Pending] = []

    # -- lifecycle -------------------------------------------------------------------------
    def close(self) -> None:
        self.link.close()

    def __enter__(self) -> MspClient:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- core exchange ---------------------------------------------------------------------
    def request(
        self,
        command: int,
        payload: bytes = b"",
        *,
        timeout_s: float | None = None,
        retries: int | None = None,
    ) -> bytes:
        """Send one request and return the reply payload.

        Args:
            command: The MSP command id.
            payload: The request's payload.
            timeout_s: Seconds to wait for the reply; None: the client's.
            retries: Times a read is retried first (writes never are); None: the client's.

        Returns:
            The reply's payload.
        """
        result = self.pipeline(
            [MspRequest(command, bytes(payload))], timeout_s=timeout_s, retries=retries
        )[0]
        if isinstance(result, Exception):
            raise result
        return result

    def pipeline(
        self,
        requests: Iterable[MspRequest],
        *,
        depth: int = 4,
        timeout_s: float | None = None,
        retries: int | None = None,
        on_reply: Callable[[MspRequest, bytes], None] | None = None,
    ) -> list[bytes | MspErrorReply | MspTimeoutError]:
        """Run many requests with up to ``depth`` in flight; results in request order.

        Args:
            requests: The requests; a generator is consumed as the window opens.
            depth: Requests in flight at most (the byte budget may allow fewer).
            timeout_s: Seconds to wait for each reply; None: the client's.
            retries: Times a read is retried first; None: the client's.
            on_reply: Called with each request and its payload as a good reply arrives.

        Returns:
            Per request, its payload or the error it got (the others still complete).
        """
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        retries = self.retries if retries is None else retries
        run = _PipelineRun(self, iter(requests), depth, timeout_s, retries, on_reply)
        with self._lock:
            self._parser.clear_recent_garbage()  # CLI text seen long ago proves nothing now
            run.queue.extend(self._ghosts)
            try:
                # A late reply to an earlier call may already be waiting: let the ghosts take
                # it now, before a new request of the same command could be handed it.
                run.absorb_pending_input()
                run.run()
            finally:
                self._ghosts = [p for p in run.queue if p.ghost]
                for ghost in self._ghosts:
                    ghost.index = -1  # belongs to a finished call: never adopted by a retry
        return [run.results[i] for i in range(run.next_index)]

    def _timeout_message(self, command: int, timeout_s: float) -> str:
        name = _command_name(command)
        text = self._parser.recent_garbage().decode("ascii", "replace")
        if "# " in text or "Entering CLI" in text or "ERROR IN" in text or "$M<" in text:
            return (
                f"no MSP reply to {name} within {timeout_s} s: the port is in CLI mode (it "
                f"echoes text instead of answering). Run `bfsitl cli exit` or call "
                f"CliSession.leave() to return it to MSP."
            )
        return (
            f"no MSP reply to {name} within {timeout_s} s on {self.link.uri}: the FC is busy, "
            f"rebooting, or gone; on a real board check that MSP is enabled on this port"
        )

    # -- typed helpers ---------------------------------------------------------------------
    def get(self, message_type: type[T], payload: bytes = b"") -> T:
        """Request a message by its type and decode the reply: ``client.get(Attitude)``.

        Args:
            message_type: A message class of :mod:`bfsitl.protocol.messages`.
            payload: The request's payload, for messages that take one.

        Returns:
            The decoded reply.
        """
        decodable: Any = message_type
        return decodable.decode(self.request(decodable.COMMAND, payload))

    def send(self, message: _Encodable) -> bytes:
        """Send a request message (``SetModeRange(...)``) and return the raw reply.

        Args:
            message: A message object that encodes a request.

        Returns:
            The reply's payload, as it came.
        """
        return self.request(message.COMMAND, message.encode())

    def multiple(self, commands: Sequence[int]) -> tuple[bytes, ...]:
        """Several parameterless v1 reads in one MSP_MULTIPLE_MSP round trip.

        Args:
            commands: MSP v1 command ids that take no payload.

        Returns:
            One payload per command, in order; empty for one the FC cannot answer.
        """
        request = msg.MultipleMspRequest(tuple(commands))
        reply = msg.MultipleMspReply.decode(self.request(request.COMMAND, request.encode()))
        if len(reply.payloads) != len(request.commands):
            raise MspDecodeError(
                f"MSP_MULTIPLE_MSP: asked for {len(request.commands)} replies, got "
                f"{len(reply.payloads)} (the FC truncates what does not fit its buffer)"
            )
        return reply.payloads

    def box_ids(self, refresh: bool = False) -> tuple[int, ...]:
        """The FC's active boxes (permanent ids) in STATUS flight-mode bit order; cached.

        Args:
            refresh: Ask the FC again instead of answering from the cache.

        Returns:
            The permanent box ids.
        """
        if self._box_ids is None or refresh:
            self._box_ids = self.get(msg.BoxIds).ids
        return self._box_ids

    def telemetry(self) -> Telemetry:
        """Attitude, altitude, status, analog, RC, motors and raw IMU in one round trip."""
        box_ids = self.box_ids()
        return telemetry_from_payloads(self.multiple(TELEMETRY_COMMANDS), self._clock(),
                                        box_ids)

    def telemetry_request(self) -> MspRequest:
        """The request :meth:`telemetry` sends, for pipelining many of them."""
        request = msg.MultipleMspRequest(TELEMETRY_COMMANDS)
        return MspRequest(request.COMMAND, request.encode())

    def decode_telemetry(self, payload: bytes) -> Telemetry:
        """Decode the reply to :meth:`telemetry_request`.

        Args:
            payload: The MSP_MULTIPLE_MSP reply's payload.

        Returns:
            The snapshot, as :meth:`telemetry` gives it.
        """
        reply = msg.MultipleMspReply.decode(payload)
        return telemetry_from_payloads(reply.payloads, self._clock(), self._box_ids or ())

    # Small conveniences for the commonest reads.
    def api_version(self) -> msg.ApiVersion:
        return self.get(msg.ApiVersion)

    def status(self) -> msg.StatusEx:
        return self.get(msg.StatusEx)

    def attitude(self) -> msg.Attitude:
        return self.get(msg.Attitude)

    def altitude(self) -> msg.Altitude:
        return self.get(msg.Altitude)

    def mode_ranges(self) -> msg.ModeRanges:
        return self.get(msg.ModeRanges)

    def set_mode_range(self, index: int, mode_range: msg.ModeRange) -> None:
        """Write one mode range slot; not saved until :meth:`eeprom_write`.

        Args:
            index: The slot, 0-based.
            mode_range: The mode, its AUX channel and its pulse range.
        """
        self.send(msg.SetModeRange(index, mode_range))

    def eeprom_write(self) -> None:
        """Save the configuration without rebooting (refused with ``!`` while armed)."""
        self.send(msg.EepromWrite())

    def reboot(self) -> None:
        """Reboot the FC.  A SITL process exits on reboot: something must restart it."""
        try:
            self.send(msg.Reboot())
        except LinkClosedError:
            pass  # the SITL may close the socket before the reply is read


class _PipelineRun:
    """One :meth:`MspClient.pipeline` call: the window, the FIFO and the results.

    ``queue`` is the FIFO of requests on the wire in send order: live requests, and ghosts
    (timed out, or answered through a retry, whose other reply may still arrive).  Ghosts
    are mostly at the front; they leave when they expire, when their late reply arrives, or
    when a reply to a later request proves theirs never will.
    """

    def __init__(
        self,
        client: MspClient,
        source: Iterator[MspRequest],
        depth: int,
        timeout_s: float,
        retries: int,
        on_reply: Callable[[MspRequest, bytes], None] | None,
    ) -> None:
        self.client = client
        self.source = source
        self.depth = depth
        self.timeout_s = timeout_s
        self.retries = retries
        self.on_reply = on_reply
        self.queue: deque[_Pending] = deque()
        self.resend: deque[tuple[int, MspRequest]] = deque()
        self.results: dict[int, bytes | MspErrorReply | MspTimeoutError] = {}
        self.attempts: dict[int, int] = {}
        self.next_index = 0
        self.exhausted = False
        #: Wake bytes sent after the newest frame; the FC's idle parser eats them next tick.
        self.trailing_wake_bytes = 0

    def _live(self) -> list[_Pending]:
        return [p for p in self.queue if not p.ghost]

    def _first_live(self) -> _Pending | None:
        return next((p for p in self.queue if not p.ghost), None)

    def run(self) -> None:
        client = self.client
        while True:
            self._expire_ghosts()
            self._fill_window()
            head = self._first_live()
            if head is None:
                return
            now_s = client._clock()
            if head.lost or now_s >= head.clock_start_s + self.timeout_s:
                # Look behind a garbage header before declaring the head lost.
                self._dispatch(client._parser.flush_stalled())
                if head in self.queue and (head.lost or
                                           client._clock() >= head.clock_start_s
                                           + self.timeout_s):
                    self._give_up_on(head)
                continue
            wait_s = head.clock_start_s + self.timeout_s - now_s
            data = client.link.read_some(min(wait_s, client.wake_interval_s or 0.1))
            if data:
                self._dispatch(client._parser.feed(data))
            elif client.wake_interval_s is not None and \
                    self._unconsumed_bytes() < client.max_in_flight_bytes:
                client.link.write(WAKE_BYTE)
                self.trailing_wake_bytes += 1

    def absorb_pending_input(self) -> None:
        """Dispatch bytes that are already buffered, without waiting for more."""
        while True:
            data = self.client.link.read_some(0.0)
            if not data:
                return
            self._dispatch(self.client._parser.feed(data))

    def _unconsumed_bytes(self) -> int:
        """Bytes of ours the FC may not have read yet: frames in flight, wake bytes between.

        Per serial tick the FC reads idle bytes up to one frame and that frame, so a frame's
        reply proves it consumed everything up to that frame.
        """
        return sum(p.frame_size + p.wake_bytes_before for p in self.queue) + \
            self.trailing_wake_bytes

    def _expire_ghosts(self) -> None:
        now_s = self.client._clock()
        while self.queue and self.queue[0].ghost and now_s >= self.queue[0].clock_start_s:
            self.queue.popleft()

    def _fill_window(self) -> None:
        client = self.client
        while len(self._live()) < self.depth:
            if self.resend:
                index, request = self.resend.popleft()
            elif not self.exhausted:
                try:
                    request = next(self.source)
                except StopIteration:
                    self.exhausted = True
                    continue
                index = self.next_index
                self.next_index += 1
            else:
                return
            frame = encode_request(request.command, request.payload)
            # With nothing live outstanding, send anyway: waiting could not free anything.
            if self._live() and \
                    self._unconsumed_bytes() + len(frame) > client.max_in_flight_bytes:
                self.resend.appendleft((index, request))
                return
            client.link.write(frame)
            client.stats.requests += 1
            self.attempts[index] = self.attempts.get(index, 0) + 1
            self.queue.append(_Pending(request, len(frame), client._clock(), index,
                                       wake_bytes_before=self.trailing_wake_bytes))
            self.trailing_wake_bytes = 0

    def _give_up_on(self, pending: _Pending) -> None:
        """The oldest live request got no reply: retry a read, fail anything else."""
        client = self.client
        now_s = client._clock()
        if pending.lost:
            self.queue.remove(pending)  # its reply will never come: no ghost needed
        else:
            client.stats.timeouts += 1
            pending.ghost = True
            pending.clock_start_s = now_s + self.timeout_s  # expiry of the ghost
        self._restart_head_clock()
        command = pending.request.command
        if is_idempotent(command) and self.attempts[pending.index] <= self.retries:
            client.stats.retries += 1
            # 0x03 ends a non-interactive CLI session that a stray 0x02 may have started;
            # harmless to an MSP parser in its idle state.
            client.link.write(b"\x03")
            self.resend.append((pending.index, pending.request))
            return
        self.results[pending.index] = MspTimeoutError(
            client._timeout_message(command, self.timeout_s)
        )

    def _restart_head_clock(self) -> None:
        head = self._first_live()
        if head is not None:
            head.clock_start_s = max(head.clock_start_s, self.client._clock())

    def _best_match(self, command: int) -> int | None:
        """Which outstanding request a reply to ``command`` answers (its queue position).

        The FC answers in order and each intact request exactly once, so a reply to an entry
        means every live entry ahead of it was lost.  The best explanation is the candidate
        that declares the fewest live requests lost; on a tie a live request beats a ghost.
        That keeps a ghost whose request was simply lost from eating the reply to the next
        identical request (a stream of polls), while a late reply to a slow request is not
        taken for its retry queued behind other requests (which would lose those).
        """
        best: tuple[int, bool, int] | None = None
        live_ahead = 0
        for position, pending in enumerate(self.queue):
            if pending.request.command == command:
                key = (live_ahead, pending.ghost, position)
                if best is None or key < best:
                    best = key
            if not pending.ghost and not pending.lost:
                live_ahead += 1
        return None if best is None else best[2]

    def _dispatch(self, events: list[MspFrame | ChecksumFailure]) -> None:
        client = self.client
        for event in events:
            if isinstance(event, ChecksumFailure):
                client.stats.checksum_failures += 1
                # Replies come in order, so a corrupted reply carrying the oldest request's
                # command is that request's reply: retry now instead of waiting out the
                # timeout.  (4.6 SITL corrupts a reply now and then: its main thread appends
                # to the TCP thread's write buffer without a lock.)
                head = self.queue[0] if self.queue else None
                if head is not None and head.request.command == event.command:
                    if head.ghost:
                        self.queue.popleft()
                    elif not head.lost:
                        head.lost = True
                        client.stats.lost_requests += 1
                continue
            if event.direction is Direction.REQUEST:
                # Our own request echoed back (loopback adapter, half-duplex wire).
                client.stats.stray_replies += 1
                continue
            position = self._best_match(event.command)
            if position is None:
                # A reply to a request that has expired, or a pushed frame.
                client.stats.stray_replies += 1
                continue
            # The FC answers in order: every request ahead of the match got no reply and
            # never will.  Ghosts ahead simply go; live ones are lost (retried or failed by
            # the loop at once, without waiting out their timeout).
            pending = self.queue[position]
            for ahead in [self.queue[i] for i in range(position)]:
                if ahead.ghost:
                    self.queue.remove(ahead)
                elif not ahead.lost:
                    ahead.lost = True
                    client.stats.lost_requests += 1
            self.queue.remove(pending)
            if pending.ghost:
                retry = next((p for p in self.queue
                              if not p.ghost and p.index == pending.index), None)
                if retry is None:
                    client.stats.late_replies += 1  # its caller has already moved on
                    continue
                # Only reads are retried, so this reply answers the request whichever copy
                # produced it; the retry becomes the ghost that absorbs the other reply.
                retry.ghost = True
                retry.clock_start_s = client._clock() + self.timeout_s
                pending = retry
            self._restart_head_clock()
            if event.is_error:
                client.stats.error_replies += 1
                self.results[pending.index] = MspErrorReply(event.command)
                continue
            client.stats.replies += 1
            self.results[pending.index] = event.payload
            if self.on_reply is not None:
                self.on_reply(pending.request, event.payload)


def _command_name(command: int) -> str:
    try:
        return f"MSP_{MspCommand(command).name} ({command})"
    except ValueError:
        return f"MSP command {command}"


__all__ = [
    "ClientStats",
    "MspClient",
    "MspRequest",
    "TELEMETRY_COMMANDS",
    "Telemetry",
    "is_idempotent",
]
