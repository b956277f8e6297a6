"""Sensors and telemetry: IMU, attitude, altitude, GPS, battery, motors, debug values."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, ClassVar

from bfsitl.protocol.messages.constants import (
    BATTERY_STATE_NAMES,
    GYRO_LSB_PER_DPS,
    SITL_ACC_1G_LSB,
)
from bfsitl.protocol.messages.layout import WireRecord, msp_message, wire_record
from bfsitl.protocol.messages.wire_types import (
    S16,
    S32,
    TAIL,
    TAIL_IF_WHOLE,
    U8,
    U16,
    U32,
    Array,
    Counted,
    RestArray,
    s16,
    u8,
    u16,
)
from bfsitl.protocol.msp_codes import MspCommand

#: MSP_MOTOR always carries this many motors (msp.c:1192-1205).
_MOTOR_SLOTS = 8


@msp_message(MspCommand.RAW_IMU)
@dataclass(frozen=True, slots=True)
class RawImu(WireRecord):
    """MSP_RAW_IMU (102): 3 x S16 acc, gyro, mag, all raw sensor LSB (msp.c:1139-1158).

    Not physical units: convert with :meth:`acc_g` and :meth:`gyro_dps`. Mag is 0 without a mag.
    """

    acc_raw: Annotated[tuple[int, int, int], Array(s16, 3)]
    gyro_raw: Annotated[tuple[int, int, int], Array(s16, 3)]
    mag_raw: Annotated[tuple[int, int, int], Array(s16, 3)]

    def acc_g(self, acc_1g_lsb: float = SITL_ACC_1G_LSB) -> tuple[float, float, float]:
        """Acceleration in g; pass 2048 (or the board's ``acc_1G``) for a real IMU."""
        x, y, z = self.acc_raw
        return (x / acc_1g_lsb, y / acc_1g_lsb, z / acc_1g_lsb)

    def gyro_dps(self, lsb_per_dps: float = GYRO_LSB_PER_DPS) -> tuple[float, float, float]:
        """Rotation rate in deg/s; pass 8.192 for a 4000 dps (``gyro_high_range``) sensor."""
        x, y, z = self.gyro_raw
        return (x / lsb_per_dps, y / lsb_per_dps, z / lsb_per_dps)


@msp_message(MspCommand.MOTOR)
@dataclass(frozen=True, slots=True)
class Motor(WireRecord):
    """MSP_MOTOR (104): always 8 x U16 motor outputs in PWM us (DShot mapped to 1000-2000),
    0 for absent or disabled motors (msp.c:1192-1205). SITL disarmed: 1000 x 4, then 0 x 4.
    Fewer motors are sent padded with 0."""

    COUNT: ClassVar[int] = _MOTOR_SLOTS
    motors_us: Annotated[
        tuple[int, ...],
        Array(u16, _MOTOR_SLOTS, fill=0, count_error="MSP_MOTOR carries {count} motors, got {got}"),
    ]


@msp_message(MspCommand.ATTITUDE)
@dataclass(frozen=True, slots=True)
class Attitude(WireRecord):
    """MSP_ATTITUDE (108): S16 roll and pitch in DECIdegrees, S16 yaw in WHOLE degrees 0..359
    (msp.c:1317-1321).

    Roll is positive right wing down. Pitch is positive NOSE DOWN (Betaflight's convention, the
    opposite of aerospace nose-up). Yaw is the heading, clockwise from north.
    """

    roll_decideg: S16
    pitch_decideg: S16
    yaw_deg: S16

    @property
    def roll_deg(self) -> float:
        return self.roll_decideg / 10.0

    @property
    def pitch_deg(self) -> float:
        """Positive nose down."""
        return self.pitch_decideg / 10.0


@msp_message(MspCommand.RAW_GPS)
@dataclass(frozen=True, slots=True)
class RawGps(WireRecord):
    """MSP_RAW_GPS (106): U8 fix, U8 satellites, S32 lat and lon in 1e-7 deg, U16 altitude in
    WHOLE metres (clamped at 0), U16 ground speed cm/s, U16 course in decidegrees, U16 PDOP
    (1.44) (msp.c MSP_RAW_GPS). Only builds with GPS answer it; others send an error frame.
    """

    fix: U8
    satellites: U8
    lat_e7: S32
    lon_e7: S32
    altitude_m: U16
    ground_speed_cm_s: U16
    course_decideg: U16
    pdop: Annotated[U16 | None, TAIL_IF_WHOLE] = None

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


@msp_message(MspCommand.ALTITUDE)
@dataclass(frozen=True, slots=True)
class Altitude(WireRecord):
    """MSP_ALTITUDE (109): S32 altitude cm, S16 vario cm/s (msp.c:1323-1330).

    Positive UP (not NED). Disarmed: baro altitude relative to the boot-time calibration (or GPS
    altitude with a 3D fix); armed: zeroed at arming and low-pass filtered. Vario is 0 while
    disarmed (flight/position.c).
    """

    altitude_cm: S32
    vario_cm_s: S16

    @property
    def altitude_m(self) -> float:
        return self.altitude_cm / 100.0

    @property
    def vario_m_s(self) -> float:
        return self.vario_cm_s / 100.0


@msp_message(MspCommand.ANALOG)
@dataclass(frozen=True, slots=True)
class Analog(WireRecord):
    """MSP_ANALOG (110): U8 battery 0.1 V (clamped to 255), U16 mAh drawn, U16 RSSI 0..1023,
    S16 current 0.01 A, U16 battery 0.01 V (msp.c:763-769)."""

    vbat_dv: U8
    mah_drawn: U16
    rssi: U16
    amperage_ca: S16
    vbat_cv: Annotated[U16 | None, TAIL] = None

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


@msp_message(MspCommand.BATTERY_STATE)
@dataclass(frozen=True, slots=True)
class BatteryState(WireRecord):
    """MSP_BATTERY_STATE (130): U8 cells, U16 capacity mAh, U8 0.1 V, U16 mAh drawn, S16 0.01 A,
    U8 state (sensors/battery.h:88-94), U16 0.01 V (msp.c:795-810)."""

    cell_count: U8
    capacity_mah: U16
    vbat_dv: U8
    mah_drawn: U16
    amperage_ca: S16
    state: U8
    vbat_cv: Annotated[U16 | None, TAIL] = None

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


@msp_message(MspCommand.MSP2_SENSOR_CONFIG_ACTIVE)
@dataclass(frozen=True, slots=True)
class SensorConfigActive(WireRecord):
    """MSP2_SENSOR_CONFIG_ACTIVE (0x300A, 1.46): the detected hardware type per sensor, U8 each:
    gyro, acc, baro, mag, rangefinder, optical flow; 0xFF = not compiled in (msp.c:2113-2145)."""

    gyro_hw: U8
    acc_hw: U8
    baro_hw: U8
    mag_hw: U8
    rangefinder_hw: U8
    opticalflow_hw: U8


@msp_message(MspCommand.DEBUG)
@dataclass(frozen=True, slots=True)
class Debug(WireRecord):
    """MSP_DEBUG (254): the ``debug[]`` array as S16 (8 values in 4.6, ``DEBUG16_VALUE_COUNT``,
    build/debug.h:25; older firmware sent 4), msp.c:771-775. Meaning set by ``debug_mode``."""

    values: Annotated[tuple[int, ...], RestArray(s16)]


@wire_record
@dataclass(frozen=True, slots=True)
class MotorTelemetryEntry(WireRecord):
    """One motor of MSP_MOTOR_TELEMETRY (13 bytes, msp.c:1266-1271)."""

    SIZE: ClassVar[int] = 13
    rpm: U32
    invalid_centipercent: U16  # share of invalid DShot telemetry frames, 0.01 % (10000 = 100 %)
    temperature_c: U8
    voltage_cv: U16
    current_ca: U16
    consumption_mah: U16

    @property
    def invalid_percent(self) -> float:
        return self.invalid_centipercent / 100.0

    @property
    def voltage_v(self) -> float:
        return self.voltage_cv / 100.0

    @property
    def current_a(self) -> float:
        return self.current_ca / 100.0


@msp_message(MspCommand.MOTOR_TELEMETRY)
@dataclass(frozen=True, slots=True)
class MotorTelemetry(WireRecord):
    """MSP_MOTOR_TELEMETRY (139, 1.42): U8 motor count, then per motor U32 rpm, U16 invalid
    0.01 %, U8 temperature C, U16 0.01 V, U16 0.01 A, U16 mAh (msp.c:1208-1273). All zero
    without DShot telemetry or ESC sensor (always on SITL)."""

    motors: Annotated[tuple[MotorTelemetryEntry, ...], Counted(u8, MotorTelemetryEntry)]
