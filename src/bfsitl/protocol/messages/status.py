"""MSP_STATUS and MSP_STATUS_EX: cycle time, sensors, flight modes, arming blockers.

Written by hand: the flight-mode bits come in two places, the low 32 bits near the start and
``N`` more bytes after a count in the middle, and every field after them moves with ``N``. The
fixed parts are still read and written with precompiled structs (both are on the telemetry
hot path).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Self

from bfsitl.errors import MspRequestError
from bfsitl.protocol.arming import ArmingFlagInfo, decode_arming_flags
from bfsitl.protocol.messages.codec import FIT_ERRORS, IntRun, does_not_fit, short_payload
from bfsitl.protocol.messages.constants import SENSOR_NAMES, mask_names
from bfsitl.protocol.messages.layout import WireRecord, msp_message
from bfsitl.protocol.msp_codes import MspCommand

# msp.c:1088-1137. Up to the flight-mode byte count N: cycle time, I2C errors, sensors, flight
# modes 0-31, PID profile, CPU load, then 2 bytes that differ, then N ("lowest 4 bits contain
# number of bytes that follow", msp.c:1110-1114).
_STATUS_HEAD = IntRun("HHHIBH" + "H" + "B")  # STATUS: U16 "gyro cycle time", always 0 (1107)
_STATUS_EX_HEAD = IntRun("HHHIBH" + "BB" + "B")  # STATUS_EX: PID-profile count, rate profile
# After the N bytes: arming-disable flag count, the flags, config state; then the optional
# tail: S16 CPU temperature (1.46), U8 rate-profile count (1.47).
_AFTER_FLAGS = IntRun("BIB")
_AFTER_FLAGS_AND_TAIL = IntRun("BIB" + "hB")
_TAIL = (IntRun("h"), IntRun("B"))


class _StatusView(WireRecord):
    """Derived views shared by :class:`Status` and :class:`StatusEx`."""

    __slots__ = ()
    flight_mode_flags: int
    arming_disable_flags: int
    arming_disable_flag_count: int
    sensors_mask: int
    config_state: int

    @property
    def armed(self) -> bool:
        """Bit 0 of the flight-mode flags is the ARM box, which is always active (msp_box.c:206)."""
        return bool(self.flight_mode_flags & 1)

    @property
    def arming_blockers(self) -> tuple[ArmingFlagInfo, ...]:
        # The flag count the firmware sends picks the bit table (4.6: 29, master: 30).
        return decode_arming_flags(self.arming_disable_flags, self.arming_disable_flag_count)

    @property
    def sensors(self) -> tuple[str, ...]:
        return mask_names(self.sensors_mask, SENSOR_NAMES)

    @property
    def reboot_required(self) -> bool:
        """Bit 0 of ``config_state`` (msp.c:1126)."""
        return bool(self.config_state & 1)


def _decode_status(what: str, head_run: IntRun, payload: bytes) -> tuple[list[int], int, int]:
    """(head fields before N, all flight-mode flags, N) and the fields after, as one list:
    ``head..., arming count, arming flags, config state[, cpu temp[, rate-profile count]]``."""
    head = head_run.unpack(payload, 0, what)
    extra = head[-1] & 0x0F
    pos = head_run.size + extra
    length = len(payload)
    if length < pos:
        raise short_payload(what, pos, length)
    flags = head[3] | int.from_bytes(payload[head_run.size : pos], "little") << 32
    if length - pos >= _AFTER_FLAGS_AND_TAIL.size:
        after = list(_AFTER_FLAGS_AND_TAIL.unpack(payload, pos, what))
    else:
        after = list(_AFTER_FLAGS.unpack(payload, pos, what))
        pos += _AFTER_FLAGS.size
        for run in _TAIL:
            if pos >= length:
                break
            after.extend(run.unpack(payload, pos, what))
            pos += run.size
    return [*head[:-1], *after], flags, extra


def _encode_status(msg: Status | StatusEx, middle: Sequence[int], head_run: IntRun) -> bytes:
    flags = msg.flight_mode_flags
    needed = max(0, (flags.bit_length() - 32 + 7) // 8)
    extra = max(needed, msg.flight_mode_extra_bytes)
    if extra > 15:
        raise MspRequestError("flight-mode flags above bit 159 do not fit MSP_STATUS")
    try:
        parts = [
            head_run.struct.pack(
                msg.cycle_time_us,
                msg.i2c_errors,
                msg.sensors_mask,
                flags & 0xFFFFFFFF,
                msg.pid_profile,
                msg.cpu_load_percent,
                *middle,
                extra,
            ),
            (flags >> 32).to_bytes(extra, "little"),
        ]
        after = (msg.arming_disable_flag_count, msg.arming_disable_flags, msg.config_state)
        if msg.cpu_temp_c is not None and msg.rate_profile_count is not None:
            parts.append(
                _AFTER_FLAGS_AND_TAIL.struct.pack(*after, msg.cpu_temp_c, msg.rate_profile_count)
            )
        else:
            parts.append(_AFTER_FLAGS.struct.pack(*after))
            if msg.cpu_temp_c is not None:  # the tail up to its first None
                parts.append(_TAIL[0].struct.pack(msg.cpu_temp_c))
        return b"".join(parts)
    except FIT_ERRORS as exc:
        raise does_not_fit(msg, exc) from exc


@msp_message(MspCommand.STATUS)
@dataclass(frozen=True, slots=True)
class Status(_StatusView):
    """MSP_STATUS (101): msp.c:1088-1137.

    U16 PID-loop cycle time (us), U16 I2C errors, U16 sensor bits, U32 flight-mode bits 0-31,
    U8 PID profile, U16 CPU load (%), U16 0, U8 N, N bytes of flight-mode bits 32+, U8 number of
    arming-disable flags (29), U32 arming-disable flags, U8 config state (bit 0 reboot required),
    S16 CPU temperature (1.46, 0 on SITL), U8 rate-profile count (1.47).

    ``flight_mode_flags`` holds all bits in one int; bit i is the i-th entry of MSP_BOXIDS
    (see :func:`bfsitl.protocol.boxes.decode_flight_modes`). ``flight_mode_extra_bytes`` keeps N,
    which follows the number of active boxes, not the bits set, so round trips stay exact.
    """

    cycle_time_us: int
    i2c_errors: int
    sensors_mask: int
    flight_mode_flags: int
    pid_profile: int
    cpu_load_percent: int
    arming_disable_flag_count: int
    arming_disable_flags: int
    config_state: int
    cpu_temp_c: int | None = None
    rate_profile_count: int | None = None
    flight_mode_extra_bytes: int = 0

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        values, flags, extra = _decode_status(f"MSP {cls.__name__}", _STATUS_HEAD, payload)
        cycle, i2c, sensors, _, pid_profile, cpu, _gyro_cycle, *after = values
        arming_count, arming_flags, config, *tail = after
        cpu_temp, rate_count = (*tail, None, None)[:2]
        return cls(
            cycle,
            i2c,
            sensors,
            flags,
            pid_profile,
            cpu,
            arming_count,
            arming_flags,
            config,
            cpu_temp,
            rate_count,
            extra,
        )

    def encode(self) -> bytes:
        return _encode_status(self, (0,), _STATUS_HEAD)


@msp_message(MspCommand.STATUS_EX)
@dataclass(frozen=True, slots=True)
class StatusEx(_StatusView):
    """MSP_STATUS_EX (150): as :class:`Status`, but the U16 0 is U8 PID-profile count and U8
    current rate-profile index (msp.c:1103-1108), so the arming flags sit at offset 17 + N."""

    cycle_time_us: int
    i2c_errors: int
    sensors_mask: int
    flight_mode_flags: int
    pid_profile: int
    cpu_load_percent: int
    pid_profile_count: int
    rate_profile_index: int
    arming_disable_flag_count: int
    arming_disable_flags: int
    config_state: int
    cpu_temp_c: int | None = None
    rate_profile_count: int | None = None
    flight_mode_extra_bytes: int = 0

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        values, flags, extra = _decode_status(f"MSP {cls.__name__}", _STATUS_EX_HEAD, payload)
        cycle, i2c, sensors, _, pid_profile, cpu, profile_count, rate_index, *after = values
        arming_count, arming_flags, config, *tail = after
        cpu_temp, rate_count = (*tail, None, None)[:2]
        return cls(
            cycle,
            i2c,
            sensors,
            flags,
            pid_profile,
            cpu,
            profile_count,
            rate_index,
            arming_count,
            arming_flags,
            config,
            cpu_temp,
            rate_count,
            extra,
        )

    def encode(self) -> bytes:
        return _encode_status(
            self, (self.pid_profile_count, self.rate_profile_index), _STATUS_EX_HEAD
        )
