"""Wire types: what one field of an MSP payload looks like in bytes.

A message field names its wire type in its annotation, ``Annotated[python type, wire type]``;
the common integers have aliases, so ``vbat_dv: U8`` reads as the firmware's ``sbufWriteU8``.
Betaflight writes every multi-byte field little-endian (``sbufWriteU16`` and friends).

The descriptors only describe; :mod:`.codec` turns a list of them into decode and encode
functions, and :mod:`.layout` reads them off a dataclass.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Annotated, Any, TypeAlias


@dataclass(frozen=True, slots=True)
class Int:
    """A little-endian integer; ``code`` is its :mod:`struct` format character."""

    code: str

    @property
    def size(self) -> int:
        return struct.calcsize("<" + self.code)

    @property
    def signed(self) -> bool:
        return self.code.islower()

    @property
    def min(self) -> int:
        return -(1 << (8 * self.size - 1)) if self.signed else 0

    @property
    def max(self) -> int:
        return (1 << (8 * self.size - (1 if self.signed else 0))) - 1


u8 = Int("B")
s8 = Int("b")
u16 = Int("H")
s16 = Int("h")
u32 = Int("I")
s32 = Int("i")

U8: TypeAlias = Annotated[int, u8]
S8: TypeAlias = Annotated[int, s8]
U16: TypeAlias = Annotated[int, u16]
S16: TypeAlias = Annotated[int, s16]
U32: TypeAlias = Annotated[int, u32]
S32: TypeAlias = Annotated[int, s32]


@dataclass(frozen=True, slots=True)
class Text:
    """Text in a fixed number of bytes, NUL padded; decoding stops at the first NUL.

    Latin-1 keeps every byte, so whatever decodes re-encodes to the same bytes."""

    size: int


@dataclass(frozen=True, slots=True)
class Raw:
    """Exactly ``size`` bytes, kept as they are."""

    size: int


@dataclass(frozen=True, slots=True)
class PStr:
    """Text after a U8 byte count (the firmware's ``sbufWritePString``)."""


@dataclass(frozen=True, slots=True)
class RestText:
    """Text filling the rest of the payload, no count and no terminator (MSP_NAME)."""


@dataclass(frozen=True, slots=True)
class Array:
    """``count`` integers in a row, held as a tuple.

    Encoding a tuple of another length raises :class:`MspRequestError` with ``count_error``
    (formatted with ``count`` and ``got``), unless ``fill`` is given: then a shorter tuple is
    padded with it (MSP_MOTOR always carries 8 motors)."""

    item: Int
    count: int
    fill: int | None = None
    count_error: str | None = None


@dataclass(frozen=True, slots=True)
class RestArray:
    """Items to the end of the payload, no count before them; ``item`` is an :class:`Int` or
    a record class (:func:`.layout.wire_record`). ``label`` is added to the error message of a
    payload that is not a whole number of items."""

    item: Any
    label: str = ""


@dataclass(frozen=True, slots=True)
class Counted:
    """A ``count`` integer, then that many items (an :class:`Int` or a record class)."""

    count: Int
    item: Any


@dataclass(frozen=True, slots=True)
class Nested:
    """A record class (:func:`.layout.wire_record`) inline; a field annotated with a record
    class gets this wire type without saying so."""

    record: Any


@dataclass(frozen=True, slots=True)
class Pad:
    """``size`` bytes before the field that the firmware writes as 0 and nobody reads (retired
    fields); decoding skips them, encoding writes zeros."""

    size: int


@dataclass(frozen=True, slots=True)
class Tail:
    """Put on the first field that older firmware does not send; it and every field after it
    are optional.

    Decoding reads them in order while bytes remain and leaves the rest at their defaults
    (None); a field cut short is an error, unless ``cut_is_absent``: then it is absent too.
    Encoding writes them in order up to the first one that is None."""

    cut_is_absent: bool = False


#: Fields from here on are newer firmware's; a field cut in half is a broken payload.
TAIL = Tail()
#: As :data:`TAIL`, but a field cut short reads as absent (MSP_RAW_GPS's PDOP and
#: MSP_RC_TUNING's rates type were always read only when whole).
TAIL_IF_WHOLE = Tail(cut_is_absent=True)

#: The wire types a field can have (Pad and Tail only qualify one).
WIRE_TYPES = (Int, Text, Raw, PStr, RestText, Array, RestArray, Counted, Nested)
Wire: TypeAlias = Int | Text | Raw | PStr | RestText | Array | RestArray | Counted | Nested


@dataclass(frozen=True, slots=True)
class WireField:
    """One dataclass field as the codec sees it: its name, wire type, the padding bytes before
    it, whether it is in the optional tail, and for a tail field the value it has when absent
    (its default; only a None default makes None mean "absent" when encoding)."""

    name: str
    wire: Wire
    pad_bytes: int = 0
    in_tail: bool = False
    absent: Any = None

    @property
    def fixed_size(self) -> int | None:
        """Bytes on the wire, padding included; None when the size depends on the value."""
        size = _fixed_size(self.wire)
        return None if size < 0 else size + self.pad_bytes


def _fixed_size(wire: Wire) -> int:
    """Size of a fixed-size wire type, -1 for the variable ones."""
    if isinstance(wire, Int):
        return wire.size
    if isinstance(wire, Text | Raw):
        return wire.size
    if isinstance(wire, Array):
        return wire.item.size * wire.count
    if isinstance(wire, Nested):
        size = wire.record.LAYOUT.size
        return -1 if size is None else int(size)
    return -1
