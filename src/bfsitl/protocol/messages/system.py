"""Control of the FC itself: save, reboot, and its real-time clock."""

from __future__ import annotations

import time
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import IntEnum
from typing import Annotated, Self

from bfsitl.errors import MspRequestError
from bfsitl.protocol.messages.layout import WireRecord, declared_layout, msp_message
from bfsitl.protocol.messages.wire_types import S32, TAIL, U8, U16, u8
from bfsitl.protocol.msp_codes import MspCommand


class RebootMode(IntEnum):
    """MSP_REBOOT modes (msp.c:166-173)."""

    FIRMWARE = 0
    BOOTLOADER_ROM = 1
    MSC = 2
    MSC_UTC = 3
    BOOTLOADER_FLASH = 4


@msp_message(MspCommand.EEPROM_WRITE)
@dataclass(frozen=True, slots=True)
class EepromWrite(WireRecord):
    """MSP_EEPROM_WRITE (250): empty request and empty reply (msp.c:3398-3415). Saves without
    rebooting; refused with an error reply while armed."""


@msp_message(MspCommand.REBOOT)
@dataclass(frozen=True, slots=True)
class Reboot(WireRecord):
    """MSP_REBOOT (68) request: [U8 mode] (msp.c:2367-2404; absent = firmware). The FC reboots
    after replying, even while armed; on SITL a reboot ends the process."""

    mode: Annotated[int, u8, TAIL] = RebootMode.FIRMWARE


@msp_message(MspCommand.REBOOT)
@dataclass(frozen=True, slots=True)
class RebootReply(WireRecord):
    """MSP_REBOOT (68) reply: U8 mode, plus U8 ready flag for MSC mode (msp.c:2382-2393)."""

    mode: U8
    msc_ready: Annotated[U8 | None, TAIL] = None


@msp_message(MspCommand.SET_RTC)
@dataclass(frozen=True, slots=True)
class SetRtc(WireRecord):
    """MSP_SET_RTC (246) request: U32 unix seconds (read as int32), U16 milliseconds
    (msp.c:4052-4063). Until it is set, MSP_RTC answers with an empty payload."""

    unix_seconds: S32  # the FC reads it as int32; __post_init__ keeps it >= 0, so U32 alike
    millis: U16 = 0

    def __post_init__(self) -> None:
        if not 0 <= self.unix_seconds < 2**31:
            raise MspRequestError(f"unix_seconds {self.unix_seconds} does not fit an int32 >= 0")
        if not 0 <= self.millis < 1000:
            raise MspRequestError(f"millis {self.millis} is not 0..999")

    @classmethod
    def from_timestamp(cls, timestamp: float | None = None) -> Self:
        """From a unix time in seconds (default: now)."""
        ts = time.time() if timestamp is None else timestamp
        seconds = int(ts)
        return cls(seconds, min(999, int(round((ts - seconds) * 1000))))


@msp_message(MspCommand.RTC)
@dataclass(frozen=True, slots=True)
class Rtc(WireRecord):
    """MSP_RTC (247): U16 year, U8 month, day, hours, minutes, seconds, U16 millis, UTC
    (msp.c:2204-2217). Empty while the clock was never set (then every field is None)."""

    year: U16 | None = None
    month: U8 | None = None
    day: U8 | None = None
    hours: U8 | None = None
    minutes: U8 | None = None
    seconds: U8 | None = None
    millis: U16 | None = None

    @property
    def is_set(self) -> bool:
        return self.year is not None

    @property
    def datetime_utc(self) -> datetime | None:
        """The FC time as an aware UTC datetime, None when not set."""
        if self.year is None:
            return None
        return datetime(
            self.year,
            self.month or 0,
            self.day or 0,
            self.hours or 0,
            self.minutes or 0,
            self.seconds or 0,
            (self.millis or 0) * 1000,
            tzinfo=UTC,
        )

    # By hand around the layout: an empty payload means "not set", else every field is there.
    @classmethod
    def decode(cls, payload: bytes) -> Self:
        if not len(payload):
            return cls()
        return cls(*declared_layout(cls).decode_values(payload))

    def encode(self) -> bytes:
        if self.year is None:
            return b""
        fields = (self.month, self.day, self.hours, self.minutes, self.seconds, self.millis)
        if any(value is None for value in fields):
            raise MspRequestError("Rtc: either all fields or none")
        return declared_layout(type(self)).encode(self)
