"""Gazebo's state out of the plugin's fdm packets: NED and FRD whatever the world's transforms.

Each case is a physical situation in Gazebo's ENU world (a model pose), turned into the packet
the plugin would send by the plugin's own formula (``SendState``: ``q = conj(q_to_ned) *
q_world_link * q_model_to_airplane``, ``p = R(conj(q_to_ned)) p_world``), then read back.  The
expected NED and Betaflight attitude are written out by hand from the situation, not computed
by the code under test.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from bfsitl.errors import GazeboError
from bfsitl.gazebo.plugin_frame import PluginFrame
from bfsitl.gazebo.world import (
    GAZEBO_XYZ_TO_NED_BRIDGE,
    GAZEBO_XYZ_TO_NED_COPIED,
    WorldChanges,
    world_for_profile,
    world_path,
    write_session_world,
)
from bfsitl.physics.frames import (
    betaflight_attitude_deg,
    body_to_world,
    quat_conjugate,
    quat_from_euler_rad,
    quat_multiply,
)
from bfsitl.physics.params import Quat, Vec3
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, Generation, profile_for
from bfsitl.protocol.sitl_packets import FdmPacket


def _rpy(text: str) -> Vec3:
    numbers = [float(x) for x in text.split()]
    return (numbers[3], numbers[4], numbers[5])


def plugin_packet(
    frame: PluginFrame, position_enu: Vec3, q_enu_flu: Quat, velocity_enu: Vec3 = (0, 0, 0)
) -> FdmPacket:
    """What the plugin sends for imu_link at this ENU pose (BetaflightPlugin.cpp SendState)."""
    q_to_ned = quat_from_euler_rad(*frame.gazebo_to_ned_rpy)
    q_off = quat_from_euler_rad(*frame.model_to_airplane_rpy)
    undo = quat_conjugate(q_to_ned)
    return FdmPacket(
        timestamp_s=12.5,
        quaternion_wxyz=quat_multiply(quat_multiply(undo, q_enu_flu), q_off),
        velocity_m_s=body_to_world(undo, velocity_enu),
        position=body_to_world(undo, position_enu),
    )


#: Gazebo's model yaw (about +z up, from +x east) for each heading: east is 0, north +90 deg.
FACING_EAST = quat_from_euler_rad(0.0, 0.0, 0.0)
FACING_NORTH = quat_from_euler_rad(0.0, 0.0, math.pi / 2)

FRAMES = {
    "4.6.0's world": PluginFrame(gazebo_to_ned_rpy=_rpy(GAZEBO_XYZ_TO_NED_COPIED)),
    "master's world": PluginFrame(gazebo_to_ned_rpy=_rpy(GAZEBO_XYZ_TO_NED_BRIDGE)),
    "the plugin's defaults": PluginFrame(),
}


@pytest.mark.parametrize("frame", FRAMES.values(), ids=FRAMES.keys())
def test_position_and_velocity_come_out_north_east_down(frame: PluginFrame) -> None:
    # 1 m east, 2 m north, 3 m up, climbing at 0.5 m/s while moving north at 4 m/s.
    state = frame.state(plugin_packet(frame, (1.0, 2.0, 3.0), FACING_EAST, (0.0, 4.0, 0.5)))
    assert state.position_ned_m == pytest.approx((2.0, 1.0, -3.0), abs=1e-9)
    assert state.velocity_ned_m_s == pytest.approx((4.0, 0.0, -0.5), abs=1e-9)
    assert state.altitude_m == pytest.approx(3.0)
    assert state.sim_time_s == 12.5


@pytest.mark.parametrize("frame", FRAMES.values(), ids=FRAMES.keys())
def test_heading_is_clockwise_from_north(frame: PluginFrame) -> None:
    for model_yaw, heading_deg in ((FACING_EAST, 90.0), (FACING_NORTH, 0.0)):
        attitude = frame.state(plugin_packet(frame, (0, 0, 1), model_yaw)).quaternion_wxyz
        roll, pitch, yaw = betaflight_attitude_deg(attitude)
        assert (roll, pitch) == pytest.approx((0.0, 0.0), abs=1e-6)
        assert yaw % 360.0 == pytest.approx(heading_deg, abs=1e-6)


@pytest.mark.parametrize("frame", FRAMES.values(), ids=FRAMES.keys())
def test_right_wing_down_is_positive_roll_and_nose_down_positive_pitch(
    frame: PluginFrame,
) -> None:
    # Facing north, the right wing points east (+x).  Right wing down: the body turns about
    # its forward axis (+y, north) so that +x goes down: +20 deg about +y.
    q = quat_multiply(_about((0.0, 1.0, 0.0), math.radians(20.0)), FACING_NORTH)
    roll, pitch, yaw = _attitude(frame, q)
    assert roll == pytest.approx(20.0, abs=1e-6)
    assert pitch == pytest.approx(0.0, abs=1e-6)
    # Nose down facing north: the nose (+y) goes down, a turn about the right wing (+x east)
    # by -15 deg.  Betaflight's pitch is nose down positive.
    q = quat_multiply(_about((1.0, 0.0, 0.0), -math.radians(15.0)), FACING_NORTH)
    roll, pitch, yaw = _attitude(frame, q)
    assert roll == pytest.approx(0.0, abs=1e-6)
    assert pitch == pytest.approx(15.0, abs=1e-6)
    assert yaw % 360.0 == pytest.approx(0.0, abs=1e-6)


def _attitude(frame: PluginFrame, q_enu_flu: Quat) -> Vec3:
    return betaflight_attitude_deg(
        frame.state(plugin_packet(frame, (0, 0, 1), q_enu_flu)).quaternion_wxyz
    )


def _about(axis: Vec3, angle_rad: float) -> Quat:
    s = math.sin(angle_rad / 2)
    return (math.cos(angle_rad / 2), axis[0] * s, axis[1] * s, axis[2] * s)


def test_the_frame_is_read_from_each_world(tmp_path: Path) -> None:
    shipped = PluginFrame.of_world(world_path())
    expected = FRAMES["4.6.0's world"]
    assert shipped.gazebo_to_ned_rpy == pytest.approx(expected.gazebo_to_ned_rpy, abs=1e-6)
    assert shipped.model_to_airplane_rpy == pytest.approx(expected.model_to_airplane_rpy, abs=1e-6)
    master = profile_for("1.49", "2026.12.0")
    assert master.generation is Generation.MASTER
    derived = PluginFrame.of_world(world_for_profile(master, tmp_path))
    assert derived.gazebo_to_ned_rpy == pytest.approx(FRAMES["master's world"].gazebo_to_ned_rpy)
    # The relay's copy keeps the transforms and moves only the ports.
    relayed = write_session_world(world_path(), tmp_path, WorldChanges(9102, 9103))
    assert PluginFrame.of_world(relayed) == shipped
    text = relayed.read_text()
    assert "<fdm_port_in>9102</fdm_port_in>" in text
    assert "<fcu_port_out>9103</fcu_port_out>" in text
    assert world_for_profile(DEFAULT_PROFILE, tmp_path) == world_path()


def test_a_world_without_the_plugin_or_with_a_bad_transform_is_refused(tmp_path: Path) -> None:
    bare = tmp_path / "bare.sdf"
    bare.write_text("<sdf version='1.9'><world name='w'/></sdf>")
    with pytest.raises(GazeboError, match="BetaflightPlugin"):
        PluginFrame.of_world(bare)
    bad = tmp_path / "bad.sdf"
    bad.write_text(
        "<sdf><world name='w'><model name='m'><plugin filename='BetaflightPlugin' name='p'>"
        "<gazeboXYZToNED>0 0 0 pi 0</gazeboXYZToNED></plugin></model></world></sdf>"
    )
    with pytest.raises(GazeboError, match="six numbers"):
        PluginFrame.of_world(bad)
    with pytest.raises(GazeboError, match="cannot read"):
        PluginFrame.of_world(tmp_path / "missing.sdf")
