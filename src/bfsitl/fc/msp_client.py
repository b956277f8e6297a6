"""Synchronous MSP client: requests matched to replies in order, over any :class:`Link`.

Why it is built this way (facts in ``shared/FIRMWARE_FACTS.md``):

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
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

from bfsitl.errors import LinkClosedError, MspDecodeError, MspErrorReply, MspTimeoutError
from bfsitl.link.base import Link
from bfsitl.link.serial_link import SerialLink
from bfsitl.protocol import msp_messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import (
    ChecksumFailure,
    MspFrame,
    MspParser,
    MspVersion,
    encode_request,
)

DEFAULT_TIMEOUT_S = 0.5
DEFAULT_RETRIES = 2
#: Below the SITL's 1400-byte TCP receive ring, with room for an RC frame from another thread.
TCP_MAX_IN_FLIGHT_BYTES = 1024
#: Below a real UART's 256-byte receive buffer.
SERIAL_MAX_IN_FLIGHT_BYTES = 192

#: Commands that change state although their name has no SET in it.
_MUTATING_COMMANDS = frozenset({
    MspCommand.REBOOT, MspCommand.EEPROM_WRITE, MspCommand.ACC_CALIBRATION,
    MspCommand.MAG_CALIBRATION, MspCommand.RESET_CONF, MspCommand.DATAFLASH_ERASE,
    MspCommand.COPY_PROFILE, MspCommand.SELECT_SETTING, MspCommand.CALCULATE_SIMPLIFIED_PID,
    MspCommand.CALCULATE_SIMPLIFIED_GYRO, MspCommand.CALCULATE_SIMPLIFIED_DTERM,
    MspCommand.OSD_CHAR_WRITE, MspCommand.DISPLAYPORT, MspCommand.MSP2_BETAFLIGHT_BIND,
    MspCommand.MSP2_SEND_DSHOT_COMMAND,
})

#: What :meth:`MspClient.telemetry` asks for in one MSP_MULTIPLE_MSP round trip.
TELEMETRY_COMMANDS: tuple[int, ...] = (
    MspCommand.ATTITUDE, MspCommand.ALTITUDE, MspCommand.STATUS_EX, MspCommand.ANALOG,
    MspCommand.RC, MspCommand.MOTOR,
)

T = TypeVar("T")


class _Decodable(Protocol):
    COMMAND: Any

    @classmethod
    def decode(cls, payload: bytes) -> Any: ...


class _Encodable(Protocol):
    COMMAND: Any

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


@dataclass(slots=True)
class _Pending:
    request: MspRequest
    frame_size: int
    #: When the reply could start to be late: sent, or became the oldest outstanding request
    #: (the FC answers in order, so a request queued behind others is not late yet).
    clock_start_s: float
    index: int
    lost: bool = False


@dataclass(slots=True)
class ClientStats:
    """Counters since the client was made."""

    requests: int = 0
    replies: int = 0
    error_replies: int = 0
    timeouts: int = 0
    retries: int = 0
    lost_requests: int = 0
    stray_replies: int = 0
    checksum_failures: int = 0


@dataclass(frozen=True, slots=True)
class Telemetry:
    """One consistent snapshot of the FC's flight state, taken in one round trip."""

    received_at_s: float
    attitude: msg.Attitude
    altitude: msg.Altitude
    status: msg.StatusEx
    analog: msg.Analog
    rc: msg.Rc
    motors: msg.Motor
    box_ids: tuple[int, ...] = field(default=())

    @property
    def armed(self) -> bool:
        return self.status.armed

    @property
    def arming_blockers(self) -> tuple[str, ...]:
        """CLI names of the flags that currently block arming (empty when it may arm)."""
        return tuple(info.cli_name for info in self.status.arming_blockers)

    @property
    def flight_modes(self) -> tuple[str, ...]:
        from bfsitl.protocol.boxes import decode_flight_modes

        return decode_flight_modes(self.status.flight_mode_flags, self.box_ids)


