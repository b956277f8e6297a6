"""Typed MSP payloads of Betaflight 4.6 (MSP API 1.47), both directions.

Every message is a frozen dataclass with ``COMMAND``, ``decode(payload)`` and ``encode()``; both
follow the firmware layout exactly, so a fake FC can build replies with the same classes a client
uses to read them, and ``encode(decode(x)) == x`` for every layout the class covers fully.

Conventions, and why:

* Fields hold the exact wire integer and carry the wire unit in their name (``roll_decideg``,
  ``vbat_cv``); properties convert to physical units. Units differ per field in MSP (attitude
  yaw is whole degrees while roll is decidegrees), and keeping the raw value makes that visible.
* Decoders ignore trailing bytes, because newer firmware appends fields to old messages. Fields
  that older firmware lacks (gated by API version) are ``None`` when absent. A tail is either
  absent or complete: a half field means a broken payload.
* A payload too short for its layout raises :class:`MspDecodeError`, never ``struct.error``.
* Request values the FC would refuse, misread or crash on raise :class:`MspRequestError`
  (an :class:`MspFrameError` and a ``ValueError``) before anything is sent.

Layouts are cited as ``file:line`` in the firmware tree ``src/main/`` of Betaflight 4.6.0;
``msp.c`` means ``msp/msp.c``.
"""

from __future__ import annotations

import functools
import struct
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from enum import IntEnum
from typing import Any, ClassVar, Protocol, Self, TypeVar

from bfsitl.errors import (
    MspDecodeError,
    MspRequestError,  # noqa: F401 - defined in errors.py, importable here too
)
from bfsitl.protocol.arming import ArmingFlagInfo, decode_arming_flags
from bfsitl.protocol.boxes import BOX_NAMES
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MAX_REQUEST_PAYLOAD
from bfsitl.protocol.payload import PayloadReader, PayloadWriter

# --------------------------------------------------------------------------------------------
# constants

#: 1 g in accelerometer LSB on the SITL: ``acc.dev.acc_1G = 256`` (sensors/acceleration_init.c:385)
#: and the virtual accelerometer never changes it. Real IMUs usually report 2048 per g.
SITL_ACC_1G_LSB = 256
#: The SITL turns the fdm's acceleration into int16 by truncation (``sitl.c``: ``int16_t z =
#: constrain(-acc * ACC_SCALE, ...)``), not rounding, so in flight its z axis reads half an LSB
#: low on average: 0.019 m/s^2, which integrated is a climb-rate drift of 2 cm/s per second.
SITL_ACC_TRUNCATION_LSB = 0.5

#: MSP_RAW_IMU gyro is raw LSB: ``gyroRateDps()`` divides deg/s by the sensor scale
#: (sensors/gyro_init.c:747-750); 2000 dps sensors and the SITL's virtual gyro use
#: ``GYRO_SCALE_2000DPS`` = 2000/32768 deg/s per LSB (drivers/accgyro/accgyro.h:41,
#: accgyro_virtual.c:97), i.e. 16.384 LSB per deg/s.
GYRO_LSB_PER_DPS = 16.384

#: ``MAX_SUPPORTED_RC_CHANNEL_COUNT`` (rx/rx.h:73): MSP_SET_RAW_RC refuses more channels.
MAX_RC_CHANNELS = 18

#: ``MAX_MODE_ACTIVATION_CONDITION_COUNT`` (fc/rc_modes.h:96): mode range slots.
MODE_RANGE_SLOTS = 20

#: ``MAX_AUX_CHANNEL_COUNT`` (rx/rx.h:76): AUX1..AUX14, the valid ``aux_channel_index`` values.
MAX_AUX_CHANNELS = 14

#: ``RX_MAPPABLE_CHANNEL_COUNT`` (target/common_defaults_post.h:61).
RX_MAP_CHANNELS = 8

#: Letters of the channel map as the CLI ``map`` command uses them (rx/rx.c:75, first 8 only).
RC_MAP_LETTERS = "AERT1234"

#: Default map ``AETR1234`` (pg/rx.c:122): internal channel -> raw (wire) channel index.
DEFAULT_RCMAP: tuple[int, ...] = (0, 1, 3, 2, 4, 5, 6, 7)

#: ``CHANNEL_RANGE_MIN``/``MAX`` and the 25 us step of mode ranges (fc/rc_modes.h:98-105).
MODE_RANGE_MIN_US = 900
MODE_RANGE_MAX_US = 2100
MODE_RANGE_STEP_US = 25

#: MSP2_SENSOR_CONFIG_ACTIVE value for a sensor type not compiled in (msp.c:2115).
SENSOR_NOT_BUILT = 0xFF

#: Bits of the STATUS ``sensors`` word (msp.c:1099; NOT the firmware's internal sensor bits).
SENSOR_NAMES: tuple[str, ...] = ("ACC", "BARO", "MAG", "GPS", "RANGEFINDER", "GYRO", "OPTICALFLOW")

#: Feature bits (config/feature.h:46-69) named as the CLI ``feature`` command spells them
#: (cli/cli.c:234-257). Bit 14 RX_MSP has no CLI name in 4.6 (the CLI cannot toggle it).
FEATURE_NAMES: dict[int, str] = {
    0: "RX_PPM", 2: "INFLIGHT_ACC_CAL", 3: "RX_SERIAL", 4: "MOTOR_STOP", 5: "SERVO_TILT",
    6: "SOFTSERIAL", 7: "GPS", 8: "OPTICALFLOW", 9: "RANGEFINDER", 10: "TELEMETRY", 12: "3D",
    13: "RX_PARALLEL_PWM", 14: "RX_MSP", 15: "RSSI_ADC", 16: "LED_STRIP", 17: "DISPLAY",
    18: "OSD", 20: "CHANNEL_FORWARDING", 21: "TRANSPONDER", 22: "AIRMODE", 25: "RX_SPI",
    27: "ESC_SENSOR", 28: "ANTI_GRAVITY",
}  # fmt: skip

