"""The Gazebo world files bfsitl ships, and the names inside them that other code relies on.

The worlds are package data (``bfsitl/gazebo/worlds/*.sdf``).  They are read from the
installed package directory, not extracted from a zip: ``gz sim`` needs a real file path, and
setuptools installs package data as plain files.

The shipped world is written for 4.6.0.  :func:`world_for_profile` derives the world another
generation needs from it (the plugin's frame transform and its motor channels), from the
firmware profile, so that the conventions stay in one place
(:mod:`bfsitl.protocol.firmware_profile`).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import BfsitlError
from bfsitl.protocol.firmware_profile import (
    DEFAULT_PROFILE,
    FirmwareProfile,
    QuaternionConvention,
)

#: The folder holding the shipped worlds; it goes on GZ_SIM_RESOURCE_PATH.
WORLDS_DIR = Path(__file__).resolve().parent / "worlds"

#: IRIS with the BetaflightPlugin, equivalent to the Betaflight SITL Gazebo tutorial world.
DEFAULT_WORLD = "iris_betaflight.sdf"

#: ``<world name>`` of the default world.  The plugin hard-codes it in its pressure topic.
WORLD_NAME = "empty_betaflight_world"

#: File name ``gz sim`` looks for on GZ_SIM_SYSTEM_PLUGIN_PATH for ``filename="BetaflightPlugin"``.
PLUGIN_LIBRARY = "libBetaflightPlugin.so"

#: The topic the vehicle_gateway BetaflightPlugin reads the barometer from (hard-coded in it).
PRESSURE_TOPIC = (
    "/world/empty_betaflight_world/model/iris_with_Betaflight/model/iris_with_standoffs/"
    "link/imu_link/sensor/air_pressure_sensor/air_pressure"
)


def shipped_worlds() -> tuple[str, ...]:
    """File names of the worlds in the package."""
    return tuple(sorted(p.name for p in WORLDS_DIR.glob("*.sdf")))


def world_path(world: str | Path = DEFAULT_WORLD) -> Path:
    """A shipped world by file name, or any existing SDF file by path."""
    candidate = Path(world)
    if candidate.is_file():
        return candidate.resolve()
    shipped = WORLDS_DIR / str(world)
    if shipped.is_file():
        return shipped
    raise BfsitlError(
        f"no Gazebo world {str(world)!r}: give an SDF file path or one of the shipped worlds "
        f"({', '.join(shipped_worlds()) or 'none installed'})"
    )


#: The plugin's ENU -> NED transform for a firmware that takes the quaternion as it is (4.6.0:
#: roll pi, then yaw pi/2, so that north is +Y).
GAZEBO_XYZ_TO_NED_COPIED = "0 0 0 3.141593 0 1.5707963"
#: For a firmware that turns the plugin's quaternion by Rz(pi/2) itself (master's
#: ENABLE_GAZEBO_BRIDGE): the reference world's roll pi only, or the turn is applied twice.
GAZEBO_XYZ_TO_NED_BRIDGE = "0 0 0 3.141593 0 0"


def world_for_profile(profile: FirmwareProfile, directory: Path) -> Path:
    """The world for a firmware of ``profile``: the shipped one for 4.6.0's conventions, else
    one derived from it and written into ``directory`` (which goes on Gazebo's resource path).

    Two things differ between generations: the plugin's frame transform (``gazeboXYZToNED``)
    and which servo_packet slot carries each Betaflight motor.  Each rotor joint keeps the
    Betaflight motor it has in the shipped world, so the derived world's channel for a joint
    is the slot ``profile`` puts that motor in.
    """
    shipped = world_path(DEFAULT_WORLD)
    transform = (
        GAZEBO_XYZ_TO_NED_BRIDGE
        if profile.fdm.quaternion is QuaternionConvention.GAZEBO
        else GAZEBO_XYZ_TO_NED_COPIED
    )
    slots_shipped = DEFAULT_PROFILE.motor_slot_of_betaflight_motor
    slots = profile.motor_slot_of_betaflight_motor
    if transform == GAZEBO_XYZ_TO_NED_COPIED and slots == slots_shipped:
        return shipped
    tree = ET.parse(shipped, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    plugin = tree.getroot().find(".//plugin[@filename='BetaflightPlugin']")
    if plugin is None:
        raise BfsitlError(f"{shipped} has no BetaflightPlugin element")
    frame = plugin.find("gazeboXYZToNED")
    if frame is None:
        raise BfsitlError(f"{shipped} has no gazeboXYZToNED in its BetaflightPlugin")
    frame.text = transform
    motor_in_shipped_slot = {slot: motor for motor, slot in enumerate(slots_shipped)}
    for control in plugin.findall("control"):
        shipped_slot = int(control.attrib["channel"])
        control.set("channel", str(slots[motor_in_shipped_slot[shipped_slot]]))
    plugin.insert(
        0,
        ET.Comment(
            f" Derived by bfsitl from {DEFAULT_WORLD} for {profile.name}: gazeboXYZToNED "
            f"and the channel numbers (the servo_packet slots this firmware uses) differ. "
        ),
    )
    directory.mkdir(parents=True, exist_ok=True)
    derived = directory / f"{Path(DEFAULT_WORLD).stem}-{profile.generation.value}.sdf"
    tree.write(derived, encoding="unicode", xml_declaration=True)
    return derived


#: Gazebo's WindEffects pushes each link that feels the wind with mass x this x (wind - link
#: velocity), in every axis.  bfsitl's value gives the IRIS (1.75 kg) the embedded physics'
#: linear drag, 0.55 N per m/s (``IRIS.drag_linear_n_s_per_m``, PX4's rotor drag).  Gazebo's
#: own IRIS has none (``velocity_decay`` 0), so a flight without a wind keeps it that way.
WIND_FORCE_PER_KG_PER_M_S = 0.55 / 1.75
#: How fast Gazebo's WindEffects follows a new wind (its ``time_for_rise``), seconds.
WIND_RISE_S = 0.1


@dataclass(frozen=True, slots=True)
class WorldChanges:
    """What bfsitl changes in a world for one flight (:func:`write_session_world`)."""

    #: The plugin's ``fdm_port_in`` and ``fcu_port_out``: where bfsitl's relay meets it.
    servo_in_port: int
    fdm_out_port: int
    #: The wind at the start, ENU metres per second; None leaves the world without wind
    #: (no WindEffects system, no link feels it, no drag: Gazebo's own IRIS).
    wind_enu_m_s: tuple[float, float, float] | None = None


def write_session_world(world: Path, directory: Path, changes: WorldChanges) -> Path:
    """A copy of ``world`` in ``directory`` with ``changes``: the BetaflightPlugin's ports
    moved (so that bfsitl's relay, :mod:`bfsitl.gazebo.packet_tap`, sits between it and the
    SITL's fixed ports) and, with a wind, Gazebo's WindEffects system loaded, the world's
    ``<wind>`` set and every link of the plugin's model feeling it."""
    try:
        tree = ET.parse(world, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except (OSError, ET.ParseError) as exc:
        raise BfsitlError(f"cannot read the Gazebo world {world}: {exc}") from exc
    root = tree.getroot()
    world_element = root.find("world")
    plugin = root.find(".//plugin[@filename='BetaflightPlugin']")
    if plugin is None or world_element is None:
        raise BfsitlError(
            f'{world} has no <world> with a <plugin filename="BetaflightPlugin">: bfsitl '
            f"flies Gazebo through that plugin (docs/gazebo.md)"
        )
    for tag, port in (
        ("fdm_port_in", changes.servo_in_port),
        ("fcu_port_out", changes.fdm_out_port),
    ):
        _set_child(plugin, tag, str(port))
    if changes.wind_enu_m_s is not None:
        _add_wind(world_element, plugin, changes.wind_enu_m_s)
    directory.mkdir(parents=True, exist_ok=True)
    written = directory / f"{world.stem}-session.sdf"
    tree.write(written, encoding="unicode", xml_declaration=True)
    return written


def _set_child(parent: ET.Element, tag: str, text: str) -> ET.Element:
    element = parent.find(tag)
    if element is None:
        element = ET.SubElement(parent, tag)
    element.text = text
    return element


def _add_wind(
    world: ET.Element, plugin: ET.Element, wind_enu_m_s: tuple[float, float, float]
) -> None:
    if world.find("plugin[@filename='gz-sim-wind-effects-system']") is None:
        effects = ET.SubElement(
            world,
            "plugin",
            {"filename": "gz-sim-wind-effects-system", "name": "gz::sim::systems::WindEffects"},
        )
        factor = ET.SubElement(effects, "force_approximation_scaling_factor")
        factor.text = f"{WIND_FORCE_PER_KG_PER_M_S:.6f}"
        # Gazebo eases every change of the wind in (1 s by default, the direction from east):
        # a new wind is to blow from now on, as the embedded physics' does.
        horizontal = ET.SubElement(effects, "horizontal")
        for part in ("magnitude", "direction"):
            ET.SubElement(ET.SubElement(horizontal, part), "time_for_rise").text = str(WIND_RISE_S)
        ET.SubElement(ET.SubElement(effects, "vertical"), "time_for_rise").text = str(WIND_RISE_S)
    wind = _set_child(world, "wind", "")
    wind.text = None
    _set_child(wind, "linear_velocity", " ".join(f"{v:.6f}" for v in wind_enu_m_s))
    # Every link of the model that carries the plugin (its nested models' too).
    for model in world.iter("model"):
        if plugin in list(model):
            for link in model.iter("link"):
                _set_child(link, "enable_wind", "true")


def world_name(world: Path) -> str:
    """The ``<world name>`` of a world file (its topics are under ``/world/<name>/``)."""
    element = ET.parse(world).getroot().find("world")
    if element is None or not element.get("name"):
        raise BfsitlError(f"{world} has no <world name=...>")
    return str(element.get("name"))
