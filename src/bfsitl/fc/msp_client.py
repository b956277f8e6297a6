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
from collections.abc import Callable, Iterable, Sequence
from typing import Any, ClassVar, Literal, Protocol, TypeVar

from bfsitl.errors import LinkClosedError, MspDecodeError, MspErrorReply, MspTimeoutError
from bfsitl.fc.msp_pipeline import (
    WAKE_BYTE,
    ClientStats,
    MspRequest,
    Pending,
    PipelineRun,
    command_name,
    is_idempotent,
    run_one,
)
from bfsitl.fc.telemetry import TELEMETRY_COMMANDS, Telemetry, telemetry_from_payloads
from bfsitl.link.base import Link
from bfsitl.link.serial_link import SerialLink
from bfsitl.link.tcp_link import TcpLink
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_frame import (
    MspParser,
)

DEFAULT_TIMEOUT_S = 0.5
#: How often to send it: well under the SITL's 10 ms select timeout.
DEFAULT_WAKE_INTERVAL_S = 0.001
DEFAULT_RETRIES = 2
#: What a SITL's TCP port and a real UART take in flight (each link says which applies).
TCP_MAX_IN_FLIGHT_BYTES = TcpLink.max_in_flight_bytes
SERIAL_MAX_IN_FLIGHT_BYTES = SerialLink.max_in_flight_bytes

T = TypeVar("T")


class _Encodable(Protocol):
    COMMAND: ClassVar[int]

    def encode(self) -> bytes: ...


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
        self._ghosts: list[Pending] = []

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
        request = MspRequest(command, bytes(payload))
        with self._lock:
            if self.wake_interval_s is None and not self._ghosts:
                # Nothing else on the wire: the direct path (the same outcomes, less work).
                self._parser.clear_recent_garbage()
                result = run_one(
                    self,
                    request,
                    self.timeout_s if timeout_s is None else timeout_s,
                    self.retries if retries is None else retries,
                )
            else:
                result = self.pipeline([request], timeout_s=timeout_s, retries=retries)[0]
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
        run = PipelineRun(self, iter(requests), depth, timeout_s, retries, on_reply)
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
        name = command_name(command)
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
        return self.telemetry_and(())[0]

    def telemetry_and(self, extra: Sequence[int]) -> tuple[Telemetry, tuple[bytes, ...]]:
        """:meth:`telemetry` and the parameterless reads ``extra`` in the same round trip.

        Args:
            extra: MSP v1 command ids that take no payload (``MspCommand.RAW_GPS``, ...).

        Returns:
            The snapshot, and one payload per extra command, in order: empty for one the FC
            cannot answer (ask it alone to hear why).
        """
        box_ids = self.box_ids()
        payloads = self.multiple((*TELEMETRY_COMMANDS, *extra))
        count = len(TELEMETRY_COMMANDS)
        telemetry = telemetry_from_payloads(payloads[:count], self._clock(), box_ids)
        return telemetry, payloads[count:]

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


__all__ = [
    "WAKE_BYTE",
    "ClientStats",
    "MspClient",
    "MspRequest",
    "TELEMETRY_COMMANDS",
    "Telemetry",
    "is_idempotent",
]
