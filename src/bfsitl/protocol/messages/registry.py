"""Command id -> message class, and MSP_MULTIPLE_MSP, whose reply decodes its sub-replies
through that table (so the two live in one module: the table lists every message, the batch
reply among them)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any, Self

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol.messages.codec import short_payload
from bfsitl.protocol.messages.config import (
    ArmingConfig,
    FeatureConfig,
    PidAdvanced,
    SetArmingConfig,
    SetFeatureConfig,
)
from bfsitl.protocol.messages.identity import (
    ApiVersion,
    BoardInfo,
    BuildInfo,
    CraftName,
    FcVariant,
    FcVersion,
    McuInfo,
    Uid,
)
from bfsitl.protocol.messages.layout import WireRecord, msp_message
from bfsitl.protocol.messages.modes import BoxIds, BoxNames, ModeRanges, SetModeRange
from bfsitl.protocol.messages.rc import Rc, RcTuning, RxMap, SetRawRc, SetRxMap
from bfsitl.protocol.messages.sensors import (
    Altitude,
    Analog,
    Attitude,
    BatteryState,
    Debug,
    Motor,
    MotorTelemetry,
    RawImu,
    SensorConfigActive,
)
from bfsitl.protocol.messages.status import Status, StatusEx
from bfsitl.protocol.messages.system import EepromWrite, Reboot, RebootReply, Rtc, SetRtc
from bfsitl.protocol.messages.wire_types import RestArray, u8
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MAX_REQUEST_PAYLOAD


@msp_message(MspCommand.MULTIPLE_MSP)
@dataclass(frozen=True, slots=True)
class MultipleMspRequest(WireRecord):
    """MSP_MULTIPLE_MSP (230) request: one U8 command id per parameterless v1 command
    (msp.c:2406-2437). The FC runs them in order and answers in one frame."""

    commands: Annotated[tuple[int, ...], RestArray(u8)]

    def __post_init__(self) -> None:
        if not self.commands:
            raise MspRequestError(
                "MSP_MULTIPLE_MSP needs at least one command (else the FC errors)"
            )
        if len(self.commands) > MAX_REQUEST_PAYLOAD:
            raise MspRequestError(
                f"{len(self.commands)} commands exceed the FC's "
                f"{MAX_REQUEST_PAYLOAD}-byte request buffer"
            )
        for command in self.commands:
            if not 0 <= command <= 254:
                raise MspRequestError(
                    f"command {command} is no v1 id (0..254) and cannot be batched"
                )


@msp_message(MspCommand.MULTIPLE_MSP)
@dataclass(frozen=True, slots=True)
class MultipleMspReply(WireRecord):
    """MSP_MULTIPLE_MSP (230) reply: ``[U8 len][payload]`` per command, in request order
    (msp.c:2420-2434). A failed or unknown command contributes length 0. Commands that would not
    fit the FC's output buffer are left off the end, so there may be fewer sub-replies than
    commands. The length byte is a uint8, so a sub-reply of 256 bytes or more is unusable.

    Written by hand: a run of length-prefixed payloads, on the telemetry hot path."""

    payloads: tuple[bytes, ...]

    def decode_replies(self, commands: Sequence[int]) -> tuple[object | None, ...]:
        """Decode each sub-reply with the type registered for the command that asked for it.

        One entry per command: None where the FC left the command off or it failed (an empty
        sub-reply that the reply type cannot decode). A non-empty sub-reply that does not
        decode raises :class:`MspDecodeError`.
        """
        results: list[object | None] = []
        for i, command in enumerate(commands):
            if i >= len(self.payloads):
                results.append(None)
                continue
            payload = self.payloads[i]
            try:
                results.append(decode_reply(command, payload))
            except MspDecodeError:
                if payload:
                    raise
                results.append(None)
        return tuple(results)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        data = bytes(payload)
        parts: list[bytes] = []
        pos, length = 0, len(data)
        while pos < length:
            end = pos + 1 + data[pos]
            if end > length:
                raise short_payload(f"MSP {cls.__name__}", end, length)
            parts.append(data[pos + 1 : end])
            pos = end
        return cls(tuple(parts))

    def encode(self) -> bytes:
        out = bytearray()
        for part in self.payloads:
            if len(part) > 255:
                raise MspRequestError(
                    f"a sub-reply of {len(part)} bytes does not fit its U8 length"
                )
            out.append(len(part))
            out += part
        return bytes(out)


_REPLY_CLASSES: tuple[type[WireRecord], ...] = (
    ApiVersion, FcVariant, FcVersion, BoardInfo, BuildInfo, McuInfo, CraftName, Uid, Status,
    StatusEx, RawImu, Motor, Rc, Attitude, Altitude, Analog, BatteryState, SensorConfigActive,
    Debug, MotorTelemetry, ArmingConfig, FeatureConfig, RxMap, BoxNames, BoxIds, ModeRanges,
    EepromWrite, RebootReply, Rtc, MultipleMspReply, RcTuning, PidAdvanced,
)  # fmt: skip

_REQUEST_CLASSES: tuple[type[WireRecord], ...] = (
    SetArmingConfig, SetFeatureConfig, SetRxMap, SetModeRange, SetRawRc, EepromWrite, Reboot,
    SetRtc, MultipleMspRequest,
)  # fmt: skip

#: Command id -> class of the FC's reply payload.
REPLY_TYPES: dict[int, type] = {cls.COMMAND: cls for cls in _REPLY_CLASSES}

#: Command id -> class of the request payload (for fakes that play the FC).
REQUEST_TYPES: dict[int, type] = {cls.COMMAND: cls for cls in _REQUEST_CLASSES}


def decode_reply(command: int, payload: bytes) -> Any:
    """Decode a reply payload by command id; unknown ids raise :class:`MspDecodeError`."""
    cls = REPLY_TYPES.get(command)
    if cls is None:
        raise MspDecodeError(f"no reply decoder for MSP command {command}")
    return cls.decode(payload)  # type: ignore[attr-defined]


def decode_request(command: int, payload: bytes) -> Any:
    """Decode a request payload by command id (the FC side); unknown ids raise MspDecodeError."""
    cls = REQUEST_TYPES.get(command)
    if cls is None:
        raise MspDecodeError(f"no request decoder for MSP command {command}")
    return cls.decode(payload)  # type: ignore[attr-defined]
