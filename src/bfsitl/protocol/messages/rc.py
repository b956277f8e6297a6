"""RC input: the channels the FC sees, the ones MSP sends it, the channel map, stick rates."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, ClassVar, Self

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol.messages.constants import (
    DEFAULT_RCMAP,
    MAX_RC_CHANNELS,
    RC_MAP_LETTERS,
    RX_MAP_CHANNELS,
)
from bfsitl.protocol.messages.layout import WireRecord, declared_layout, msp_message
from bfsitl.protocol.messages.wire_types import (
    TAIL_IF_WHOLE,
    U8,
    Array,
    Pad,
    RestArray,
    u8,
    u16,
)
from bfsitl.protocol.msp_codes import MspCommand


@msp_message(MspCommand.RC)
@dataclass(frozen=True, slots=True)
class Rc(WireRecord):
    """MSP_RC (105): one U16 per receiver channel, in us, in the FC's INTERNAL order roll, pitch,
    yaw, throttle, AUX1... (msp.c:1311-1315) - not the AETR order MSP_SET_RAW_RC takes.

    The count is the receiver's (18 for MSP RX, 16 after the SITL's UDP RC took over). Only the
    first ``max_aux_channels + 4`` are processed (10 on SITL); the rest read 1500. Master's UDP
    receiver reports no channels at all until the first RC packet: an empty reply is valid
    (:attr:`has_channels` False), and the stick properties then read 0.
    """

    channels_us: Annotated[tuple[int, ...], RestArray(u16)]

    @property
    def has_channels(self) -> bool:
        return bool(self.channels_us)

    def _channel(self, index: int) -> int:
        return self.channels_us[index] if index < len(self.channels_us) else 0

    @property
    def roll_us(self) -> int:
        return self._channel(0)

    @property
    def pitch_us(self) -> int:
        return self._channel(1)

    @property
    def yaw_us(self) -> int:
        return self._channel(2)

    @property
    def throttle_us(self) -> int:
        return self._channel(3)

    @property
    def aux_us(self) -> tuple[int, ...]:
        """AUX1 onwards (``aux_us[0]`` is AUX1, ``aux_channel_index`` 0 of a mode range)."""
        return self.channels_us[4:]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        # The layout reads any number of channels; a receiver has none or at least the sticks.
        (channels,) = declared_layout(cls).decode_values(payload)
        if 0 < len(channels) < 4:
            raise MspDecodeError(
                f"MSP Rc: needs 0 or at least 4 channels (8 bytes), got {len(payload)} bytes"
            )
        return cls(channels)


@msp_message(MspCommand.SET_RAW_RC)
@dataclass(frozen=True, slots=True)
class SetRawRc(WireRecord):
    """MSP_SET_RAW_RC (200) request: N x U16 channel values in us, N <= 18 (msp.c:2715-2730).

    Channels are in the RECEIVER (map) order, ``AETR1234`` by default: roll, pitch, THROTTLE,
    YAW, AUX1... Use :meth:`from_sticks` to build it from named sticks. Channels not sent are
    set to 0 (rx/msp.c:54-57), i.e. invalid, so send every channel you rely on, every time.
    The reply is an empty ACK, even when MSP is not the active receiver.
    """

    channels_us: Annotated[tuple[int, ...], RestArray(u16)]

    def __post_init__(self) -> None:
        if not 1 <= len(self.channels_us) <= MAX_RC_CHANNELS:
            raise MspRequestError(
                f"MSP_SET_RAW_RC takes 1..{MAX_RC_CHANNELS} channels, got {len(self.channels_us)}"
            )
        for value in self.channels_us:
            if not 0 <= value <= 0xFFFF:
                raise MspRequestError(f"RC channel value {value} does not fit a U16")

    @classmethod
    def from_sticks(
        cls,
        roll_us: int,
        pitch_us: int,
        yaw_us: int,
        throttle_us: int,
        aux_us: Sequence[int] = (),
        rcmap: Sequence[int] = DEFAULT_RCMAP,
    ) -> Self:
        """Place named channels where the FC's channel map (MSP_RX_MAP) reads them."""
        internal = [roll_us, pitch_us, yaw_us, throttle_us, *aux_us]
        if sorted(rcmap) != list(range(RX_MAP_CHANNELS)):
            raise MspRequestError(f"rcmap must be a permutation of 0..7, got {tuple(rcmap)}")
        wire = list(internal)
        for channel, value in enumerate(internal[:RX_MAP_CHANNELS]):
            raw = rcmap[channel]
            if raw >= len(internal):
                raise MspRequestError(
                    f"the channel map puts internal channel {channel} on raw channel {raw}; "
                    f"send at least {raw + 1} channels"
                )
            wire[raw] = value
        return cls(tuple(wire))

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        # The FC's own count check, said as the FC would refuse it (not as __post_init__ does).
        (channels,) = declared_layout(cls).decode_values(payload)
        if not 1 <= len(channels) <= MAX_RC_CHANNELS:
            raise MspDecodeError(f"MSP SetRawRc: {len(channels)} channels, the FC takes 1..18")
        return cls(channels)


