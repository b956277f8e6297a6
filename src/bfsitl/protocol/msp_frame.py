"""MSP framing, sans-I/O: build frames, and parse a byte stream split in any way.

Frame formats (Betaflight 4.6 ``src/main/msp/msp_serial.c``):

* v1:          ``$ M dir size cmd payload xor``; xor over size, cmd and payload.
* v1 jumbo:    ``$ M dir 0xFF cmd size_lo size_hi payload xor``; the FC uses it for replies of
  255 bytes or more; xor over 0xFF, cmd, both size bytes and the payload.
* v2 native:   ``$ X dir flag cmd_lo cmd_hi len_lo len_hi payload crc8``; CRC-8/DVB-S2 over
  everything between ``dir`` and the CRC.
* v2 over v1:  a v1 frame with cmd 255 whose payload is ``flag cmd16 len16 payload crc8``.

``dir`` is ``<`` (to the FC), ``>`` (reply) or ``!`` (error reply: unknown or refused command,
always with an empty payload).  A frame with a bad checksum gets no reply from the FC, so a
client only ever learns of it by timeout; this parser, on the host side, reports it as a
:class:`ChecksumFailure` event and carries on.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from enum import Enum

from bfsitl.errors import MspFrameError
from bfsitl.protocol.msp_codes import MSP_V2_OVER_V1

#: The FC's receive buffer (``MSP_PORT_INBUF_SIZE``).  Larger v1 requests are dropped, and a
#: larger v2-native request overruns the buffer and hangs the port until reboot in 4.6.
MAX_REQUEST_PAYLOAD = 192

#: Largest payload the parser believes.  The FC's output buffer is 512 bytes (4096 + 16 with
#: flash logging), so anything claiming more is garbage that happens to look like a header;
#: rejecting it at once keeps such garbage from stalling the frames that follow it.
DEFAULT_MAX_PAYLOAD = 8192

_JUMBO_SIZE = 0xFF


class MspVersion(Enum):
    V1 = "v1"
    V1_JUMBO = "v1-jumbo"
    V2 = "v2"
    V2_OVER_V1 = "v2-over-v1"


class Direction(Enum):
    REQUEST = ord("<")
    REPLY = ord(">")
    ERROR = ord("!")


_DIRECTIONS = {d.value: d for d in Direction}


@dataclass(frozen=True, slots=True)
class MspFrame:
    """One complete, checksum-verified MSP frame."""

    command: int
    payload: bytes
    direction: Direction = Direction.REPLY
    version: MspVersion = MspVersion.V1
    flags: int = 0

    @property
    def is_error(self) -> bool:
        return self.direction is Direction.ERROR


@dataclass(frozen=True, slots=True)
class ChecksumFailure:
    """A frame whose header parsed but whose checksum did not match; it was discarded."""

    version: MspVersion
    command: int
    size: int


ParserEvent = MspFrame | ChecksumFailure


# --- checksums ---------------------------------------------------------------------------------


def _make_crc8_table(poly: int) -> bytes:
    table = bytearray(256)
    for value in range(256):
        crc = value
        for _ in range(8):
            crc = ((crc << 1) ^ poly) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
        table[value] = crc
    return bytes(table)


_CRC8_DVB_S2 = _make_crc8_table(0xD5)


def crc8_dvb_s2(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-8/DVB-S2 (poly 0xD5, init 0, no reflection), as ``common/crc.c`` computes it."""
    table = _CRC8_DVB_S2
    for byte in data:
        crc = table[crc ^ byte]
    return crc


def xor_checksum(data: bytes | bytearray | memoryview) -> int:
    value = 0
    for byte in data:
        value ^= byte
    return value


# --- encoding ----------------------------------------------------------------------------------


def _v2_body(command: int, payload: bytes, flags: int) -> bytes:
    header = bytes(
        (flags & 0xFF, command & 0xFF, command >> 8, len(payload) & 0xFF, len(payload) >> 8)
    )
    body = header + payload
    return body + bytes((crc8_dvb_s2(body),))


