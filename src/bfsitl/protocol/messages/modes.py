"""Modes: the boxes the FC offers (names and permanent ids) and the AUX ranges that switch them."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, ClassVar, Self

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol.boxes import BOX_NAMES
from bfsitl.protocol.messages.codec import FIT_ERRORS, does_not_fit
from bfsitl.protocol.messages.constants import (
    MAX_AUX_CHANNELS,
    MODE_RANGE_MAX_US,
    MODE_RANGE_MIN_US,
    MODE_RANGE_SLOTS,
    MODE_RANGE_STEP_US,
)
from bfsitl.protocol.messages.layout import (
    WireRecord,
    declared_layout,
    msp_message,
    wire_record,
)
from bfsitl.protocol.messages.wire_types import TAIL, U8, RestArray, u8
from bfsitl.protocol.msp_codes import MspCommand


@msp_message(MspCommand.BOXNAMES)
@dataclass(frozen=True, slots=True)
class BoxNames(WireRecord):
    """MSP_BOXNAMES (116): ``name;name;...;`` for the active boxes of page 0 in internal order
    (msp.c:2355-2360, msp_box.c:140-196). Send a U8 page to get boxes 32+ on big builds.

    Written by hand: names ended by ``;``, no counts."""

    names: tuple[str, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        text = bytes(payload).decode("latin-1")
        parts = text.split(";")
        if parts and parts[-1] == "":
            parts.pop()
        return cls(tuple(parts))

    def encode(self) -> bytes:
        try:
            return "".join(f"{name};" for name in self.names).encode("latin-1")
        except FIT_ERRORS as exc:
            raise does_not_fit(self, exc) from exc


@msp_message(MspCommand.BOXIDS)
@dataclass(frozen=True, slots=True)
class BoxIds(WireRecord):
    """MSP_BOXIDS (119): one U8 permanent id per active box, same order as BOXNAMES
    (msp.c:2361-2366). Position i here is bit i of the STATUS flight-mode flags."""

    ids: Annotated[tuple[int, ...], RestArray(u8)]


@wire_record
@dataclass(frozen=True, slots=True)
class ModeRange(WireRecord):
    """One mode activation condition: box (permanent id), AUX channel (0 = AUX1), and a range in
    25 us steps from 900 us (fc/rc_modes.h:96-110). A slot is used when start < end
    (``IS_RANGE_USABLE``, rc_modes.h:142); unused slots read all zero."""

    SIZE: ClassVar[int] = 4
    box_id: U8
    aux_channel_index: U8
    start_step: U8
    end_step: U8

    @property
    def start_us(self) -> int:
        return MODE_RANGE_MIN_US + MODE_RANGE_STEP_US * self.start_step

    @property
    def end_us(self) -> int:
        return MODE_RANGE_MIN_US + MODE_RANGE_STEP_US * self.end_step

    @property
    def is_used(self) -> bool:
        return self.start_step < self.end_step

    @classmethod
    def from_us(cls, box_id: int, aux_channel_index: int, start_us: int, end_us: int) -> Self:
        """A range from microseconds, e.g. ARM on AUX1 high: ``from_us(0, 0, 1700, 2100)``."""
        for label, us in (("start_us", start_us), ("end_us", end_us)):
            if not MODE_RANGE_MIN_US <= us <= MODE_RANGE_MAX_US:
                raise MspRequestError(f"{label} {us} is outside 900..2100 us")
            if (us - MODE_RANGE_MIN_US) % MODE_RANGE_STEP_US:
                raise MspRequestError(f"{label} {us} is not a multiple of 25 us")
        if start_us >= end_us:
            raise MspRequestError(f"start_us {start_us} must be below end_us {end_us}")
        if not 0 <= aux_channel_index < MAX_AUX_CHANNELS:
            raise MspRequestError(f"aux_channel_index {aux_channel_index} is not 0..13 (AUX1..14)")
        if not 0 <= box_id <= 255:
            raise MspRequestError(f"box_id {box_id} is not a U8")
        step = MODE_RANGE_STEP_US
        return cls(
            box_id,
            aux_channel_index,
            (start_us - MODE_RANGE_MIN_US) // step,
            (end_us - MODE_RANGE_MIN_US) // step,
        )


@msp_message(MspCommand.MODE_RANGES)
@dataclass(frozen=True, slots=True)
class ModeRanges(WireRecord):
    """MSP_MODE_RANGES (34): 20 x {U8 permanent id, U8 AUX index, U8 start, U8 end}
    (msp.c:1403-1412)."""

    ranges: Annotated[tuple[ModeRange, ...], RestArray(ModeRange)]

    @property
    def used(self) -> tuple[tuple[int, ModeRange], ...]:
        """(slot index, range) of the slots in use."""
        return tuple((i, rng) for i, rng in enumerate(self.ranges) if rng.is_used)


@msp_message(MspCommand.SET_MODE_RANGE)
@dataclass(frozen=True, slots=True)
class SetModeRange(WireRecord):
    """MSP_SET_MODE_RANGE (35) request: U8 slot, the 4 range bytes, optionally U8 mode logic
    (0 OR, 1 AND) and U8 linked permanent id (msp.c:2761-2785). Applied at once, RAM only until
    saved; an unknown box id or slot >= 20 gets an error reply.

    4.6 dereferences the box found for ``linked_to`` without a NULL check (msp.c:2776), so an
    unknown linked id would crash the FC; this class only accepts known permanent ids there.
    """

    index: U8
    range: ModeRange
    mode_logic: Annotated[U8 | None, TAIL] = None
    linked_to: U8 | None = None

    def __post_init__(self) -> None:
        if not 0 <= self.index < MODE_RANGE_SLOTS:
            raise MspRequestError(f"mode range slot {self.index} is not 0..19")
        if (self.mode_logic is None) != (self.linked_to is None):
            raise MspRequestError("mode_logic and linked_to go together: give both or neither")
        if self.mode_logic is not None and self.mode_logic not in (0, 1):
            raise MspRequestError(f"mode_logic {self.mode_logic} is not 0 (OR) or 1 (AND)")
        if self.linked_to is not None and self.linked_to not in BOX_NAMES:
            raise MspRequestError(
                f"linked_to {self.linked_to} is no permanent box id of 4.6 (it would crash the FC)"
            )

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        # The two tail fields go together; half of them is a broken payload, said plainly.
        index, rng, *tail = declared_layout(cls).decode_values(payload)
        if len(tail) == 1:
            raise MspDecodeError("MSP SetModeRange: mode logic without linked box id")
        try:
            return cls(index, rng, *tail)
        except MspRequestError as exc:
            raise MspDecodeError(str(exc)) from exc
