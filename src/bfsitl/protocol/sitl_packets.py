"""The SITL's UDP datagrams as typed values (``src/platform/SIMULATOR/target/SITL/target.h``).

| packet             | port | direction      | layout                                   |
| ------------------ | ---- | -------------- | ---------------------------------------- |
| ``fdm_packet``     | 9003 | sim -> SITL    | ``<d 3d 3d 4d 3d 3d d`` = 144 bytes       |
| ``servo_packet``   | 9002 | SITL -> sim    | ``<4f`` = 16 bytes                       |
| ``servo_packet_raw`` | 9001 | SITL -> sim  | ``<H 2x 16f`` = 68 bytes (C pads the u16) |
| ``rc_packet``      | 9004 | host -> SITL   | ``<d 16H`` = 40 bytes                    |

The SITL itself ignores a datagram of the wrong size (``sitl.c`` compares ``n`` with
``sizeof``), so a packet that is half right would vanish silently; here it is an error instead.
Non-finite floats are refused both ways: a NaN in an fdm packet would become the FC's attitude.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from typing import ClassVar

from bfsitl.errors import PacketError

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]

#: Channels in an rc_packet (``SIMULATOR_MAX_RC_CHANNELS``).
RC_PACKET_CHANNELS = 16
#: PWM slots in a servo_packet_raw (``SIMULATOR_MAX_PWM_CHANNELS``).
RAW_PWM_CHANNELS = 16


def _check_size(kind: str, data: bytes, expected: int) -> None:
    if len(data) != expected:
        raise PacketError(
            f"{kind}: expected a {expected}-byte datagram, got {len(data)} bytes "
            f"(wrong port, or a firmware build with a different packet layout)"
        )


def _check_finite(kind: str, values: tuple[float, ...]) -> None:
    # One sum for the usual case (a NaN or an infinity makes it non-finite, and so would an
    # overflow of huge values, which the loop then clears); the loop names the field.
    if math.isfinite(sum(values)):
        return
    for index, value in enumerate(values):
        if not math.isfinite(value):
            raise PacketError(f"{kind}: field {index} is {value!r}; every value must be finite")


@dataclass(frozen=True, slots=True)
class FdmPacket:
    """Flight dynamics state for the FC (UDP 9003).

    The layout is the same in every generation; what the fields mean differs
    (:mod:`bfsitl.protocol.firmware_profile`, encoded by :mod:`bfsitl.protocol.fdm_encoding`).
    Conventions as the 4.6.0 SITL reads them (``sitl.c updateState``): gyro in body FRD rad/s
    (FC uses +x, -y, -z); accelerometer as specific force in m/s^2, which the FC negates, so a
    level craft at rest sends (0, 0, -9.80665); quaternion w, x, y, z body-FRD to world-NED,
    used directly as the attitude; pressure in Pa (must be > 0) is the barometer.  Position
    and velocity are only read by builds with virtual GPS, as lon/lat deg + alt m and ENU m/s.
    """

    timestamp_s: float
    gyro_rad_s: Vec3 = (0.0, 0.0, 0.0)
    accel_m_s2: Vec3 = (0.0, 0.0, -9.80665)
    quaternion_wxyz: Quat = (1.0, 0.0, 0.0, 0.0)
    velocity_m_s: Vec3 = (0.0, 0.0, 0.0)
    position: Vec3 = (0.0, 0.0, 0.0)
    pressure_pa: float = 101325.0

    FORMAT: ClassVar[struct.Struct] = struct.Struct("<d3d3d4d3d3dd")
    SIZE: ClassVar[int] = 144

    def _values(self) -> tuple[float, ...]:
        return (
            self.timestamp_s,
            *self.gyro_rad_s,
            *self.accel_m_s2,
            *self.quaternion_wxyz,
            *self.velocity_m_s,
            *self.position,
            self.pressure_pa,
        )

    def pack(self) -> bytes:
        values = self._values()
        if len(values) != 18:
            raise PacketError("fdm_packet: a vector field has the wrong number of elements")
        _check_finite("fdm_packet", values)
        if self.pressure_pa <= 0:
            raise PacketError(f"fdm_packet: pressure must be > 0 Pa, got {self.pressure_pa}")
        return self.FORMAT.pack(*values)

    @classmethod
    def unpack(cls, data: bytes) -> FdmPacket:
        _check_size("fdm_packet", data, cls.SIZE)
        v = cls.FORMAT.unpack(data)
        _check_finite("fdm_packet", v)
        return cls(v[0], v[1:4], v[4:7], v[7:11], v[11:14], v[14:17], v[17])


@dataclass(frozen=True, slots=True)
class ServoPacket:
    """Motor commands from the FC (UDP 9002): 0..1 (3D mode: -1..1).

    The slot order depends on the firmware generation
    (``FirmwareProfile.motor_slot_of_betaflight_motor``): 4.6.0 remaps them,
    ``motor_speed[3]`` is Betaflight motor 1, ``[0]`` motor 2, ``[1]`` motor 3, ``[2]`` motor 4
    (``sitl.c pwmCompleteMotorUpdate``); master sends them in order. :meth:`betaflight_motors`
    undoes either.
    """

    motor_speed: tuple[float, float, float, float]

    FORMAT: ClassVar[struct.Struct] = struct.Struct("<4f")
    SIZE: ClassVar[int] = 16
    #: motor_speed slot holding Betaflight motor 1, 2, 3, 4.
    SLOT_OF_BETAFLIGHT_MOTOR: ClassVar[tuple[int, int, int, int]] = (3, 0, 1, 2)

    def pack(self) -> bytes:
        _check_finite("servo_packet", tuple(self.motor_speed))
        return self.FORMAT.pack(*self.motor_speed)

    @classmethod
    def unpack(cls, data: bytes) -> ServoPacket:
        _check_size("servo_packet", data, cls.SIZE)
        values = cls.FORMAT.unpack(data)
        _check_finite("servo_packet", values)
        return cls(values)

    @classmethod
    def from_betaflight_motors(
        cls,
        motors: tuple[float, float, float, float],
        slots: tuple[int, int, int, int] | None = None,
    ) -> ServoPacket:
        values = [0.0] * 4
        for motor_index, slot in enumerate(
            cls.SLOT_OF_BETAFLIGHT_MOTOR if slots is None else slots
        ):
            values[slot] = motors[motor_index]
        return cls((values[0], values[1], values[2], values[3]))

    def betaflight_motors(
        self, slots: tuple[int, int, int, int] | None = None
    ) -> tuple[float, float, float, float]:
        """Motor commands in Betaflight numbering (M1, M2, M3, M4).

        ``slots``: the slot of each motor, from the firmware profile
        (``FirmwareProfile.motor_slot_of_betaflight_motor``); default 4.6's remap.
        """
        return self.in_betaflight_order(self.motor_speed, slots)

    @classmethod
    def in_betaflight_order(
        cls, motor_speed: tuple[float, ...], slots: tuple[int, int, int, int] | None = None
    ) -> tuple[float, float, float, float]:
        """:meth:`betaflight_motors` of the packet's four slots, without making the packet."""
        m = cls.SLOT_OF_BETAFLIGHT_MOTOR if slots is None else slots
        s = motor_speed
        return (s[m[0]], s[m[1]], s[m[2]], s[m[3]])