#: MSP_BUILD_INFO option ids (msp/msp_build_info.h:35-84).
BUILD_OPTION_NAMES: dict[int, str] = {
    4097: "SERIALRX_CRSF", 4098: "SERIALRX_FPORT", 4099: "SERIALRX_GHST", 4100: "SERIALRX_IBUS",
    4101: "SERIALRX_JETIEXBUS", 4102: "RX_PPM", 4103: "SERIALRX_SBUS", 4104: "SERIALRX_SPEKTRUM",
    4105: "SERIALRX_SRXL2", 4106: "SERIALRX_SUMD", 4107: "SERIALRX_SUMH", 4108: "SERIALRX_XBUS",
    12301: "TELEMETRY_FRSKY_HUB", 12302: "TELEMETRY_HOTT", 12303: "TELEMETRY_IBUS_EXTENDED",
    12304: "TELEMETRY_LTM", 12305: "TELEMETRY_MAVLINK", 12306: "TELEMETRY_SMARTPORT",
    12307: "TELEMETRY_SRXL", 16404: "ACRO_TRAINER", 16405: "AKK_SMARTAUDIO",
    16406: "BATTERY_CONTINUE", 16407: "CAMERA_CONTROL", 16408: "DASHBOARD", 16409: "EMFAT_TOOLS",
    16410: "ESCSERIAL_SIMONK", 16411: "FRSKYOSD", 16412: "GPS", 16413: "LED_STRIP",
    16414: "LED_STRIP_64", 16415: "MAG", 16416: "OSD_SD", 16417: "OSD_HD", 16418: "PINIO",
    16419: "RACE_PRO", 16420: "SERVOS", 16421: "VTX", 16422: "ALTITUDE_HOLD",
    16423: "SOFTSERIAL", 16424: "WING", 16425: "POSITION_HOLD", 8230: "BRUSHED", 8231: "DSHOT",
    8232: "MULTISHOT", 8233: "ONESHOT", 8234: "PROSHOT", 8235: "PWM_OUTPUT",
}  # fmt: skip

#: BOARD_INFO ``configurationProblems`` bits (msp.c:723-724).
CONFIGURATION_PROBLEM_NAMES: dict[int, str] = {
    0: "ACC_NEEDS_CALIBRATION",
    1: "MOTOR_PROTOCOL_DISABLED",
}

#: ``batteryState_e`` (sensors/battery.h:88-94).
BATTERY_STATE_NAMES: tuple[str, ...] = ("OK", "WARNING", "CRITICAL", "NOT_PRESENT", "INIT")


class RebootMode(IntEnum):
    """MSP_REBOOT modes (msp.c:166-173)."""

    FIRMWARE = 0
    BOOTLOADER_ROM = 1
    MSC = 2
    MSC_UTC = 3
    BOOTLOADER_FLASH = 4


class MspMessage(Protocol):
    """What every message class here provides."""

    COMMAND: ClassVar[int]

    def encode(self) -> bytes: ...


# --------------------------------------------------------------------------------------------
# helpers

_M = TypeVar("_M")


def _encoder(fn: Callable[[_M], bytes]) -> Callable[[_M], bytes]:
    """Turn a field that does not fit its wire type into :class:`MspRequestError`."""

    @functools.wraps(fn)
    def wrapper(self: _M) -> bytes:
        try:
            return fn(self)
        except (struct.error, OverflowError, UnicodeEncodeError) as exc:
            raise MspRequestError(
                f"{type(self).__name__}: a field does not fit its wire type ({exc})"
            ) from exc

    return wrapper


def _reader(cls: type, payload: bytes) -> PayloadReader:
    return PayloadReader(payload, f"MSP {cls.__name__}")


def _decode_text(raw: bytes) -> str:
    """Latin-1 keeps every byte, so text fields always re-encode to the same bytes."""
    return raw.split(b"\0", 1)[0].decode("latin-1")


def _read_text(r: PayloadReader, size: int) -> str:
    return _decode_text(r.raw(size))


def _read_pstr(r: PayloadReader) -> str:
    return _read_text(r, r.u8())


def _text_bytes(value: str, size: int | None = None) -> bytes:
    data = value.encode("latin-1")
    if size is not None:
        if len(data) > size:
            raise MspRequestError(f"text {value!r} is longer than its {size}-byte field")
        data = data.ljust(size, b"\0")
    return data


def _pstr_bytes(value: str) -> bytes:
    data = _text_bytes(value)
    return bytes([len(data)]) + data


def _read_tail(r: PayloadReader, readers: Sequence[Callable[[], Any]]) -> list[Any]:
    """Read optional trailing fields in order until the payload ends."""
    values: list[Any] = []
    for read in readers:
        if not r.remaining():
            break
        values.append(read())
    return values


def _write_tail(values: Sequence[Any], writers: Sequence[Callable[[Any], object]]) -> None:
    """Write optional trailing fields in order, stopping at the first one that is ``None``."""
    for value, write in zip(values, writers, strict=True):
        if value is None:
            return
        write(value)


def _array(r: PayloadReader, item_size: int, what: str) -> int:
    """Number of items in an array that runs to the end of the payload."""
    left = r.remaining()
    if left % item_size:
        raise MspDecodeError(
            f"{what}: {left} bytes is not a whole number of {item_size}-byte items"
        )
    return left // item_size


def _mask_names(mask: int, names: dict[int, str] | Sequence[str]) -> tuple[str, ...]:
    lookup = dict(enumerate(names)) if isinstance(names, Sequence) else names
    return tuple(
        lookup.get(bit, f"BIT{bit}") for bit in range(mask.bit_length()) if mask >> bit & 1
    )


def _three(r: PayloadReader, read: Callable[[], int]) -> tuple[int, int, int]:
    return (read(), read(), read())


# --------------------------------------------------------------------------------------------
# identity


@dataclass(frozen=True, slots=True)
class ApiVersion:
    """MSP_API_VERSION (1): msp.c:632-636. 4.6.0 answers 0, 1, 47."""

    COMMAND: ClassVar[int] = MspCommand.API_VERSION
    protocol_version: int
    api_major: int
    api_minor: int

    @property
    def api(self) -> tuple[int, int]:
        """(major, minor), comparable: ``msg.api >= (1, 46)``."""
        return (self.api_major, self.api_minor)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.u8(), r.u8(), r.u8())

    @_encoder
    def encode(self) -> bytes:
        return (
            PayloadWriter().u8(self.protocol_version).u8(self.api_major).u8(self.api_minor).build()
        )


@dataclass(frozen=True, slots=True)
class FcVariant:
    """MSP_FC_VARIANT (2): 4 characters, ``BTFL`` for Betaflight (msp.c:638-640)."""

    COMMAND: ClassVar[int] = MspCommand.FC_VARIANT
    identifier: str

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        return cls(_read_text(_reader(cls, payload), 4))

    @_encoder
    def encode(self) -> bytes:
        return _text_bytes(self.identifier, 4)


@dataclass(frozen=True, slots=True)
class FcVersion:
    """MSP_FC_VERSION (3): U8 major, minor, patch (4.6 msp.c:642-646).

    Master (calendar versions) sends U8 year - 2000, U8 month, U8 patch and then the whole
    version as a PStr, e.g. ``2026.12.0-alpha`` (master msp.c:688-695); :attr:`text` is that
    string when present.
    """

    COMMAND: ClassVar[int] = MspCommand.FC_VERSION
    major: int
    minor: int
    patch: int
    version_string: str | None = None

    @property
    def text(self) -> str:
        if self.version_string:
            return self.version_string
        return f"{self.major}.{self.minor}.{self.patch}"

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        major, minor, patch = r.u8(), r.u8(), r.u8()
        version_string = _read_pstr(r) if r.remaining() else None
        return cls(major, minor, patch, version_string)

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(self.major).u8(self.minor).u8(self.patch)
        if self.version_string is not None:
            w.raw(_pstr_bytes(self.version_string))
        return w.build()