@msp_message(MspCommand.RX_MAP)
@dataclass(frozen=True, slots=True)
class RxMap(WireRecord):
    """MSP_RX_MAP (64): 8 x U8, for each internal channel (roll, pitch, yaw, throttle, AUX1-4)
    the raw (wire) channel index it reads (msp.c:1671-1673, rx/rx.c:659-683). Default AETR:
    0, 1, 3, 2, 4, 5, 6, 7."""

    rcmap: Annotated[
        tuple[int, ...],
        Array(u8, RX_MAP_CHANNELS, count_error="a channel map has {count} entries, got {got}"),
    ]

    @property
    def letters(self) -> str:
        """The map as the CLI ``map`` command prints it (cli/cli.c:3510-3511), e.g. AETR1234."""
        slots = ["?"] * RX_MAP_CHANNELS
        for internal, raw in enumerate(self.rcmap[:RX_MAP_CHANNELS]):
            if raw < RX_MAP_CHANNELS:
                slots[raw] = RC_MAP_LETTERS[internal]
        return "".join(slots)

    @classmethod
    def from_letters(cls, letters: str) -> Self:
        """Parse a CLI-style map ("AETR1234", "TAER1234") like parseRcChannels (rx/rx.c:801)."""
        text = letters.upper()
        if len(text) != RX_MAP_CHANNELS or sorted(text) != sorted(RC_MAP_LETTERS):
            raise MspRequestError(
                f"a channel map is 8 letters using each of AERT1234 once: {letters!r}"
            )
        return cls(tuple(text.index(letter) for letter in RC_MAP_LETTERS))


@msp_message(MspCommand.SET_RX_MAP)
@dataclass(frozen=True, slots=True)
class SetRxMap(RxMap):
    """MSP_SET_RX_MAP (65) request, 8 x U8 (msp.c:3931-3935).

    4.6 reads 8 bytes without a length check and uses each entry as an array index, so this
    class only accepts a permutation of 0..7 (what the CLI ``map`` command enforces).
    """

    def __post_init__(self) -> None:
        if sorted(self.rcmap) != list(range(RX_MAP_CHANNELS)):
            raise MspRequestError(f"channel map must be a permutation of 0..7, got {self.rcmap}")


@msp_message(MspCommand.RC_TUNING)
@dataclass(frozen=True, slots=True)
class RcTuning(WireRecord):
    """MSP_RC_TUNING (111), the parts that shape the sticks: per-axis RC rate (Actual rates:
    centre sensitivity, 10 deg/s units), expo (percent) and rate (Actual: the maximum, 10 deg/s
    units), and the rates type (4.6.0 and master msp.c: rcRates[R], rcExpo[R], rates[R, P, Y],
    5 bytes of throttle fields, rcExpo[Y], rcRates[Y], rcRates[P], rcExpo[P], 2 throttle-limit
    bytes, 3 U16 rate limits, then U8 rates_type from API 1.43)."""

    roll_rc_rate: U8
    roll_expo: U8
    roll_rate: U8
    pitch_rate: U8
    yaw_rate: U8
    # Pad(5): was tpa_rate, thrMid8, thrExpo8, U16 was tpa_breakpoint (written as 0).
    yaw_expo: Annotated[U8, Pad(5)]
    yaw_rc_rate: U8
    pitch_rc_rate: U8
    pitch_expo: U8
    # Pad(8): throttle limit type and percent, three U16 rate limits. Then the rates type:
    # 0 Betaflight, 1 Raceflight, 2 KISS, 3 Actual, 4 Quick.
    rates_type: Annotated[U8 | None, Pad(8), TAIL_IF_WHOLE] = None

    #: ``rates_type`` of Actual rates (the default of 4.6.0 and master).
    ACTUAL: ClassVar[int] = 3