@dataclass(frozen=True, slots=True)
class ServoPacketRaw:
    """Raw PWM outputs (UDP 9001, the RealFlight bridge): motors first, then servos."""

    motor_count: int
    pwm_output_raw: tuple[float, ...]

    FORMAT: ClassVar[struct.Struct] = struct.Struct("<H2x16f")
    SIZE: ClassVar[int] = 68

    def pack(self) -> bytes:
        if len(self.pwm_output_raw) != RAW_PWM_CHANNELS:
            raise PacketError(f"servo_packet_raw: needs {RAW_PWM_CHANNELS} PWM values")
        if not 0 <= self.motor_count <= RAW_PWM_CHANNELS:
            raise PacketError(f"servo_packet_raw: motor_count {self.motor_count} out of range")
        _check_finite("servo_packet_raw", self.pwm_output_raw)
        return self.FORMAT.pack(self.motor_count, *self.pwm_output_raw)

    @classmethod
    def unpack(cls, data: bytes) -> ServoPacketRaw:
        _check_size("servo_packet_raw", data, cls.SIZE)
        count, *values = cls.FORMAT.unpack(data)
        _check_finite("servo_packet_raw", tuple(values))
        return cls(count, tuple(values))


@dataclass(frozen=True, slots=True)
class RcPacket:
    """RC channels for the FC (UDP 9004), in microseconds, receiver-map order (AETR1234...).

    The first rc_packet permanently replaces MSP as the SITL's RC source, and the SITL holds
    the last values forever when packets stop (no RXLOSS, no failsafe).  The timestamp is
    unused by 4.6.0 but sent anyway.
    """

    timestamp_s: float
    channels_us: tuple[int, ...]

    FORMAT: ClassVar[struct.Struct] = struct.Struct("<d16H")
    SIZE: ClassVar[int] = 40

    def pack(self) -> bytes:
        if len(self.channels_us) > RC_PACKET_CHANNELS:
            raise PacketError(
                f"rc_packet: at most {RC_PACKET_CHANNELS} channels, got {len(self.channels_us)}"
            )
        _check_finite("rc_packet", (self.timestamp_s,))
        for index, value in enumerate(self.channels_us):
            if not 0 <= value <= 0xFFFF:
                raise PacketError(f"rc_packet: channel {index + 1} = {value} is not a u16")
        padded = tuple(self.channels_us) + (0,) * (RC_PACKET_CHANNELS - len(self.channels_us))
        return self.FORMAT.pack(self.timestamp_s, *padded)

    @classmethod
    def unpack(cls, data: bytes) -> RcPacket:
        _check_size("rc_packet", data, cls.SIZE)
        timestamp, *channels = cls.FORMAT.unpack(data)
        _check_finite("rc_packet", (timestamp,))
        return cls(timestamp, tuple(channels))