def encode_frame(frame: MspFrame) -> bytes:
    """Serialise any frame, replies included (a fake FC uses this); no request-size limit."""
    command, payload, version = frame.command, bytes(frame.payload), frame.version
    direction = frame.direction.value
    if not 0 <= command <= 0xFFFF:
        raise MspFrameError(f"MSP command id {command} is outside 0..65535")
    if version is MspVersion.V2:
        if len(payload) > 0xFFFF:
            raise MspFrameError(f"MSP v2 payload of {len(payload)} bytes exceeds 65535")
        return b"$X" + bytes((direction,)) + _v2_body(command, payload, frame.flags)
    if version is MspVersion.V2_OVER_V1:
        inner = _v2_body(command, payload, frame.flags)
        return _encode_v1(MSP_V2_OVER_V1, inner, direction)
    if command >= MSP_V2_OVER_V1:
        raise MspFrameError(
            f"MSP command {command} does not fit a v1 frame (ids 0..254); use MspVersion.V2"
        )
    if version is MspVersion.V1 and len(payload) >= _JUMBO_SIZE:
        raise MspFrameError(
            f"MSP v1 payload of {len(payload)} bytes needs a jumbo frame (MspVersion.V1_JUMBO)"
        )
    return _encode_v1(command, payload, direction)


def _encode_v1(command: int, payload: bytes, direction: int) -> bytes:
    if len(payload) < _JUMBO_SIZE:
        body = bytes((len(payload), command)) + payload
    elif len(payload) <= 0xFFFF:
        body = bytes((_JUMBO_SIZE, command, len(payload) & 0xFF, len(payload) >> 8)) + payload
    else:
        raise MspFrameError(f"MSP v1 jumbo payload of {len(payload)} bytes exceeds 65535")
    return b"$M" + bytes((direction,)) + body + bytes((xor_checksum(body),))


def encode_request(command: int, payload: bytes = b"", version: MspVersion | None = None) -> bytes:
    """Build a request frame for the FC.

    ``version`` defaults to v1 for ids below 255 and v2 native above.  Payloads over
    :data:`MAX_REQUEST_PAYLOAD` are refused: the FC drops them (v1) or hangs its MSP port
    until reboot (v2 native, 4.6).
    """
    payload = bytes(payload)
    if len(payload) > MAX_REQUEST_PAYLOAD:
        raise MspFrameError(
            f"MSP request payload of {len(payload)} bytes exceeds the FC's "
            f"{MAX_REQUEST_PAYLOAD}-byte receive buffer; split it into smaller requests"
        )
    if version is None:
        version = MspVersion.V1 if command < MSP_V2_OVER_V1 else MspVersion.V2
    if version is MspVersion.V1_JUMBO:
        raise MspFrameError("the FC does not accept jumbo requests; use v1 or v2")
    return encode_frame(MspFrame(command, payload, Direction.REQUEST, version))


# --- parsing -----------------------------------------------------------------------------------


