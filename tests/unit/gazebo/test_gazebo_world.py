"""The shipped Gazebo world: it parses, its BetaflightPlugin block is complete and consistent
with the model it drives, and it describes the same IRIS as bfsitl's embedded physics.

Gazebo is not installed here, so this reads the SDF with xml.etree and checks what the plugin
source reads (vehicle_gateway BetaflightPlugin.cpp: Configure, LoadControlChannels,
InitSockets) and how its names must resolve.  It does not prove that gz-sim accepts the file.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from bfsitl.errors import BfsitlError
from bfsitl.gazebo.world import (
    DEFAULT_WORLD,
    PRESSURE_TOPIC,
    WORLD_NAME,
    WORLDS_DIR,
    shipped_worlds,
    world_for_profile,
    world_path,
)
from bfsitl.physics.params import IRIS
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, FirmwareProfile, profile_for
from bfsitl.protocol.sitl_packets import ServoPacket

#: channel -> (rotor, multiplier): CCW (+838) front-right and rear-left, CW (-838) the others.
EXPECTED_CONTROLS = {
    0: ("rotor_0", 838.0),
    1: ("rotor_1", 838.0),
    2: ("rotor_2", -838.0),
    3: ("rotor_3", -838.0),
}
NESTED = "iris_with_standoffs"


@pytest.fixture(scope="module")
def world() -> ET.Element:
    root = ET.parse(world_path()).getroot()
    assert root.tag == "sdf"
    worlds = root.findall("world")
    assert len(worlds) == 1
    return worlds[0]


@pytest.fixture(scope="module")
def outer(world: ET.Element) -> ET.Element:
    models = [
        m
        for m in world.findall("model")
        if m.find("plugin[@filename='BetaflightPlugin']") is not None
    ]
    assert len(models) == 1, "exactly one model carries the BetaflightPlugin"
    return models[0]


@pytest.fixture(scope="module")
def nested(outer: ET.Element) -> ET.Element:
    model = outer.find(f"model[@name='{NESTED}']")
    assert model is not None
    return model


@pytest.fixture(scope="module")
def plugin(outer: ET.Element) -> ET.Element:
    plugins = outer.findall("plugin[@filename='BetaflightPlugin']")
    assert len(plugins) == 1
    return plugins[0]


def text(element: ET.Element, path: str) -> str:
    found = element.find(path)
    assert found is not None and found.text is not None, f"missing <{path}>"
    return found.text.strip()


def numbers(value: str) -> list[float]:
    return [float(part) for part in value.split()]


def rotation_rpy(roll: float, pitch: float, yaw: float) -> list[list[float]]:
    """The rotation of an SDF/gz-math pose: Rz(yaw) * Ry(pitch) * Rx(roll)."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]


def column(matrix: list[list[float]], index: int) -> list[float]:
    return [row[index] for row in matrix]


# --- the file ----------------------------------------------------------------------------------


def test_the_default_world_is_package_data() -> None:
    assert DEFAULT_WORLD in shipped_worlds()
    assert world_path().parent == WORLDS_DIR and world_path().is_file()


def test_world_path_takes_a_file_path_and_rejects_unknown_names(tmp_path: Path) -> None:
    custom = tmp_path / "mine.sdf"
    custom.write_text("<sdf/>")
    assert world_path(custom) == custom.resolve()
    with pytest.raises(BfsitlError, match="iris_betaflight.sdf"):
        world_path("nope.sdf")


def test_world_name_physics_and_systems(world: ET.Element) -> None:
    assert world.get("name") == WORLD_NAME
    assert numbers(text(world, "physics/max_step_size")) == [0.001]
    assert numbers(text(world, "physics/real_time_factor")) == [1.0]
    assert text(world, "spherical_coordinates/world_frame_orientation") == "ENU"
    systems = {p.get("filename"): p.get("name") for p in world.findall("plugin")}
    assert systems["gz-sim-physics-system"] == "gz::sim::systems::Physics"
    assert systems["gz-sim-imu-system"] == "gz::sim::systems::Imu"
    assert systems["gz-sim-air-pressure-system"] == "gz::sim::systems::AirPressure"
    # No rendering system: the headless server must not need a GPU.
    assert "gz-sim-sensors-system" not in systems


