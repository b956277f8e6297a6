"""What the BetaflightPlugin's fdm packets say about Gazebo's vehicle, in bfsitl's frames.

The plugin fills each fdm_packet from Gazebo's own state: ``imu_link``'s world pose and linear
velocity, turned by two transforms of its ``<plugin>`` element, and the IMU sensor's rates
and specific force (``SendState`` in vehicle_gateway's BetaflightPlugin.cpp)::

    q_packet = conj(q_to_ned) * q_world_link * q_model_to_airplane
    p_packet = R(conj(q_to_ned)) * p_world,   v_packet = R(conj(q_to_ned)) * v_world

where ``q_to_ned`` is ``<gazeboXYZToNED>`` and ``q_model_to_airplane`` is
``<modelXYZToAirplaneXForwardZDown>`` (Gazebo's ``Pose3 - Pose3`` and ``+``).  A world made
for 4.6.0 has ``gazeboXYZToNED`` = roll pi, yaw pi/2, which is exactly ENU -> NED, so its
packets carry NED position and velocity and the FRD -> NED attitude; a world made for master
keeps roll pi only and the packets are in another frame.  :class:`PluginFrame` undoes
whichever transforms a world has, so the truth bfsitl logs is NED and FRD for any world.
"""

from __future__ import annotations

import functools
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import GazeboError
from bfsitl.physics.frames import (
    GeoPoint,
    body_to_world,
    ned_to_enu,
    ned_to_geodetic,
    quat_conjugate,
    quat_from_euler_rad,
    quat_multiply,
)
from bfsitl.physics.params import Quat, Vec3
from bfsitl.protocol.sitl_packets import FdmPacket

#: The plugin's defaults when the element does not set them (BetaflightPlugin.cpp).
DEFAULT_MODEL_TO_AIRPLANE_RPY: Vec3 = (math.pi, 0.0, 0.0)
DEFAULT_GAZEBO_TO_NED_RPY: Vec3 = (math.pi, 0.0, 0.0)

#: ENU -> NED as a Gazebo pose (roll pi, then yaw pi/2): the frame the packets should be in.
_ENU_TO_NED: Quat = quat_from_euler_rad(math.pi, 0.0, math.pi / 2)
#: A Gazebo model is x forward, y left, z up; FRD is that rolled by pi.
_FLU_TO_FRD: Quat = quat_from_euler_rad(math.pi, 0.0, 0.0)


@dataclass(frozen=True, slots=True)
class GazeboState:
    """Gazebo's vehicle at one fdm packet: world NED from the world's origin, body FRD."""

    sim_time_s: float
    position_ned_m: Vec3
    velocity_ned_m_s: Vec3
    #: Body FRD -> world NED.
    quaternion_wxyz: Quat
    #: What the IMU sensor measured, in the sensor's own frame (FRD in bfsitl's world).
    gyro_rad_s: Vec3
    specific_force_m_s2: Vec3
    pressure_pa: float

    @property
    def altitude_m(self) -> float:
        """Height of ``imu_link`` above the world's origin (the ground plane), up positive."""
        return -self.position_ned_m[2]


@dataclass(frozen=True, slots=True)
class PluginFrame:
    """The two transforms of one world's ``<plugin filename="BetaflightPlugin">``, as
    (roll, pitch, yaw) in radians, and how to undo them."""

    model_to_airplane_rpy: Vec3 = DEFAULT_MODEL_TO_AIRPLANE_RPY
    gazebo_to_ned_rpy: Vec3 = DEFAULT_GAZEBO_TO_NED_RPY

    @classmethod
    def of_world(cls, world: Path) -> PluginFrame:
        """Read the transforms from a world file (the plugin's defaults where unset)."""
        try:
            root = ET.parse(world).getroot()
        except (OSError, ET.ParseError) as exc:
            raise GazeboError(f"cannot read the Gazebo world {world}: {exc}") from exc
        plugin = root.find(".//plugin[@filename='BetaflightPlugin']")
        if plugin is None:
            raise GazeboError(
                f'{world} has no <plugin filename="BetaflightPlugin">: bfsitl flies Gazebo '
                f"through that plugin (docs/gazebo.md)"
            )
        return cls(
            _pose_rpy(plugin, "modelXYZToAirplaneXForwardZDown", DEFAULT_MODEL_TO_AIRPLANE_RPY),
            _pose_rpy(plugin, "gazeboXYZToNED", DEFAULT_GAZEBO_TO_NED_RPY),
        )

    def state(self, packet: FdmPacket) -> GazeboState:
        """Gazebo's state as one packet reports it, in NED and FRD."""
        to_ned = _ned_from_packet(self.gazebo_to_ned_rpy)
        attitude = quat_multiply(
            quat_multiply(to_ned, packet.quaternion_wxyz),
            _frd_from_airplane(self.model_to_airplane_rpy),
        )
        return GazeboState(
            sim_time_s=packet.timestamp_s,
            # body_to_world is the rotation by a quaternion: here, by the packet frame -> NED.
            position_ned_m=body_to_world(to_ned, packet.position),
            velocity_ned_m_s=body_to_world(to_ned, packet.velocity_m_s),
            quaternion_wxyz=attitude,
            gyro_rad_s=packet.gyro_rad_s,
            specific_force_m_s2=packet.accel_m_s2,
            pressure_pa=packet.pressure_pa,
        )


# One world's two turns, made once: the relay reads a thousand packets a second.
@functools.cache
def _ned_from_packet(gazebo_to_ned_rpy: Vec3) -> Quat:
    # p_ned = R(conj(q_enu_to_ned) * q_to_ned) p_packet: undo the world's turn, do ENU -> NED.
    return quat_multiply(quat_conjugate(_ENU_TO_NED), quat_from_euler_rad(*gazebo_to_ned_rpy))


@functools.cache
def _frd_from_airplane(model_to_airplane_rpy: Vec3) -> Quat:
    # body FRD = airplane * conj(q_model_to_airplane) * q_flu_to_frd.
    return quat_multiply(quat_conjugate(quat_from_euler_rad(*model_to_airplane_rpy)), _FLU_TO_FRD)


def _pose_rpy(plugin: ET.Element, tag: str, default: Vec3) -> Vec3:
    element = plugin.find(tag)
    if element is None or not (element.text or "").strip():
        return default
    try:
        numbers = [float(part) for part in (element.text or "").split()]
    except ValueError as exc:
        raise GazeboError(f"<{tag}> must be six numbers (x y z roll pitch yaw): {exc}") from exc
    if len(numbers) != 6:
        raise GazeboError(f"<{tag}> must be six numbers (x y z roll pitch yaw), got {numbers}")
    return (numbers[3], numbers[4], numbers[5])


def gps_fields(state: GazeboState, home: GeoPoint) -> tuple[Vec3, Vec3]:
    """What a 4.6.0 build with ``-DUSE_GPS`` reads from the fdm packet's position_xyz and
    velocity_xyz: (longitude, latitude in degrees, altitude above sea level in metres) and ENU
    metres per second (docs/firmware-facts.md#no-gps), for Gazebo's state with the world's
    origin at ``home``.  The plugin sends NED metres there, which such a build would take as
    a position near 0 N 0 E jumping a degree per metre."""
    point = ned_to_geodetic(state.position_ned_m, home)
    return (point.lon_deg, point.lat_deg, point.alt_m), ned_to_enu(state.velocity_ned_m_s)