@dataclass(frozen=True, slots=True)
class BoardInfo:
    """MSP_BOARD_INFO (4): msp.c:654-753.

    4 chars board id, U16 hardware revision, U8 FC type (2 = with MAX7456), U8 capability bits,
    PStr target name; then, appended over API versions: PStr board name, PStr manufacturer id,
    32-byte signature, U8 MCU type, U8 configuration state (1.42), U16 gyro sample rate (1.43),
    U32 configuration problems, U8 SPI and U8 I2C device counts (1.44). The SITL sends 57 bytes.
    """

    COMMAND: ClassVar[int] = MspCommand.BOARD_INFO
    board_id: str
    hardware_revision: int
    fc_type: int
    target_capabilities: int
    target_name: str
    board_name: str | None = None
    manufacturer_id: str | None = None
    signature: bytes | None = None
    mcu_type_id: int | None = None
    configuration_state: int | None = None
    gyro_sample_rate_hz: int | None = None
    configuration_problems: int | None = None
    spi_device_count: int | None = None
    i2c_device_count: int | None = None

    @property
    def problems(self) -> tuple[str, ...]:
        """Names of the configuration problems the FC reports (ACC calibration, motor protocol)."""
        return _mask_names(self.configuration_problems or 0, CONFIGURATION_PROBLEM_NAMES)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        head = (_read_text(r, 4), r.u16(), r.u8(), r.u8(), _read_pstr(r))
        tail = _read_tail(
            r,
            (
                lambda: _read_pstr(r),
                lambda: _read_pstr(r),
                lambda: r.raw(32),
                r.u8,
                r.u8,
                r.u16,
                r.u32,
                r.u8,
                r.u8,
            ),
        )
        return cls(*head, *tail)

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().raw(_text_bytes(self.board_id, 4)).u16(self.hardware_revision)
        w.u8(self.fc_type).u8(self.target_capabilities).raw(_pstr_bytes(self.target_name))

        def signature(value: bytes) -> None:
            if len(value) != 32:
                raise MspRequestError(f"signature must be 32 bytes, got {len(value)}")
            w.raw(value)

        _write_tail(
            (
                self.board_name,
                self.manufacturer_id,
                self.signature,
                self.mcu_type_id,
                self.configuration_state,
                self.gyro_sample_rate_hz,
                self.configuration_problems,
                self.spi_device_count,
                self.i2c_device_count,
            ),
            (
                lambda v: w.raw(_pstr_bytes(v)),
                lambda v: w.raw(_pstr_bytes(v)),
                signature,
                w.u8,
                w.u8,
                w.u16,
                w.u32,
                w.u8,
                w.u8,
            ),
        )
        return w.build()


