"""The machinery under :meth:`MspClient.pipeline <bfsitl.fc.msp_client.MspClient.pipeline>`:
requests in flight in a FIFO, replies matched to them in order, retries of reads, ghosts that
absorb late replies (why it works this way: :mod:`bfsitl.fc.msp_client`)."""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from bfsitl.errors import MspErrorReply, MspTimeoutError
from bfsitl.link.base import Link
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import (
    ChecksumFailure,
    Direction,
    MspFrame,
    MspParser,
    encode_request,
)

#: Sent while waiting on a SITL TCP link to make its I/O thread flush replies.
WAKE_BYTE = b"\x00"

#: Commands that change state although their name has no SET in it.
_MUTATING_COMMANDS = frozenset(
    {
        MspCommand.REBOOT,
        MspCommand.EEPROM_WRITE,
        MspCommand.ACC_CALIBRATION,
        MspCommand.MAG_CALIBRATION,
        MspCommand.RESET_CONF,
        MspCommand.DATAFLASH_ERASE,
        MspCommand.COPY_PROFILE,
        MspCommand.SELECT_SETTING,
        MspCommand.CALCULATE_SIMPLIFIED_PID,
        MspCommand.CALCULATE_SIMPLIFIED_GYRO,
        MspCommand.CALCULATE_SIMPLIFIED_DTERM,
        MspCommand.OSD_CHAR_WRITE,
        MspCommand.DISPLAYPORT,
        MspCommand.MSP2_BETAFLIGHT_BIND,
        MspCommand.MSP2_SEND_DSHOT_COMMAND,
        MspCommand.CAMERA_CONTROL,
    }
)


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
class Pending:
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


class PipelineHost(Protocol):
    """What a pipeline run uses of its client (:class:`~bfsitl.fc.msp_client.MspClient`)."""

    link: Link
    stats: ClientStats
    wake_interval_s: float | None
    max_in_flight_bytes: int
    _clock: Callable[[], float]
    _parser: MspParser
    _ghosts: list[Pending]

    def _timeout_message(self, command: int, timeout_s: float) -> str: ...


class PipelineRun:
    """One :meth:`MspClient.pipeline` call: the window, the FIFO and the results.

    ``queue`` is the FIFO of requests on the wire in send order: live requests, and ghosts
    (timed out, or answered through a retry, whose other reply may still arrive).  Ghosts
    are mostly at the front; they leave when they expire, when their late reply arrives, or
    when a reply to a later request proves theirs never will.
    """

    def __init__(
        self,
        client: PipelineHost,
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
        self.queue: deque[Pending] = deque()
        self.resend: deque[tuple[int, MspRequest]] = deque()
        self.results: dict[int, bytes | MspErrorReply | MspTimeoutError] = {}
        self.attempts: dict[int, int] = {}
        self.next_index = 0
        self.exhausted = False
        #: Wake bytes sent after the newest frame; the FC's idle parser eats them next tick.
        self.trailing_wake_bytes = 0

    def _live(self) -> list[Pending]:
        return [p for p in self.queue if not p.ghost]

    def _first_live(self) -> Pending | None:
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
                if head in self.queue and (
                    head.lost or client._clock() >= head.clock_start_s + self.timeout_s
                ):
                    self._give_up_on(head)
                continue
            wait_s = head.clock_start_s + self.timeout_s - now_s
            data = client.link.read_some(min(wait_s, client.wake_interval_s or 0.1))
            if data:
                self._dispatch(client._parser.feed(data))
            elif (
                client.wake_interval_s is not None
                and self._unconsumed_bytes() < client.max_in_flight_bytes
            ):
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
        return (
            sum(p.frame_size + p.wake_bytes_before for p in self.queue) + self.trailing_wake_bytes
        )

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
            frame = request_frame(request)
            # With nothing live outstanding, send anyway: waiting could not free anything.
            if self._live() and self._unconsumed_bytes() + len(frame) > client.max_in_flight_bytes:
                self.resend.appendleft((index, request))
                return
            client.link.write(frame)
            client.stats.requests += 1
            self.attempts[index] = self.attempts.get(index, 0) + 1
            self.queue.append(
                Pending(
                    request,
                    len(frame),
                    client._clock(),
                    index,
                    wake_bytes_before=self.trailing_wake_bytes,
                )
            )
            self.trailing_wake_bytes = 0

    def _give_up_on(self, pending: Pending) -> None:
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
                retry = next(
                    (p for p in self.queue if not p.ghost and p.index == pending.index), None
                )
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


def run_one(
    client: PipelineHost, request: MspRequest, timeout_s: float, retries: int
) -> bytes | MspErrorReply | MspTimeoutError:
    """One request with nothing else on the wire (no ghosts) to a peer that needs no wake
    bytes: what a control loop asks at every step.  The frame goes out and the first read is
    taken; when it holds exactly the reply, that is the answer, with no FIFO, window or
    matching.  Anything else (nothing yet, part of a frame, a stray or corrupted frame, a
    timeout) goes on in a :class:`PipelineRun` that has this request in flight, as if it had
    sent it, so every case ends as :meth:`MspClient.pipeline` would end it."""
    link, parser = client.link, client._parser
    waiting = link.read_some(0.0)
    if waiting:  # bytes nobody asked for: with no ghosts they are strays, as pipeline counts
        PipelineRun(client, iter(()), 1, timeout_s, retries, None)._dispatch(parser.feed(waiting))
    frame = request_frame(request)
    link.write(frame)
    client.stats.requests += 1
    sent_s = client._clock()
    data = link.read_some(min(timeout_s, 0.1))
    events = parser.feed(data) if data else []
    if len(events) == 1:
        event = events[0]
        if (
            isinstance(event, MspFrame)
            and event.command == request.command
            and event.direction is not Direction.REQUEST
        ):
            if event.is_error:
                client.stats.error_replies += 1
                return MspErrorReply(event.command)
            client.stats.replies += 1
            return event.payload
    run = PipelineRun(client, iter(()), 1, timeout_s, retries, None)
    run.exhausted, run.next_index, run.attempts[0] = True, 1, 1
    run.queue.append(Pending(request, len(frame), sent_s, 0))
    try:
        run._dispatch(events)
        run.run()
    finally:
        client._ghosts = [p for p in run.queue if p.ghost]
        for ghost in client._ghosts:
            ghost.index = -1
    return run.results[0]


#: Request frames already encoded: a control loop sends the same few at every step.
_FRAMES: dict[MspRequest, bytes] = {}
_MAX_FRAMES = 256


def request_frame(request: MspRequest) -> bytes:
    """``request`` as a frame on the wire (kept: the same requests recur)."""
    frame = _FRAMES.get(request)
    if frame is None:
        if len(_FRAMES) >= _MAX_FRAMES:
            _FRAMES.clear()
        frame = _FRAMES[request] = encode_request(request.command, request.payload)
    return frame


def command_name(command: int) -> str:
    try:
        return f"MSP_{MspCommand(command).name} ({command})"
    except ValueError:
        return f"MSP command {command}"