# --- the plugin block --------------------------------------------------------------------------


def test_plugin_identity_ports_and_stepping(plugin: ET.Element) -> None:
    assert plugin.get("name") == "BetaFlightPlugin"  # the alias the library registers
    assert text(plugin, "fdm_addr") == "127.0.0.1"
    assert text(plugin, "listen_addr") == "127.0.0.1"
    assert text(plugin, "fdm_port_in") == "9002"
    # The plugin reads <fcu_port_out> for where fdm packets go; <fdm_port_out> would be ignored.
    assert text(plugin, "fcu_port_out") == "9003"
    assert plugin.find("fdm_port_out") is None
    assert text(plugin, "lock_step") == "1"
    assert text(plugin, "connectionTimeoutMaxCount") == "5"


def test_plugin_frame_transforms(plugin: ET.Element) -> None:
    model_to_frd = text(plugin, "modelXYZToAirplaneXForwardZDown")
    gazebo_to_ned = text(plugin, "gazeboXYZToNED")
    assert model_to_frd == "0 0 0 3.141593 0 0"
    assert gazebo_to_ned == "0 0 0 3.141593 0 1.5707963"

    # Roll pi turns the FLU model frame into FRD: forward stays, right = -left, down = -up.
    frd = rotation_rpy(*numbers(model_to_frd)[3:])
    for axis, expected in ((0, [1, 0, 0]), (1, [0, -1, 0]), (2, [0, 0, -1])):
        assert column(frd, axis) == pytest.approx(expected, abs=1e-6)
    # In the ENU world the NED axes are: north = +Y, east = +X, down = -Z.
    ned = rotation_rpy(*numbers(gazebo_to_ned)[3:])
    for axis, expected in ((0, [0, 1, 0]), (1, [1, 0, 0]), (2, [0, 0, -1])):
        assert column(ned, axis) == pytest.approx(expected, abs=1e-6)


def test_imu_name_resolves_to_an_frd_imu_sensor(plugin: ET.Element, nested: ET.Element) -> None:
    model, link, sensor = text(plugin, "imuName").split("::")
    assert model == NESTED
    imu = nested.find(f"link[@name='{link}']/sensor[@name='{sensor}']")
    assert imu is not None and imu.get("type") == "imu"
    assert numbers(text(imu, "pose")) == pytest.approx([0, 0, 0, math.pi, 0, 0], abs=1e-6)
    assert numbers(text(imu, "update_rate")) == [1000.0]


def test_pressure_sensor_sits_where_the_plugin_listens(
    world: ET.Element, outer: ET.Element, nested: ET.Element
) -> None:
    """The plugin hard-codes its pressure topic: every name on that path must match."""
    sensors = [
        (link.get("name"), s)
        for link in nested.findall("link")
        for s in link.findall("sensor")
        if s.get("type") == "air_pressure"
    ]
    assert len(sensors) == 1
    link_name, sensor = sensors[0]
    topic = (
        f"/world/{world.get('name')}/model/{outer.get('name')}/model/{nested.get('name')}"
        f"/link/{link_name}/sensor/{sensor.get('name')}/air_pressure"
    )
    assert topic == PRESSURE_TOPIC
    assert numbers(text(sensor, "air_pressure/reference_altitude")) == [0.0]


CONTROL_VALUES = {
    "type": "VELOCITY",
    "useForce": "1",
    "offset": "0",
    "p_gain": "0.20",
    "i_gain": "0",
    "d_gain": "0",
    "i_max": "0",
    "i_min": "0",
    "cmd_max": "2.5",
    "cmd_min": "-2.5",
    "rotorVelocitySlowdownSim": "1",
    "servo_min": "1100",
    "servo_max": "1900",
}


