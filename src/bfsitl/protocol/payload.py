"""Little-endian readers and writers for MSP payloads.

Betaflight writes every multi-byte field little-endian (``sbufWriteU16`` and friends).  Newer
firmware appends fields to old messages, so decoders read what they know, tolerate trailing bytes,
and ask :meth:`PayloadReader.remaining` before reading fields that older firmware lacks.
"""

from __future__ import annotations

import struct

from bfsitl.errors import MspDecodeError

_U8 = struct.Struct("<B")
_S8 = struct.Struct("<b")
_U16 = struct.Struct("<H")
_S16 = struct.Struct("<h")
_U32 = struct.Struct("<I")
_S32 = struct.Struct("<i")


class PayloadReader:
    """Reads typed fields from one payload; running past its end raises :class:`MspDecodeError`."""

    __slots__ = ("_data", "_pos", "_what")

    def __init__(self, data: bytes, what: str = "payload") -> None:
        self._data = bytes(data)
        self._pos = 0
        self._what = what

    def remaining(self) -> int:
        return len(self._data) - self._pos

    def _take(self, size: int) -> bytes:
        end = self._pos + size
        if end > len(self._data):
            raise MspDecodeError(f"{self._what}: needs at least {end} bytes, got {len(self._data)}")
        chunk = self._data[self._pos : end]
        self._pos = end
        return chunk

    def _unpack(self, fmt: struct.Struct) -> int:
        return fmt.unpack(self._take(fmt.size))[0]

    def u8(self) -> int:
        return self._unpack(_U8)

    def s8(self) -> int:
        return self._unpack(_S8)

    def u16(self) -> int:
        return self._unpack(_U16)

    def s16(self) -> int:
        return self._unpack(_S16)

    def u32(self) -> int:
        return self._unpack(_U32)

    def s32(self) -> int:
        return self._unpack(_S32)

    def raw(self, size: int) -> bytes:
        return self._take(size)

    def rest(self) -> bytes:
        return self._take(self.remaining())

    def text(self, size: int) -> str:
        """Fixed-size text field; NUL padding is stripped, undecodable bytes replaced."""
        return self._take(size).split(b"\0", 1)[0].decode("ascii", errors="replace")

    def pstr(self) -> str:
        """Length-prefixed (U8) text field."""
        return self.text(self.u8())


class PayloadWriter:
    """Builds a payload field by field."""

    __slots__ = ("_parts",)

    def __init__(self) -> None:
        self._parts: list[bytes] = []

    def u8(self, value: int) -> PayloadWriter:
        self._parts.append(_U8.pack(value))
        return self

    def s8(self, value: int) -> PayloadWriter:
        self._parts.append(_S8.pack(value))
        return self

    def u16(self, value: int) -> PayloadWriter:
        self._parts.append(_U16.pack(value))
        return self

    def s16(self, value: int) -> PayloadWriter:
        self._parts.append(_S16.pack(value))
        return self

    def u32(self, value: int) -> PayloadWriter:
        self._parts.append(_U32.pack(value))
        return self

    def s32(self, value: int) -> PayloadWriter:
        self._parts.append(_S32.pack(value))
        return self

    def raw(self, data: bytes) -> PayloadWriter:
        self._parts.append(bytes(data))
        return self

    def text(self, value: str, size: int | None = None) -> PayloadWriter:
        data = value.encode("ascii")
        if size is not None:
            data = data[:size].ljust(size, b"\0")
        self._parts.append(data)
        return self

    def pstr(self, value: str) -> PayloadWriter:
        data = value.encode("ascii")
        return self.u8(len(data)).raw(data)

    def build(self) -> bytes:
        return b"".join(self._parts)