class MspParser:
    """Incremental MSP parser: feed it bytes in any split, get frames and checksum failures.

    Bytes that are not part of a frame (garbage, CLI text on a port left in CLI mode) are
    skipped and counted; the last few hundred are kept for diagnostics.  After a header that
    turns out to be bogus (bad direction, absurd size, bad checksum) the parser rescans from the
    byte after its ``$``, so a valid frame hidden behind garbage is still found.
    """

    def __init__(self, max_payload: int = DEFAULT_MAX_PAYLOAD) -> None:
        self._buffer = bytearray()
        self._max_payload = max_payload
        self._recent_garbage: deque[int] = deque(maxlen=512)
        self.frames_parsed = 0
        self.checksum_failures = 0
        self.garbage_bytes = 0

    @property
    def pending_bytes(self) -> int:
        """Bytes held back as the start of a frame not yet complete."""
        return len(self._buffer)

    def recent_garbage(self) -> bytes:
        """The last skipped non-frame bytes, oldest first (for example CLI text)."""
        return bytes(self._recent_garbage)

    def clear_recent_garbage(self) -> None:
        self._recent_garbage.clear()

    def reset(self) -> None:
        self._buffer.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[ParserEvent]:
        self._buffer += data
        return self._drain()

    def flush_stalled(self) -> list[ParserEvent]:
        """Give up on the incomplete frame at the front and rescan the bytes behind it.

        A garbage ``$M>`` with a large size byte holds back every byte after it until enough
        have arrived to check it; a client that times out waiting calls this to look behind it.
        """
        if not self._buffer:
            return []
        self._skip(1)
        return self._drain()

    def _skip(self, count: int) -> None:
        skipped = self._buffer[:count]
        self.garbage_bytes += len(skipped)
        self._recent_garbage.extend(skipped)
        del self._buffer[:count]

    def _drain(self) -> list[ParserEvent]:
        events: list[ParserEvent] = []
        buf = self._buffer
        while buf:
            start = buf.find(b"$")
            if start < 0:
                self._skip(len(buf))
                break
            if start:
                self._skip(start)
            outcome = self._try_frame()
            if outcome is None:  # need more bytes
                break
            if outcome is _REJECT:
                self._skip(1)
                continue
            assert isinstance(outcome, tuple)  # an (event, bytes used) pair
            event, consumed = outcome
            if isinstance(event, ChecksumFailure):
                # The size field itself may be corrupt, so only the '$' is dropped: a frame
                # inside the claimed span is found on the rescan.
                self.checksum_failures += 1
                self._skip(1)
            else:
                self.frames_parsed += 1
                del buf[:consumed]
            events.append(event)
        return events

    def _try_frame(self) -> tuple[ParserEvent, int] | object | None:
        buf = self._buffer
        if len(buf) < 3:
            return None if _prefix_possible(buf) else _REJECT
        kind, direction_byte = buf[1], buf[2]
        if kind not in (0x4D, 0x58) or direction_byte not in _DIRECTIONS:  # 'M' / 'X'
            return _REJECT
        direction = _DIRECTIONS[direction_byte]
        if kind == 0x4D:
            return self._try_v1(direction)
        return self._try_v2(direction)

    def _try_v1(self, direction: Direction) -> tuple[ParserEvent, int] | object | None:
        buf = self._buffer
        if len(buf) < 5:
            return None
        size, command = buf[3], buf[4]
        header_end = 5
        version = MspVersion.V1
        if size == _JUMBO_SIZE:
            if len(buf) < 7:
                return None
            size = buf[5] | (buf[6] << 8)
            header_end = 7
            version = MspVersion.V1_JUMBO
        if size > self._max_payload:
            return _REJECT
        total = header_end + size + 1
        if len(buf) < total:
            return None
        checksum = xor_checksum(memoryview(buf)[3 : total - 1])
        if checksum != buf[total - 1]:
            return ChecksumFailure(version, command, size), total
        payload = bytes(buf[header_end : total - 1])
        if command == MSP_V2_OVER_V1:
            inner = _unwrap_v2(payload, direction)
            if inner is None:
                return ChecksumFailure(MspVersion.V2_OVER_V1, command, size), total
            return inner, total
        return MspFrame(command, payload, direction, version), total

    def _try_v2(self, direction: Direction) -> tuple[ParserEvent, int] | object | None:
        buf = self._buffer
        if len(buf) < 8:
            return None
        flags = buf[3]
        command = buf[4] | (buf[5] << 8)
        size = buf[6] | (buf[7] << 8)
        if size > self._max_payload:
            return _REJECT
        total = 8 + size + 1
        if len(buf) < total:
            return None
        if crc8_dvb_s2(memoryview(buf)[3 : total - 1]) != buf[total - 1]:
            return ChecksumFailure(MspVersion.V2, command, size), total
        payload = bytes(buf[8 : total - 1])
        return MspFrame(command, payload, direction, MspVersion.V2, flags), total


_REJECT = object()


def _prefix_possible(buf: bytearray) -> bool:
    """Whether the 1-2 bytes held could still grow into a frame header."""
    if len(buf) >= 2 and buf[1] not in (0x4D, 0x58):
        return False
    return True


def _unwrap_v2(block: bytes, direction: Direction) -> MspFrame | None:
    """Decode the v2 frame tunnelled in a v1 cmd-255 payload; None if inconsistent."""
    if len(block) < 6:
        return None
    flags = block[0]
    command = block[1] | (block[2] << 8)
    size = block[3] | (block[4] << 8)
    if len(block) != 5 + size + 1:
        return None
    if crc8_dvb_s2(block[:-1]) != block[-1]:
        return None
    return MspFrame(command, block[5:-1], direction, MspVersion.V2_OVER_V1, flags)