def test_four_control_channels_with_joints_multipliers_and_gains(
    plugin: ET.Element, nested: ET.Element
) -> None:
    controls = plugin.findall("control")
    assert sorted(int(c.get("channel", "-1")) for c in controls) == [0, 1, 2, 3]
    for control in controls:
        rotor, multiplier = EXPECTED_CONTROLS[int(control.get("channel", "-1"))]
        assert text(control, "jointName") == f"{NESTED}::{rotor}_joint"
        assert float(text(control, "multiplier")) == multiplier
        for element, value in CONTROL_VALUES.items():
            assert text(control, element) == value, element
        # The name the plugin does not read (a leftover of the reference world) is not used.
        assert control.find("controlVelocitySlowdownSim") is None
        joint = nested.find(f"joint[@name='{rotor}_joint']")
        assert joint is not None and joint.get("type") == "revolute"
        assert text(joint, "parent") == "base_link" and text(joint, "child") == rotor
        assert numbers(text(joint, "axis/xyz")) == [0, 0, 1]
        assert numbers(text(joint, "axis/dynamics/damping")) == [IRIS.rotor_damping_nm_s_per_rad]


def test_channels_drive_the_rotors_bfsitl_assigns_to_those_servo_slots(
    plugin: ET.Element, nested: ET.Element
) -> None:
    """Servo slot = channel; 4.6.0 puts Betaflight motor m in slot SLOT_OF_BETAFLIGHT_MOTOR[m].
    The rotor each channel spins must sit where, and turn the way, the embedded IRIS has
    that motor: the same firmware mixer must fly both."""
    for control in plugin.findall("control"):
        channel = int(control.get("channel", "-1"))
        motor = ServoPacket.SLOT_OF_BETAFLIGHT_MOTOR.index(channel)
        link_name = text(control, "jointName").split("::")[1].removesuffix("_joint")
        x, y, z = numbers(text(nested, f"link[@name='{link_name}']/pose"))[:3]
        expected = IRIS.rotor_positions_frd_m[motor]
        assert (x, -y) == pytest.approx(expected[:2]), (channel, link_name)  # FLU -> FRD
        assert (float(text(control, "multiplier")) > 0) == IRIS.rotor_spin_ccw[motor]


def test_lift_drag_blades_follow_each_rotors_spin(
    outer: ET.Element, plugin: ET.Element, nested: ET.Element
) -> None:
    spin = {
        text(c, "jointName").split("::")[1].removesuffix("_joint"): math.copysign(
            1.0, float(text(c, "multiplier"))
        )
        for c in plugin.findall("control")
    }
    blades = outer.findall("plugin[@filename='gz-sim-lift-drag-system']")
    assert len(blades) == 8
    per_rotor: dict[str, int] = {}
    for blade in blades:
        model, rotor = text(blade, "link_name").split("::")
        assert model == NESTED and nested.find(f"link[@name='{rotor}']") is not None
        per_rotor[rotor] = per_rotor.get(rotor, 0) + 1
        cp_x = numbers(text(blade, "cp"))[0]
        forward_y = numbers(text(blade, "forward"))[1]
        assert abs(cp_x) == 0.084
        # Spinning +z (CCW), the blade at +x moves towards +y.
        assert math.copysign(1.0, cp_x * forward_y) == spin[rotor], (rotor, cp_x)
        assert numbers(text(blade, "upward")) == [0, 0, 1]
    assert per_rotor == {"rotor_0": 2, "rotor_1": 2, "rotor_2": 2, "rotor_3": 2}


