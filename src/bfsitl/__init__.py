"""bfsitl: fly a real Betaflight flight controller in software-in-the-loop, from Python.

The public surface is importable from here; each name lives in the module its docstring
points to, and is imported on first use, so ``import bfsitl`` stays light.

    from bfsitl import Autopilot, launch_sitl

    with launch_sitl(firmware="master") as vehicle:   # a GPS build flies positions
        pilot = Autopilot(vehicle)
        pilot.takeoff(2.0)
        pilot.goto(10.0, 0.0, 2.0)
        pilot.land()
    print(pilot.legs)
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from bfsitl.errors import BfsitlError
from bfsitl.version import __version__

#: Public name -> the module that defines it.
_EXPORTS: dict[str, str] = {
    # flights
    "FlightSession": "bfsitl.mission.session",
    "SessionConfig": "bfsitl.mission.session",
    "SitlLaunch": "bfsitl.mission.session",
    "Timing": "bfsitl.backend.options",
    "FcSetup": "bfsitl.mission.session",
    "World": "bfsitl.backend.options",
    "ConfiguratorBridge": "bfsitl.mission.session",
    "FLY_PROFILE": "bfsitl.mission.session",
    "FlightLoop": "bfsitl.mission.loop",
    "MissionPlan": "bfsitl.mission.plan",
    "MissionResult": "bfsitl.mission.results",
    "Outcome": "bfsitl.mission.results",
    "fly": "bfsitl.mission.plan_driver",
    "Waypoint": "bfsitl.mission.plan",
    "load_mission": "bfsitl.mission.plan",
    "Autopilot": "bfsitl.autopilot",
    "launch_sitl": "bfsitl.autopilot",
    "connect": "bfsitl.autopilot",
    "Vehicle": "bfsitl.mission.vehicle",
    "BoardVehicle": "bfsitl.mission.board",
    "make_controller": "bfsitl.control",
    "load_vehicle": "bfsitl.vehicles",
    # scenarios: faults and expectations, the FC's blackbox
    "Scenario": "bfsitl.scenario.spec",
    "load_scenario": "bfsitl.scenario.load",
    "run_scenario": "bfsitl.scenario.run",
    "RunOptions": "bfsitl.scenario.run",
    "ScenarioResult": "bfsitl.scenario.result",
    "RcFault": "bfsitl.fc.rc_link",
    "decode_blackbox": "bfsitl.blackbox",
    # the SITL and its firmware
    "SitlProcess": "bfsitl.sitl.process",
    "FirmwareBinary": "bfsitl.sitl.firmware",
    "find_firmware": "bfsitl.sitl.firmware",
    # talking to an FC (a SITL or a board)
    "MspClient": "bfsitl.fc.msp_client",
    "CliSession": "bfsitl.fc.cli_session",
    "Profile": "bfsitl.fc.provisioning",
    "provision": "bfsitl.fc.provisioning",
    "open_link": "bfsitl.link",
    # the embedded physics
    "Simulator": "bfsitl.physics",
    "Wind": "bfsitl.physics.wind",
    "SensorConfig": "bfsitl.physics",
    "GeoPoint": "bfsitl.physics",
}

__all__ = [
    "Autopilot",
    "BfsitlError",
    "BoardVehicle",
    "CliSession",
    "ConfiguratorBridge",
    "FLY_PROFILE",
    "FcSetup",
    "FirmwareBinary",
    "FlightLoop",
    "FlightSession",
    "GeoPoint",
    "MissionPlan",
    "MissionResult",
    "MspClient",
    "Outcome",
    "Profile",
    "RcFault",
    "RunOptions",
    "Scenario",
    "ScenarioResult",
    "SensorConfig",
    "SessionConfig",
    "Simulator",
    "SitlLaunch",
    "SitlProcess",
    "Timing",
    "Vehicle",
    "Waypoint",
    "Wind",
    "World",
    "__version__",
    "connect",
    "decode_blackbox",
    "find_firmware",
    "fly",
    "launch_sitl",
    "load_mission",
    "load_scenario",
    "load_vehicle",
    "make_controller",
    "open_link",
    "provision",
    "run_scenario",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'bfsitl' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # the next lookup is a plain attribute
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # what type checkers and IDEs see; nothing is imported at run time
    from bfsitl.autopilot import Autopilot, connect, launch_sitl
    from bfsitl.backend.options import Timing, World
    from bfsitl.blackbox import decode_blackbox
    from bfsitl.control import make_controller
    from bfsitl.fc.cli_session import CliSession
    from bfsitl.fc.msp_client import MspClient
    from bfsitl.fc.provisioning import Profile, provision
    from bfsitl.fc.rc_link import RcFault
    from bfsitl.link import open_link
    from bfsitl.mission.board import BoardVehicle
    from bfsitl.mission.loop import FlightLoop
    from bfsitl.mission.plan import MissionPlan, Waypoint, load_mission
    from bfsitl.mission.plan_driver import fly
    from bfsitl.mission.results import MissionResult, Outcome
    from bfsitl.mission.session import (
        FLY_PROFILE,
        ConfiguratorBridge,
        FcSetup,
        FlightSession,
        SessionConfig,
        SitlLaunch,
    )
    from bfsitl.mission.vehicle import Vehicle
    from bfsitl.physics import GeoPoint, SensorConfig, Simulator
    from bfsitl.physics.wind import Wind
    from bfsitl.scenario.load import load_scenario
    from bfsitl.scenario.result import ScenarioResult
    from bfsitl.scenario.run import RunOptions, run_scenario
    from bfsitl.scenario.spec import Scenario
    from bfsitl.sitl.firmware import FirmwareBinary, find_firmware
    from bfsitl.sitl.process import SitlProcess
    from bfsitl.vehicles import load_vehicle
