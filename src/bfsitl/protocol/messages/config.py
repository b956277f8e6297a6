"""Configuration the FC keeps: arming settings, features, the ANGLE-mode angle limit."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, ClassVar, Self

from bfsitl.errors import MspDecodeError
from bfsitl.protocol.messages.codec import does_not_fit
from bfsitl.protocol.messages.constants import FEATURE_NAMES, mask_names
from bfsitl.protocol.messages.layout import WireRecord, msp_message
from bfsitl.protocol.messages.wire_types import U8, U32, Pad
from bfsitl.protocol.msp_codes import MspCommand


@msp_message(MspCommand.ARMING_CONFIG)
@dataclass(frozen=True, slots=True)
class ArmingConfig(WireRecord):
    """MSP_ARMING_CONFIG (61): U8 auto-disarm delay s, U8 0, U8 small_angle deg, U8
    gyro_cal_on_first_arm (msp.c:1346-1351). SITL default: 5, 0, 25, 0."""

    auto_disarm_delay_s: U8
    small_angle_deg: Annotated[U8, Pad(1)]  # Pad(1): was disarm_kill_switch, always 0
    gyro_cal_on_first_arm: U8


@msp_message(MspCommand.SET_ARMING_CONFIG)
@dataclass(frozen=True, slots=True)
class SetArmingConfig(ArmingConfig):
    """MSP_SET_ARMING_CONFIG (62) request, same 4 bytes (msp.c:2738-2747). RAM only until saved."""


@msp_message(MspCommand.FEATURE_CONFIG)
@dataclass(frozen=True, slots=True)
class FeatureConfig(WireRecord):
    """MSP_FEATURE_CONFIG (36): U32 CONFIGURED feature mask (msp.c:783-785), not the running one.
    SITL default 0x10404000 = RX_MSP, AIRMODE, ANTI_GRAVITY."""

    feature_mask: U32

    @property
    def features(self) -> tuple[str, ...]:
        return mask_names(self.feature_mask, FEATURE_NAMES)


@msp_message(MspCommand.SET_FEATURE_CONFIG)
@dataclass(frozen=True, slots=True)
class SetFeatureConfig(FeatureConfig):
    """MSP_SET_FEATURE_CONFIG (37) request: U32 mask (msp.c:3782-3784). Replaces the configured
    mask only; the running features change after save + reboot."""


@msp_message(MspCommand.PID_ADVANCED)
@dataclass(frozen=True, slots=True)
class PidAdvanced(WireRecord):
    """MSP_PID_ADVANCED (94), only ``angle_limit``: the ANGLE-mode angle at full stick, in
    degrees, a U8 at byte 17 (4.6.0 and master msp.c: three U16, four U8, two U16
    acceleration limits, then angle_limit; read 60 there from both SITLs, 61-byte payloads);
    the rest of the payload is kept as it came.

    Written by hand: one byte read out of, and written into, a payload kept whole."""

    angle_limit_deg: int
    payload: bytes = b""

    ANGLE_LIMIT_OFFSET: ClassVar[int] = 17

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        if len(payload) <= cls.ANGLE_LIMIT_OFFSET:
            raise MspDecodeError(
                f"MSP_PID_ADVANCED: {len(payload)} bytes, angle_limit is "
                f"byte {cls.ANGLE_LIMIT_OFFSET}"
            )
        return cls(payload[cls.ANGLE_LIMIT_OFFSET], bytes(payload))

    def encode(self) -> bytes:
        body = bytearray(self.payload or bytes(self.ANGLE_LIMIT_OFFSET + 1))
        try:
            body[self.ANGLE_LIMIT_OFFSET] = self.angle_limit_deg
        except ValueError as exc:  # not 0..255
            raise does_not_fit(self, exc) from exc
        return bytes(body)