def test_vehicle_matches_the_embedded_iris(outer: ET.Element, nested: ET.Element) -> None:
    masses = [float(text(link, "inertial/mass")) for link in nested.findall("link")]
    assert sum(masses) == pytest.approx(IRIS.mass_kg)
    for index in range(4):
        izz = float(text(nested, f"link[@name='rotor_{index}']/inertial/inertia/izz"))
        assert izz == pytest.approx(IRIS.rotor_inertia_kg_m2)
    blade = outer.find("plugin[@filename='gz-sim-lift-drag-system']")
    assert blade is not None
    cla, a0, rho, area = (float(text(blade, name)) for name in ("cla", "a0", "air_density", "area"))
    radius = abs(numbers(text(blade, "cp"))[0])
    # Two blade elements: T = 2 * cla * a0 * 1/2 rho A r^2 * omega^2.
    k_thrust = 2 * cla * a0 * 0.5 * rho * area * radius**2
    assert k_thrust == pytest.approx(IRIS.thrust_coefficient_n_per_rad2_s2, rel=1e-3)
    control = outer.find(".//control")
    assert control is not None
    assert float(text(control, "multiplier")) == IRIS.motor_command_speed_rad_s


# --- the world of each generation ---------------------------------------------------------------

MASTER = profile_for("1.49", "2026.12.0-alpha")


def test_4_6_flies_the_shipped_world_as_it_is(tmp_path: Path) -> None:
    assert world_for_profile(DEFAULT_PROFILE, tmp_path) == world_path(DEFAULT_WORLD)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("profile", [DEFAULT_PROFILE, MASTER], ids=["4.6.0", "master"])
def test_each_generations_world_spins_each_betaflight_motors_rotor(
    profile: FirmwareProfile, tmp_path: Path
) -> None:
    """Channel = the slot this firmware puts a motor in; that channel must spin the rotor that
    sits where the embedded IRIS has the motor, the way it turns: a wrong slot table flips the
    mixer (master sends motors in plain order, 4.6.0 remaps them)."""
    root = ET.parse(world_for_profile(profile, tmp_path)).getroot()
    world = root.find("world")
    assert world is not None and world.get("name") == WORLD_NAME
    outer = next(
        m
        for m in world.findall("model")
        if m.find("plugin[@filename='BetaflightPlugin']") is not None
    )
    plugin = outer.find("plugin[@filename='BetaflightPlugin']")
    nested = outer.find(f"model[@name='{NESTED}']")
    assert plugin is not None and nested is not None
    channels = sorted(int(c.get("channel", "-1")) for c in plugin.findall("control"))
    assert channels == [0, 1, 2, 3]
    for control in plugin.findall("control"):
        motor = profile.motor_slot_of_betaflight_motor.index(int(control.get("channel", "-1")))
        link_name = text(control, "jointName").split("::")[1].removesuffix("_joint")
        x, y, _z = numbers(text(nested, f"link[@name='{link_name}']/pose"))[:3]
        assert (x, -y) == pytest.approx(IRIS.rotor_positions_frd_m[motor][:2]), link_name
        assert (float(text(control, "multiplier")) > 0) == IRIS.rotor_spin_ccw[motor]


def test_master_world_leaves_the_yaw_turn_to_the_firmware(tmp_path: Path) -> None:
    """Master's ENABLE_GAZEBO_BRIDGE turns the quaternion by Rz(pi/2) itself (sitl.c); the
    plugin's transform must then be the reference world's roll pi alone."""
    derived = world_for_profile(MASTER, tmp_path)
    assert derived.parent == tmp_path
    plugin = ET.parse(derived).getroot().find(".//plugin[@filename='BetaflightPlugin']")
    assert plugin is not None
    assert numbers(text(plugin, "gazeboXYZToNED")) == pytest.approx(
        [0, 0, 0, math.pi, 0, 0], abs=1e-6
    )
    shipped = ET.parse(world_path()).getroot().find(".//plugin[@filename='BetaflightPlugin']")
    assert shipped is not None
    # Everything else the plugin reads is the shipped world's.
    for name in (
        "fdm_port_in",
        "fcu_port_out",
        "imuName",
        "modelXYZToAirplaneXForwardZDown",
        "lock_step",
    ):
        assert text(plugin, name) == text(shipped, name)
