"""SITL UDP packets: exact layouts from target.h, and refusal of malformed datagrams."""

from __future__ import annotations

import math
import struct

import pytest

from bfsitl.errors import PacketError
from bfsitl.protocol.sitl_packets import FdmPacket, RcPacket, ServoPacket, ServoPacketRaw


def test_fdm_packet_is_144_bytes_in_declaration_order():
    packet = FdmPacket(
        timestamp_s=1.5,
        gyro_rad_s=(0.1, 0.2, 0.3),
        accel_m_s2=(1.0, 2.0, -9.8),
        quaternion_wxyz=(1.0, 0.0, 0.0, 0.0),
        velocity_m_s=(4.0, 5.0, 6.0),
        position=(7.0, 8.0, 9.0),
        pressure_pa=101000.0,
    )
    wire = packet.pack()
    assert len(wire) == 144
    assert struct.unpack("<18d", wire) == (
        1.5,
        0.1,
        0.2,
        0.3,
        1.0,
        2.0,
        -9.8,
        1.0,
        0.0,
        0.0,
        0.0,
        4.0,
        5.0,
        6.0,
        7.0,
        8.0,
        9.0,
        101000.0,
    )
    assert FdmPacket.unpack(wire) == packet


def test_fdm_default_is_level_at_rest():
    values = struct.unpack("<18d", FdmPacket(0.0).pack())
    assert values[4:7] == (0.0, 0.0, -9.80665) and values[7:11] == (1.0, 0.0, 0.0, 0.0)


@pytest.mark.parametrize("size", [0, 143, 145, 40])
def test_wrong_size_datagrams_are_rejected_not_half_decoded(size):
    with pytest.raises(PacketError, match="144-byte"):
        FdmPacket.unpack(bytes(size))


def test_non_finite_values_are_rejected_both_ways():
    wire = bytearray(FdmPacket(0.0).pack())
    wire[8:16] = struct.pack("<d", math.nan)
    with pytest.raises(PacketError, match="finite"):
        FdmPacket.unpack(bytes(wire))
    with pytest.raises(PacketError, match="finite"):
        FdmPacket(0.0, gyro_rad_s=(math.inf, 0.0, 0.0)).pack()
    with pytest.raises(PacketError, match="finite"):
        ServoPacket.unpack(struct.pack("<4f", 0.5, math.nan, 0.5, 0.5))


def test_pressure_must_be_positive():
    with pytest.raises(PacketError, match="pressure"):
        FdmPacket(0.0, pressure_pa=0.0).pack()


def test_servo_packet_slots_map_to_betaflight_motor_numbers():
    # sitl.c: motor_speed[3] = M1, [0] = M2, [1] = M3, [2] = M4
    packet = ServoPacket.unpack(struct.pack("<4f", 0.2, 0.3, 0.4, 0.1))
    assert packet.betaflight_motors() == pytest.approx((0.1, 0.2, 0.3, 0.4))
    assert ServoPacket.from_betaflight_motors((0.1, 0.2, 0.3, 0.4)).pack() == packet.pack()
    with pytest.raises(PacketError):
        ServoPacket.unpack(bytes(15))


def test_servo_packet_raw_has_c_padding_after_the_count():
    wire = struct.pack("<H2x16f", 4, *([1500.0] * 4 + [0.0] * 12))
    assert len(wire) == 68
    packet = ServoPacketRaw.unpack(wire)
    assert packet.motor_count == 4 and packet.pwm_output_raw[:4] == (1500.0,) * 4
    assert packet.pack() == wire


def test_rc_packet_pads_to_16_channels_and_validates():
    wire = RcPacket(2.0, (1500, 1500, 1000, 1500, 1800)).pack()
    assert len(wire) == 40
    assert struct.unpack("<d16H", wire) == (2.0, 1500, 1500, 1000, 1500, 1800) + (0,) * 11
    assert RcPacket.unpack(wire).channels_us[:5] == (1500, 1500, 1000, 1500, 1800)
    with pytest.raises(PacketError):
        RcPacket(0.0, (1500,) * 17).pack()
    with pytest.raises(PacketError):
        RcPacket(0.0, (70000,)).pack()
    with pytest.raises(PacketError, match="40-byte"):
        RcPacket.unpack(bytes(39))