@dataclass(frozen=True, slots=True)
class BuildInfo:
    """MSP_BUILD_INFO (5): msp.c:755-761, msp/msp_build_info.c:38-188.

    11 chars date, 8 chars time, 7 chars short git revision, then U16 build-option ids to the
    end of the payload (1.46; no count byte). A build without git metadata sends whatever follows
    the revision string in memory; the text stops at the first NUL.
    """

    COMMAND: ClassVar[int] = MspCommand.BUILD_INFO
    date: str
    time: str
    git_revision: str
    build_options: tuple[int, ...] = ()

    @property
    def option_names(self) -> tuple[str, ...]:
        return tuple(BUILD_OPTION_NAMES.get(o, f"OPTION_{o}") for o in self.build_options)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        date, clock, git = _read_text(r, 11), _read_text(r, 8), _read_text(r, 7)
        count = _array(r, 2, "MSP BuildInfo options")
        return cls(date, clock, git, tuple(r.u16() for _ in range(count)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().raw(_text_bytes(self.date, 11)).raw(_text_bytes(self.time, 8))
        w.raw(_text_bytes(self.git_revision, 7))
        for option in self.build_options:
            w.u16(option)
        return w.build()


@dataclass(frozen=True, slots=True)
class McuInfo:
    """MSP2_MCU_INFO (0x300C): U8 MCU type id, PStr MCU name (msp.c:648-652); SITL: 0, SIMULATOR."""

    COMMAND: ClassVar[int] = MspCommand.MSP2_MCU_INFO
    mcu_type_id: int
    name: str

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.u8(), _read_pstr(r))

    @_encoder
    def encode(self) -> bytes:
        return PayloadWriter().u8(self.mcu_type_id).raw(_pstr_bytes(self.name)).build()


@dataclass(frozen=True, slots=True)
class CraftName:
    """MSP_NAME (10): the craft name, raw characters, no terminator, may be empty (msp.c:1160-1162).

    The whole payload is the name, so there is no trailing-byte tolerance here.
    """

    COMMAND: ClassVar[int] = MspCommand.NAME
    name: str

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(_read_text(r, r.remaining()))

    @_encoder
    def encode(self) -> bytes:
        return _text_bytes(self.name)


@dataclass(frozen=True, slots=True)
class Uid:
    """MSP_UID (160): the MCU unique id as 3 x U32 (msp.c:777-781); SITL sends 0, 1, 2."""

    COMMAND: ClassVar[int] = MspCommand.UID
    uid: tuple[int, int, int]

    @property
    def text(self) -> str:
        return "".join(f"{word:08x}" for word in self.uid)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(_three(r, r.u32))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for word in self.uid:
            w.u32(word)
        return w.build()


# --------------------------------------------------------------------------------------------
# status


class _StatusView:
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
        return _mask_names(self.sensors_mask, SENSOR_NAMES)

    @property
    def reboot_required(self) -> bool:
        """Bit 0 of ``config_state`` (msp.c:1126)."""
        return bool(self.config_state & 1)


_S = TypeVar("_S", bound=_StatusView)


def _decode_status(cls: type[_S], payload: bytes, extended: bool) -> _S:
    # msp.c:1088-1137; STATUS and STATUS_EX differ only in the 2 bytes after the CPU load.
    r = _reader(cls, payload)
    kw: dict[str, Any] = {"cycle_time_us": r.u16(), "i2c_errors": r.u16(), "sensors_mask": r.u16()}
    low_flags = r.u32()
    kw["pid_profile"] = r.u8()
    kw["cpu_load_percent"] = r.u16()
    if extended:
        kw["pid_profile_count"] = r.u8()
        kw["rate_profile_index"] = r.u8()
    else:
        r.u16()  # "gyro cycle time", always 0 (msp.c:1107)
    extra = r.u8() & 0x0F  # "lowest 4 bits contain number of bytes that follow" (msp.c:1110-1114)
    high_flags = int.from_bytes(r.raw(extra), "little")
    kw["flight_mode_flags"] = low_flags | high_flags << 32
    kw["flight_mode_extra_bytes"] = extra
    kw["arming_disable_flag_count"] = r.u8()
    kw["arming_disable_flags"] = r.u32()
    kw["config_state"] = r.u8()
    tail = _read_tail(r, (r.s16, r.u8))  # CPU temperature (1.46), rate profile count (1.47)
    kw["cpu_temp_c"], kw["rate_profile_count"] = (*tail, None, None)[:2]
    return cls(**kw)


def _encode_status(msg: Status | StatusEx, middle: Callable[[PayloadWriter], object]) -> bytes:
    flags = msg.flight_mode_flags
    needed = max(0, (flags.bit_length() - 32 + 7) // 8)
    extra = max(needed, msg.flight_mode_extra_bytes)
    if extra > 15:
        raise MspRequestError("flight-mode flags above bit 159 do not fit MSP_STATUS")
    w = PayloadWriter().u16(msg.cycle_time_us).u16(msg.i2c_errors).u16(msg.sensors_mask)
    w.u32(flags & 0xFFFFFFFF).u8(msg.pid_profile).u16(msg.cpu_load_percent)
    middle(w)
    w.u8(extra).raw((flags >> 32).to_bytes(extra, "little"))
    w.u8(msg.arming_disable_flag_count).u32(msg.arming_disable_flags).u8(msg.config_state)
    _write_tail((msg.cpu_temp_c, msg.rate_profile_count), (w.s16, w.u8))
    return w.build()


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

    COMMAND: ClassVar[int] = MspCommand.STATUS
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
        return _decode_status(cls, payload, extended=False)

    @_encoder
    def encode(self) -> bytes:
        return _encode_status(self, lambda w: w.u16(0))


@dataclass(frozen=True, slots=True)
class StatusEx(_StatusView):
    """MSP_STATUS_EX (150): as :class:`Status`, but the U16 0 is U8 PID-profile count and U8
    current rate-profile index (msp.c:1103-1108), so the arming flags sit at offset 17 + N."""

    COMMAND: ClassVar[int] = MspCommand.STATUS_EX
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
        return _decode_status(cls, payload, extended=True)

    @_encoder
    def encode(self) -> bytes:
        return _encode_status(
            self, lambda w: w.u8(self.pid_profile_count).u8(self.rate_profile_index)
        )


# --------------------------------------------------------------------------------------------
# sensors and telemetry


@dataclass(frozen=True, slots=True)
class RawImu:
    """MSP_RAW_IMU (102): 3 x S16 acc, gyro, mag, all raw sensor LSB (msp.c:1139-1158).

    Not physical units: convert with :meth:`acc_g` and :meth:`gyro_dps`. Mag is 0 without a mag.
    """

    COMMAND: ClassVar[int] = MspCommand.RAW_IMU
    acc_raw: tuple[int, int, int]
    gyro_raw: tuple[int, int, int]
    mag_raw: tuple[int, int, int]

    def acc_g(self, acc_1g_lsb: float = SITL_ACC_1G_LSB) -> tuple[float, float, float]:
        """Acceleration in g; pass 2048 (or the board's ``acc_1G``) for a real IMU."""
        x, y, z = self.acc_raw
        return (x / acc_1g_lsb, y / acc_1g_lsb, z / acc_1g_lsb)

    def gyro_dps(self, lsb_per_dps: float = GYRO_LSB_PER_DPS) -> tuple[float, float, float]:
        """Rotation rate in deg/s; pass 8.192 for a 4000 dps (``gyro_high_range``) sensor."""
        x, y, z = self.gyro_raw
        return (x / lsb_per_dps, y / lsb_per_dps, z / lsb_per_dps)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(_three(r, r.s16), _three(r, r.s16), _three(r, r.s16))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in (*self.acc_raw, *self.gyro_raw, *self.mag_raw):
            w.s16(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class Motor:
    """MSP_MOTOR (104): always 8 x U16 motor outputs in PWM us (DShot mapped to 1000-2000),
    0 for absent or disabled motors (msp.c:1192-1205). SITL disarmed: 1000 x 4, then 0 x 4."""

    COMMAND: ClassVar[int] = MspCommand.MOTOR
    COUNT: ClassVar[int] = 8
    motors_us: tuple[int, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(tuple(r.u16() for _ in range(cls.COUNT)))

    @_encoder
    def encode(self) -> bytes:
        if len(self.motors_us) > self.COUNT:
            raise MspRequestError(
                f"MSP_MOTOR carries {self.COUNT} motors, got {len(self.motors_us)}"
            )
        w = PayloadWriter()
        for value in (*self.motors_us, *([0] * (self.COUNT - len(self.motors_us)))):
            w.u16(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class Rc:
    """MSP_RC (105): one U16 per receiver channel, in us, in the FC's INTERNAL order roll, pitch,
    yaw, throttle, AUX1... (msp.c:1311-1315) - not the AETR order MSP_SET_RAW_RC takes.

    The count is the receiver's (18 for MSP RX, 16 after the SITL's UDP RC took over). Only the
    first ``max_aux_channels + 4`` are processed (10 on SITL); the rest read 1500. Master's UDP
    receiver reports no channels at all until the first RC packet: an empty reply is valid
    (:attr:`has_channels` False), and the stick properties then read 0.
    """

    COMMAND: ClassVar[int] = MspCommand.RC
    channels_us: tuple[int, ...]

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
        r = _reader(cls, payload)
        count = _array(r, 2, "MSP Rc")
        if 0 < count < 4:
            raise MspDecodeError(f"MSP Rc: needs 0 or at least 4 channels (8 bytes), got "
                                 f"{len(payload)} bytes")
        return cls(tuple(r.u16() for _ in range(count)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in self.channels_us:
            w.u16(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class Attitude:
    """MSP_ATTITUDE (108): S16 roll and pitch in DECIdegrees, S16 yaw in WHOLE degrees 0..359
    (msp.c:1317-1321).

    Roll is positive right wing down. Pitch is positive NOSE DOWN (Betaflight's convention, the
    opposite of aerospace nose-up). Yaw is the heading, clockwise from north.
    """

    COMMAND: ClassVar[int] = MspCommand.ATTITUDE
    roll_decideg: int
    pitch_decideg: int
    yaw_deg: int

    @property
    def roll_deg(self) -> float:
        return self.roll_decideg / 10.0

    @property
    def pitch_deg(self) -> float:
        """Positive nose down."""
        return self.pitch_decideg / 10.0

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.s16(), r.s16(), r.s16())

    @_encoder
    def encode(self) -> bytes:
        return (
            PayloadWriter().s16(self.roll_decideg).s16(self.pitch_decideg).s16(self.yaw_deg).build()
        )


@dataclass(frozen=True, slots=True)
class RawGps:
    """MSP_RAW_GPS (106): U8 fix, U8 satellites, S32 lat and lon in 1e-7 deg, U16 altitude in
    WHOLE metres (clamped at 0), U16 ground speed cm/s, U16 course in decidegrees, U16 PDOP
    (1.44) (msp.c MSP_RAW_GPS). Only builds with GPS answer it; others send an error frame.
    """

    COMMAND: ClassVar[int] = MspCommand.RAW_GPS
    fix: int
    satellites: int
    lat_e7: int
    lon_e7: int
    altitude_m: int
    ground_speed_cm_s: int
    course_decideg: int
    pdop: int | None = None

    @property
    def has_fix(self) -> bool:
        return bool(self.fix)

    @property
    def lat_deg(self) -> float:
        return self.lat_e7 * 1e-7

    @property
    def lon_deg(self) -> float:
        return self.lon_e7 * 1e-7

    @property
    def ground_speed_m_s(self) -> float:
        return self.ground_speed_cm_s * 0.01

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        head = (r.u8(), r.u8(), r.s32(), r.s32(), r.u16(), r.u16(), r.u16())
        pdop = r.u16() if r.remaining() >= 2 else None
        return cls(*head, pdop)

    @_encoder
    def encode(self) -> bytes:
        w = (PayloadWriter().u8(self.fix).u8(self.satellites).s32(self.lat_e7).s32(self.lon_e7)
             .u16(self.altitude_m).u16(self.ground_speed_cm_s).u16(self.course_decideg))
        if self.pdop is not None:
            w.u16(self.pdop)
        return w.build()


@dataclass(frozen=True, slots=True)
class RcTuning:
    """MSP_RC_TUNING (111), the parts that shape the sticks: per-axis RC rate (Actual rates:
    centre sensitivity, 10 deg/s units), expo (percent) and rate (Actual: the maximum, 10 deg/s
    units), and the rates type (4.6.0 and master msp.c: rcRates[R], rcExpo[R], rates[R, P, Y],
    5 bytes of throttle fields, rcExpo[Y], rcRates[Y], rcRates[P], rcExpo[P], 2 throttle-limit
    bytes, 3 U16 rate limits, then U8 rates_type from API 1.43)."""

    COMMAND: ClassVar[int] = MspCommand.RC_TUNING
    roll_rc_rate: int
    roll_expo: int
    roll_rate: int
    pitch_rate: int
    yaw_rate: int
    yaw_expo: int
    yaw_rc_rate: int
    pitch_rc_rate: int
    pitch_expo: int
    rates_type: int | None = None   # 0 Betaflight, 1 Raceflight, 2 KISS, 3 Actual, 4 Quick

    #: ``rates_type`` of Actual rates (the default of 4.6.0 and master).
    ACTUAL: ClassVar[int] = 3

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        roll_rc_rate, roll_expo, roll_rate, pitch_rate, yaw_rate = (r.u8() for _ in range(5))
        for _ in range(5):  # was tpa_rate, thrMid8, thrExpo8, U16 was tpa_breakpoint
            r.u8()
        yaw_expo, yaw_rc_rate, pitch_rc_rate, pitch_expo = (r.u8() for _ in range(4))
        rates_type = None
        if r.remaining() >= 9:
            for _ in range(8):  # throttle limit type and percent, three U16 rate limits
                r.u8()
            rates_type = r.u8()
        return cls(roll_rc_rate, roll_expo, roll_rate, pitch_rate, yaw_rate, yaw_expo,
                   yaw_rc_rate, pitch_rc_rate, pitch_expo, rates_type)

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in (self.roll_rc_rate, self.roll_expo, self.roll_rate, self.pitch_rate,
                      self.yaw_rate, 0, 0, 0, 0, 0, self.yaw_expo, self.yaw_rc_rate,
                      self.pitch_rc_rate, self.pitch_expo):
            w.u8(value)
        if self.rates_type is not None:
            for value in (0, 0, 0, 0, 0, 0, 0, 0, self.rates_type):
                w.u8(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class PidAdvanced:
    """MSP_PID_ADVANCED (94), only ``angle_limit``: the ANGLE-mode angle at full stick, in
    degrees, a U8 at byte 17 (4.6.0 and master msp.c: three U16, four U8, two U16
    acceleration limits, then angle_limit; read 60 there from both SITLs, 61-byte payloads);
    the rest of the payload is kept as it came."""

    COMMAND: ClassVar[int] = MspCommand.PID_ADVANCED
    angle_limit_deg: int
    payload: bytes = b""

    ANGLE_LIMIT_OFFSET: ClassVar[int] = 17

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        if len(payload) <= cls.ANGLE_LIMIT_OFFSET:
            raise MspDecodeError(f"MSP_PID_ADVANCED: {len(payload)} bytes, angle_limit is "
                                 f"byte {cls.ANGLE_LIMIT_OFFSET}")
        return cls(payload[cls.ANGLE_LIMIT_OFFSET], bytes(payload))

    @_encoder
    def encode(self) -> bytes:
        body = bytearray(self.payload or bytes(self.ANGLE_LIMIT_OFFSET + 1))
        body[self.ANGLE_LIMIT_OFFSET] = self.angle_limit_deg
        return bytes(body)


@dataclass(frozen=True, slots=True)
class Altitude:
    """MSP_ALTITUDE (109): S32 altitude cm, S16 vario cm/s (msp.c:1323-1330).

    Positive UP (not NED). Disarmed: baro altitude relative to the boot-time calibration (or GPS
    altitude with a 3D fix); armed: zeroed at arming and low-pass filtered. Vario is 0 while
    disarmed (flight/position.c).
    """

    COMMAND: ClassVar[int] = MspCommand.ALTITUDE
    altitude_cm: int
    vario_cm_s: int

    @property
    def altitude_m(self) -> float:
        return self.altitude_cm / 100.0

    @property
    def vario_m_s(self) -> float:
        return self.vario_cm_s / 100.0

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.s32(), r.s16())

    @_encoder
    def encode(self) -> bytes:
        return PayloadWriter().s32(self.altitude_cm).s16(self.vario_cm_s).build()


@dataclass(frozen=True, slots=True)
class Analog:
    """MSP_ANALOG (110): U8 battery 0.1 V (clamped to 255), U16 mAh drawn, U16 RSSI 0..1023,
    S16 current 0.01 A, U16 battery 0.01 V (msp.c:763-769)."""

    COMMAND: ClassVar[int] = MspCommand.ANALOG
    vbat_dv: int
    mah_drawn: int
    rssi: int
    amperage_ca: int
    vbat_cv: int | None = None

    @property
    def battery_v(self) -> float:
        """Prefers the 0.01 V field: the 0.1 V one saturates at 25.5 V (6S and up)."""
        return self.vbat_cv / 100.0 if self.vbat_cv is not None else self.vbat_dv / 10.0

    @property
    def amperage_a(self) -> float:
        return self.amperage_ca / 100.0

    @property
    def rssi_percent(self) -> float:
        return self.rssi * 100.0 / 1023.0

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        head = (r.u8(), r.u16(), r.u16(), r.s16())
        return cls(*head, *_read_tail(r, (r.u16,)))

    @_encoder
    def encode(self) -> bytes:
        w = (
            PayloadWriter()
            .u8(self.vbat_dv)
            .u16(self.mah_drawn)
            .u16(self.rssi)
            .s16(self.amperage_ca)
        )
        _write_tail((self.vbat_cv,), (w.u16,))
        return w.build()


@dataclass(frozen=True, slots=True)
class BatteryState:
    """MSP_BATTERY_STATE (130): U8 cells, U16 capacity mAh, U8 0.1 V, U16 mAh drawn, S16 0.01 A,
    U8 state (sensors/battery.h:88-94), U16 0.01 V (msp.c:795-810)."""

    COMMAND: ClassVar[int] = MspCommand.BATTERY_STATE
    cell_count: int
    capacity_mah: int
    vbat_dv: int
    mah_drawn: int
    amperage_ca: int
    state: int
    vbat_cv: int | None = None

    @property
    def battery_v(self) -> float:
        return self.vbat_cv / 100.0 if self.vbat_cv is not None else self.vbat_dv / 10.0

    @property
    def amperage_a(self) -> float:
        return self.amperage_ca / 100.0

    @property
    def state_name(self) -> str:
        names = BATTERY_STATE_NAMES
        return names[self.state] if self.state < len(names) else f"UNKNOWN_{self.state}"

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        head = (r.u8(), r.u16(), r.u8(), r.u16(), r.s16(), r.u8())
        return cls(*head, *_read_tail(r, (r.u16,)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(self.cell_count).u16(self.capacity_mah).u8(self.vbat_dv)
        w.u16(self.mah_drawn).s16(self.amperage_ca).u8(self.state)
        _write_tail((self.vbat_cv,), (w.u16,))
        return w.build()


@dataclass(frozen=True, slots=True)
class SensorConfigActive:
    """MSP2_SENSOR_CONFIG_ACTIVE (0x300A, 1.46): the detected hardware type per sensor, U8 each:
    gyro, acc, baro, mag, rangefinder, optical flow; 0xFF = not compiled in (msp.c:2113-2145)."""

    COMMAND: ClassVar[int] = MspCommand.MSP2_SENSOR_CONFIG_ACTIVE
    gyro_hw: int
    acc_hw: int
    baro_hw: int
    mag_hw: int
    rangefinder_hw: int
    opticalflow_hw: int

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(*(r.u8() for _ in range(6)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in (
            self.gyro_hw,
            self.acc_hw,
            self.baro_hw,
            self.mag_hw,
            self.rangefinder_hw,
            self.opticalflow_hw,
        ):
            w.u8(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class Debug:
    """MSP_DEBUG (254): the ``debug[]`` array as S16 (8 values in 4.6, ``DEBUG16_VALUE_COUNT``,
    build/debug.h:25; older firmware sent 4), msp.c:771-775. Meaning set by ``debug_mode``."""

    COMMAND: ClassVar[int] = MspCommand.DEBUG
    values: tuple[int, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(tuple(r.s16() for _ in range(_array(r, 2, "MSP Debug"))))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in self.values:
            w.s16(value)
        return w.build()


@dataclass(frozen=True, slots=True)
class MotorTelemetryEntry:
    """One motor of MSP_MOTOR_TELEMETRY (13 bytes, msp.c:1266-1271)."""

    SIZE: ClassVar[int] = 13
    rpm: int
    invalid_centipercent: int  # share of invalid DShot telemetry frames, 0.01 % (10000 = 100 %)
    temperature_c: int
    voltage_cv: int
    current_ca: int
    consumption_mah: int

    @property
    def invalid_percent(self) -> float:
        return self.invalid_centipercent / 100.0

    @property
    def voltage_v(self) -> float:
        return self.voltage_cv / 100.0

    @property
    def current_a(self) -> float:
        return self.current_ca / 100.0


@dataclass(frozen=True, slots=True)
class MotorTelemetry:
    """MSP_MOTOR_TELEMETRY (139, 1.42): U8 motor count, then per motor U32 rpm, U16 invalid
    0.01 %, U8 temperature C, U16 0.01 V, U16 0.01 A, U16 mAh (msp.c:1208-1273). All zero
    without DShot telemetry or ESC sensor (always on SITL)."""

    COMMAND: ClassVar[int] = MspCommand.MOTOR_TELEMETRY
    motors: tuple[MotorTelemetryEntry, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        count = r.u8()
        motors = tuple(
            MotorTelemetryEntry(r.u32(), r.u16(), r.u8(), r.u16(), r.u16(), r.u16())
            for _ in range(count)
        )
        return cls(motors)

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(len(self.motors))
        for m in self.motors:
            w.u32(m.rpm).u16(m.invalid_centipercent).u8(m.temperature_c)
            w.u16(m.voltage_cv).u16(m.current_ca).u16(m.consumption_mah)
        return w.build()


# --------------------------------------------------------------------------------------------
# configuration


@dataclass(frozen=True, slots=True)
class ArmingConfig:
    """MSP_ARMING_CONFIG (61): U8 auto-disarm delay s, U8 0, U8 small_angle deg, U8
    gyro_cal_on_first_arm (msp.c:1346-1351). SITL default: 5, 0, 25, 0."""

    COMMAND: ClassVar[int] = MspCommand.ARMING_CONFIG
    auto_disarm_delay_s: int
    small_angle_deg: int
    gyro_cal_on_first_arm: int

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        delay = r.u8()
        r.u8()  # was disarm_kill_switch, always 0
        return cls(delay, r.u8(), r.u8())

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(self.auto_disarm_delay_s).u8(0)
        return w.u8(self.small_angle_deg).u8(self.gyro_cal_on_first_arm).build()


@dataclass(frozen=True, slots=True)
class SetArmingConfig(ArmingConfig):
    """MSP_SET_ARMING_CONFIG (62) request, same 4 bytes (msp.c:2738-2747). RAM only until saved."""

    COMMAND: ClassVar[int] = MspCommand.SET_ARMING_CONFIG


@dataclass(frozen=True, slots=True)
class FeatureConfig:
    """MSP_FEATURE_CONFIG (36): U32 CONFIGURED feature mask (msp.c:783-785), not the running one.
    SITL default 0x10404000 = RX_MSP, AIRMODE, ANTI_GRAVITY."""

    COMMAND: ClassVar[int] = MspCommand.FEATURE_CONFIG
    feature_mask: int

    @property
    def features(self) -> tuple[str, ...]:
        return _mask_names(self.feature_mask, FEATURE_NAMES)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        return cls(_reader(cls, payload).u32())

    @_encoder
    def encode(self) -> bytes:
        return PayloadWriter().u32(self.feature_mask).build()


@dataclass(frozen=True, slots=True)
class SetFeatureConfig(FeatureConfig):
    """MSP_SET_FEATURE_CONFIG (37) request: U32 mask (msp.c:3782-3784). Replaces the configured
    mask only; the running features change after save + reboot."""

    COMMAND: ClassVar[int] = MspCommand.SET_FEATURE_CONFIG


@dataclass(frozen=True, slots=True)
class RxMap:
    """MSP_RX_MAP (64): 8 x U8, for each internal channel (roll, pitch, yaw, throttle, AUX1-4)
    the raw (wire) channel index it reads (msp.c:1671-1673, rx/rx.c:659-683). Default AETR:
    0, 1, 3, 2, 4, 5, 6, 7."""

    COMMAND: ClassVar[int] = MspCommand.RX_MAP
    rcmap: tuple[int, ...]

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

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(tuple(r.u8() for _ in range(RX_MAP_CHANNELS)))

    @_encoder
    def encode(self) -> bytes:
        if len(self.rcmap) != RX_MAP_CHANNELS:
            raise MspRequestError(f"a channel map has 8 entries, got {len(self.rcmap)}")
        return bytes(self.rcmap)


@dataclass(frozen=True, slots=True)
class SetRxMap(RxMap):
    """MSP_SET_RX_MAP (65) request, 8 x U8 (msp.c:3931-3935).

    4.6 reads 8 bytes without a length check and uses each entry as an array index, so this
    class only accepts a permutation of 0..7 (what the CLI ``map`` command enforces).
    """

    COMMAND: ClassVar[int] = MspCommand.SET_RX_MAP

    def __post_init__(self) -> None:
        if sorted(self.rcmap) != list(range(RX_MAP_CHANNELS)):
            raise MspRequestError(f"channel map must be a permutation of 0..7, got {self.rcmap}")

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        try:
            return cls(tuple(r.u8() for _ in range(RX_MAP_CHANNELS)))
        except MspRequestError as exc:
            raise MspDecodeError(str(exc)) from exc


# --------------------------------------------------------------------------------------------
# modes


@dataclass(frozen=True, slots=True)
class BoxNames:
    """MSP_BOXNAMES (116): ``name;name;...;`` for the active boxes of page 0 in internal order
    (msp.c:2355-2360, msp_box.c:140-196). Send a U8 page to get boxes 32+ on big builds."""

    COMMAND: ClassVar[int] = MspCommand.BOXNAMES
    names: tuple[str, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        text = bytes(payload).decode("latin-1")
        parts = text.split(";")
        if parts and parts[-1] == "":
            parts.pop()
        return cls(tuple(parts))

    @_encoder
    def encode(self) -> bytes:
        return "".join(f"{name};" for name in self.names).encode("latin-1")


@dataclass(frozen=True, slots=True)
class BoxIds:
    """MSP_BOXIDS (119): one U8 permanent id per active box, same order as BOXNAMES
    (msp.c:2361-2366). Position i here is bit i of the STATUS flight-mode flags."""

    COMMAND: ClassVar[int] = MspCommand.BOXIDS
    ids: tuple[int, ...]

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        return cls(tuple(bytes(payload)))

    @_encoder
    def encode(self) -> bytes:
        return bytes(self.ids)


@dataclass(frozen=True, slots=True)
class ModeRange:
    """One mode activation condition: box (permanent id), AUX channel (0 = AUX1), and a range in
    25 us steps from 900 us (fc/rc_modes.h:96-110). A slot is used when start < end
    (``IS_RANGE_USABLE``, rc_modes.h:142); unused slots read all zero."""

    SIZE: ClassVar[int] = 4
    box_id: int
    aux_channel_index: int
    start_step: int
    end_step: int

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

    def _write(self, w: PayloadWriter) -> None:
        w.u8(self.box_id).u8(self.aux_channel_index).u8(self.start_step).u8(self.end_step)

    @classmethod
    def _read(cls, r: PayloadReader) -> Self:
        return cls(r.u8(), r.u8(), r.u8(), r.u8())


@dataclass(frozen=True, slots=True)
class ModeRanges:
    """MSP_MODE_RANGES (34): 20 x {U8 permanent id, U8 AUX index, U8 start, U8 end}
    (msp.c:1403-1412)."""

    COMMAND: ClassVar[int] = MspCommand.MODE_RANGES
    ranges: tuple[ModeRange, ...]

    @property
    def used(self) -> tuple[tuple[int, ModeRange], ...]:
        """(slot index, range) of the slots in use."""
        return tuple((i, rng) for i, rng in enumerate(self.ranges) if rng.is_used)

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(tuple(ModeRange._read(r) for _ in range(_array(r, 4, "MSP ModeRanges"))))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for rng in self.ranges:
            rng._write(w)
        return w.build()


@dataclass(frozen=True, slots=True)
class SetModeRange:
    """MSP_SET_MODE_RANGE (35) request: U8 slot, the 4 range bytes, optionally U8 mode logic
    (0 OR, 1 AND) and U8 linked permanent id (msp.c:2761-2785). Applied at once, RAM only until
    saved; an unknown box id or slot >= 20 gets an error reply.

    4.6 dereferences the box found for ``linked_to`` without a NULL check (msp.c:2776), so an
    unknown linked id would crash the FC; this class only accepts known permanent ids there.
    """

    COMMAND: ClassVar[int] = MspCommand.SET_MODE_RANGE
    index: int
    range: ModeRange
    mode_logic: int | None = None
    linked_to: int | None = None

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
        r = _reader(cls, payload)
        index = r.u8()
        rng = ModeRange._read(r)
        logic, linked = (*_read_tail(r, (r.u8, r.u8)), None, None)[:2]
        if logic is not None and linked is None:
            raise MspDecodeError("MSP SetModeRange: mode logic without linked box id")
        try:
            return cls(index, rng, logic, linked)
        except MspRequestError as exc:
            raise MspDecodeError(str(exc)) from exc

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(self.index)
        self.range._write(w)
        _write_tail((self.mode_logic, self.linked_to), (w.u8, w.u8))
        return w.build()


# --------------------------------------------------------------------------------------------
# RC input


@dataclass(frozen=True, slots=True)
class SetRawRc:
    """MSP_SET_RAW_RC (200) request: N x U16 channel values in us, N <= 18 (msp.c:2715-2730).

    Channels are in the RECEIVER (map) order, ``AETR1234`` by default: roll, pitch, THROTTLE,
    YAW, AUX1... Use :meth:`from_sticks` to build it from named sticks. Channels not sent are
    set to 0 (rx/msp.c:54-57), i.e. invalid, so send every channel you rely on, every time.
    The reply is an empty ACK, even when MSP is not the active receiver.
    """

    COMMAND: ClassVar[int] = MspCommand.SET_RAW_RC
    channels_us: tuple[int, ...]

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
        r = _reader(cls, payload)
        count = _array(r, 2, "MSP SetRawRc")
        if not 1 <= count <= MAX_RC_CHANNELS:
            raise MspDecodeError(f"MSP SetRawRc: {count} channels, the FC takes 1..18")
        return cls(tuple(r.u16() for _ in range(count)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter()
        for value in self.channels_us:
            w.u16(value)
        return w.build()


# --------------------------------------------------------------------------------------------
# control


@dataclass(frozen=True, slots=True)
class EepromWrite:
    """MSP_EEPROM_WRITE (250): empty request and empty reply (msp.c:3398-3415). Saves without
    rebooting; refused with an error reply while armed."""

    COMMAND: ClassVar[int] = MspCommand.EEPROM_WRITE

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        return cls()

    def encode(self) -> bytes:
        return b""


@dataclass(frozen=True, slots=True)
class Reboot:
    """MSP_REBOOT (68) request: [U8 mode] (msp.c:2367-2404; absent = firmware). The FC reboots
    after replying, even while armed; on SITL a reboot ends the process."""

    COMMAND: ClassVar[int] = MspCommand.REBOOT
    mode: int = RebootMode.FIRMWARE

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.u8() if r.remaining() else RebootMode.FIRMWARE)

    @_encoder
    def encode(self) -> bytes:
        return PayloadWriter().u8(self.mode).build()


@dataclass(frozen=True, slots=True)
class RebootReply:
    """MSP_REBOOT (68) reply: U8 mode, plus U8 ready flag for MSC mode (msp.c:2382-2393)."""

    COMMAND: ClassVar[int] = MspCommand.REBOOT
    mode: int
    msc_ready: int | None = None

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        return cls(r.u8(), *_read_tail(r, (r.u8,)))

    @_encoder
    def encode(self) -> bytes:
        w = PayloadWriter().u8(self.mode)
        _write_tail((self.msc_ready,), (w.u8,))
        return w.build()


@dataclass(frozen=True, slots=True)
class SetRtc:
    """MSP_SET_RTC (246) request: U32 unix seconds (read as int32), U16 milliseconds
    (msp.c:4052-4063). Until it is set, MSP_RTC answers with an empty payload."""

    COMMAND: ClassVar[int] = MspCommand.SET_RTC
    unix_seconds: int
    millis: int = 0

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

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        seconds, millis = r.s32(), r.u16()
        try:
            return cls(seconds, millis)
        except MspRequestError as exc:
            raise MspDecodeError(str(exc)) from exc

    @_encoder
    def encode(self) -> bytes:
        return PayloadWriter().u32(self.unix_seconds).u16(self.millis).build()


@dataclass(frozen=True, slots=True)
class Rtc:
    """MSP_RTC (247): U16 year, U8 month, day, hours, minutes, seconds, U16 millis, UTC
    (msp.c:2204-2217). Empty while the clock was never set (then every field is None)."""

    COMMAND: ClassVar[int] = MspCommand.RTC
    year: int | None = None
    month: int | None = None
    day: int | None = None
    hours: int | None = None
    minutes: int | None = None
    seconds: int | None = None
    millis: int | None = None

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

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        r = _reader(cls, payload)
        if not r.remaining():
            return cls()
        return cls(r.u16(), r.u8(), r.u8(), r.u8(), r.u8(), r.u8(), r.u16())

    @_encoder
    def encode(self) -> bytes:
        if self.year is None:
            return b""
        fields = (self.month, self.day, self.hours, self.minutes, self.seconds, self.millis)
        if any(value is None for value in fields):
            raise MspRequestError("Rtc: either all fields or none")
        w = PayloadWriter().u16(self.year)
        for value in fields[:-1]:
            w.u8(value)  # type: ignore[arg-type]
        return w.u16(self.millis).build()  # type: ignore[arg-type]


# --------------------------------------------------------------------------------------------
# batching


@dataclass(frozen=True, slots=True)
class MultipleMspRequest:
    """MSP_MULTIPLE_MSP (230) request: one U8 command id per parameterless v1 command
    (msp.c:2406-2437). The FC runs them in order and answers in one frame."""

    COMMAND: ClassVar[int] = MspCommand.MULTIPLE_MSP
    commands: tuple[int, ...]

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

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        try:
            return cls(tuple(bytes(payload)))
        except MspRequestError as exc:
            raise MspDecodeError(str(exc)) from exc

    def encode(self) -> bytes:
        return bytes(self.commands)


@dataclass(frozen=True, slots=True)
class MultipleMspReply:
    """MSP_MULTIPLE_MSP (230) reply: ``[U8 len][payload]`` per command, in request order
    (msp.c:2420-2434). A failed or unknown command contributes length 0. Commands that would not
    fit the FC's output buffer are left off the end, so there may be fewer sub-replies than
    commands. The length byte is a uint8, so a sub-reply of 256 bytes or more is unusable."""

    COMMAND: ClassVar[int] = MspCommand.MULTIPLE_MSP
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
        r = _reader(cls, payload)
        parts: list[bytes] = []
        while r.remaining():
            parts.append(r.raw(r.u8()))
        return cls(tuple(parts))

    def encode(self) -> bytes:
        w = PayloadWriter()
        for part in self.payloads:
            if len(part) > 255:
                raise MspRequestError(
                    f"a sub-reply of {len(part)} bytes does not fit its U8 length"
                )
            w.u8(len(part)).raw(part)
        return w.build()


# --------------------------------------------------------------------------------------------
# registry

_REPLY_CLASSES: tuple[type, ...] = (
    ApiVersion, FcVariant, FcVersion, BoardInfo, BuildInfo, McuInfo, CraftName, Uid, Status,
    StatusEx, RawImu, Motor, Rc, Attitude, Altitude, Analog, BatteryState, SensorConfigActive,
    Debug, MotorTelemetry, ArmingConfig, FeatureConfig, RxMap, BoxNames, BoxIds, ModeRanges,
    EepromWrite, RebootReply, Rtc, MultipleMspReply, RcTuning, PidAdvanced,
)  # fmt: skip

_REQUEST_CLASSES: tuple[type, ...] = (
    SetArmingConfig, SetFeatureConfig, SetRxMap, SetModeRange, SetRawRc, EepromWrite, Reboot,
    SetRtc, MultipleMspRequest,
)  # fmt: skip

#: Command id -> class of the FC's reply payload.
REPLY_TYPES: dict[int, type] = {cls.COMMAND: cls for cls in _REPLY_CLASSES}  # type: ignore[attr-defined]

#: Command id -> class of the request payload (for fakes that play the FC).
REQUEST_TYPES: dict[int, type] = {cls.COMMAND: cls for cls in _REQUEST_CLASSES}  # type: ignore[attr-defined]


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
