"""The Gazebo world files bfsitl ships, and the names inside them that other code relies on.

The worlds are package data (``bfsitl/gazebo/worlds/*.sdf``).  They are read from the
installed package directory, not extracted from a zip: ``gz sim`` needs a real file path, and
setuptools installs package data as plain files.
"""

from __future__ import annotations

from pathlib import Path

from bfsitl.errors import BfsitlError

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