class MspClient:
    """Talks MSP to one flight controller over one link.

    Thread-safe: each exchange holds a lock, so an RC thread and a telemetry thread can share
    a client (their requests are serialised, not interleaved).
    """

    def __init__(
        self,
        link: Link,
        *,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        retries: int = DEFAULT_RETRIES,
        max_in_flight_bytes: int | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.retries = retries
        if max_in_flight_bytes is None:
            max_in_flight_bytes = (
                SERIAL_MAX_IN_FLIGHT_BYTES if isinstance(link, SerialLink)
                else TCP_MAX_IN_FLIGHT_BYTES
            )
        self.max_in_flight_bytes = max_in_flight_bytes
        self.stats = ClientStats()
        self._clock = clock
        self._parser = MspParser()
        self._lock = threading.RLock()
        self._box_ids: tuple[int, ...] | None = None

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

        Raises :class:`MspErrorReply` when the FC answers ``!`` and :class:`MspTimeoutError`
        when no reply comes; reads are retried ``retries`` times first, writes never.
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

        Each result is the reply payload, or the :class:`MspErrorReply` /
        :class:`MspTimeoutError` for that request (the others still complete).  ``requests``
        may be a generator: it is consumed as the window opens.  ``on_reply`` is called for
        every successful reply as it arrives.
        """
        timeout_s = self.timeout_s if timeout_s is None else timeout_s
        retries = self.retries if retries is None else retries
        source = iter(requests)
        results: dict[int, bytes | MspErrorReply | MspTimeoutError] = {}
        attempts: dict[int, int] = {}
        in_flight: deque[_Pending] = deque()
        resend: deque[tuple[int, MspRequest]] = deque()
        next_index = 0
        exhausted = False
        with self._lock:
            while True:
                # Fill the window: retries first (they are older), then fresh requests.
                while len(in_flight) < depth:
                    if resend:
                        index, request = resend.popleft()
                    elif not exhausted:
                        try:
                            request = next(source)
                        except StopIteration:
                            exhausted = True
                            continue
                        index = next_index
                        next_index += 1
                    else:
                        break
                    frame = encode_request(request.command, request.payload)
                    bytes_in_flight = sum(p.frame_size for p in in_flight)
                    if in_flight and bytes_in_flight + len(frame) > self.max_in_flight_bytes:
                        resend.appendleft((index, request))
                        break
                    self.link.write(frame)
                    self.stats.requests += 1
                    attempts[index] = attempts.get(index, 0) + 1
                    in_flight.append(_Pending(request, len(frame), self._clock(), index))
                if not in_flight:
                    break
                head = in_flight[0]
                wait_s = head.clock_start_s + timeout_s - self._clock()
                if wait_s <= 0 or head.lost:
                    # Look behind a garbage header before declaring the head lost.
                    self._dispatch(self._parser.flush_stalled(), in_flight, results, on_reply)
                    if in_flight and in_flight[0] is head:
                        in_flight.popleft()
                        self._handle_timeout(head, attempts, retries, resend, results,
                                             timeout_s)
                    continue
                data = self.link.read_some(min(wait_s, 0.1))
                if data:
                    self._dispatch(self._parser.feed(data), in_flight, results, on_reply)
        return [results[i] for i in range(next_index)]

    def _handle_timeout(
        self,
        pending: _Pending,
        attempts: dict[int, int],
        retries: int,
        resend: deque[tuple[int, MspRequest]],
        results: dict[int, bytes | MspErrorReply | MspTimeoutError],
        timeout_s: float,
    ) -> None:
        self.stats.timeouts += 1
        command = pending.request.command
        if is_idempotent(command) and attempts[pending.index] <= retries:
            self.stats.retries += 1
            # 0x03 ends a non-interactive CLI session that a stray 0x02 may have started;
            # harmless to an MSP parser in its idle state.
            self.link.write(b"\x03")
            resend.append((pending.index, pending.request))
            return
        results[pending.index] = MspTimeoutError(self._timeout_message(command, timeout_s))

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

    def _dispatch(
        self,
        events: list[MspFrame | ChecksumFailure],
        in_flight: deque[_Pending],
        results: dict[int, bytes | MspErrorReply | MspTimeoutError],
        on_reply: Callable[[MspRequest, bytes], None] | None,
    ) -> None:
        for event in events:
            if isinstance(event, ChecksumFailure):
                self.stats.checksum_failures += 1
                continue
            position = next(
                (i for i, p in enumerate(in_flight) if p.request.command == event.command),
                None,
            )
            if position is None:
                # A late reply to a request that already timed out, or a pushed frame.
                self.stats.stray_replies += 1
                continue
            # The FC answers in order, so every request ahead of the match was lost on the
            # way (a corrupted frame gets no reply).  Mark them overdue: the timeout path then
            # retries or fails them without waiting out their deadline.
            for index in range(position):
                if not in_flight[index].lost:
                    in_flight[index].lost = True
                    self.stats.lost_requests += 1
            pending = in_flight[position]
            del in_flight[position]
            if in_flight and position == 0:
                # The next request only now becomes the one whose reply is due.
                in_flight[0].clock_start_s = max(in_flight[0].clock_start_s, self._clock())
            if event.is_error:
                self.stats.error_replies += 1
                results[pending.index] = MspErrorReply(event.command)
                continue
            self.stats.replies += 1
            results[pending.index] = event.payload
            if on_reply is not None:
                on_reply(pending.request, event.payload)

    # -- typed helpers ---------------------------------------------------------------------
    def get(self, message_type: type[T], payload: bytes = b"") -> T:
        """Request a message by its type and decode the reply: ``client.get(Attitude)``."""
        decodable: Any = message_type
        return decodable.decode(self.request(decodable.COMMAND, payload))

    def send(self, message: _Encodable) -> bytes:
        """Send a request message (``SetModeRange(...)``) and return the raw reply."""
        return self.request(message.COMMAND, message.encode())

    def multiple(self, commands: Sequence[int]) -> tuple[bytes, ...]:
        """Several parameterless v1 reads in one MSP_MULTIPLE_MSP round trip.

        A command the FC cannot answer comes back as an empty payload.
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
        """The FC's active boxes (permanent ids) in STATUS flight-mode bit order; cached."""
        if self._box_ids is None or refresh:
            self._box_ids = self.get(msg.BoxIds).ids
        return self._box_ids

    def telemetry(self) -> Telemetry:
        """Attitude, altitude, status, analog, RC and motors in one round trip."""
        box_ids = self.box_ids()
        return _telemetry_from_payloads(self.multiple(TELEMETRY_COMMANDS), self._clock(),
                                        box_ids)

    def telemetry_request(self) -> MspRequest:
        """The request :meth:`telemetry` sends, for pipelining many of them."""
        request = msg.MultipleMspRequest(TELEMETRY_COMMANDS)
        return MspRequest(request.COMMAND, request.encode())

    def decode_telemetry(self, payload: bytes) -> Telemetry:
        """Decode the reply to :meth:`telemetry_request`."""
        reply = msg.MultipleMspReply.decode(payload)
        return _telemetry_from_payloads(reply.payloads, self._clock(), self._box_ids or ())

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


def _command_name(command: int) -> str:
    try:
        return f"MSP_{MspCommand(command).name} ({command})"
    except ValueError:
        return f"MSP command {command}"


def _telemetry_from_payloads(
    payloads: Sequence[bytes], received_at_s: float, box_ids: tuple[int, ...]
) -> Telemetry:
    if len(payloads) != len(TELEMETRY_COMMANDS):
        raise MspDecodeError(
            f"telemetry: expected {len(TELEMETRY_COMMANDS)} sub-replies, got {len(payloads)}"
        )
    attitude, altitude, status, analog, rc, motors = payloads
    return Telemetry(
        received_at_s=received_at_s,
        attitude=msg.Attitude.decode(attitude),
        altitude=msg.Altitude.decode(altitude),
        status=msg.StatusEx.decode(status),
        analog=msg.Analog.decode(analog),
        rc=msg.Rc.decode(rc),
        motors=msg.Motor.decode(motors),
        box_ids=box_ids,
    )


# Keep MspVersion importable from here for callers choosing a framing explicitly.
__all__ = [
    "ClientStats",
    "MspClient",
    "MspRequest",
    "MspVersion",
    "TELEMETRY_COMMANDS",
    "Telemetry",
    "is_idempotent",
]
