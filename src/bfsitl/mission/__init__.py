"""Flights: a session (SITL + physics + provisioning + RC), missions and their records.

from bfsitl.control import make_controller
from bfsitl.mission import FlightSession, MissionPlan, fly

with FlightSession() as session:
    result = fly(session, MissionPlan(target_alt_m=2.0, hold_s=10),
                 make_controller("cascade"))
print(result.outcome, result.hold)
"""

from bfsitl.mission.flight_metrics import HoldStats
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.legs import LegStats
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
from bfsitl.mission.vehicle import FlightSample

__all__ = [
    "FLY_PROFILE",
    "ConfiguratorBridge",
    "FcSetup",
    "FlightLoop",
    "FlightRow",
    "FlightSample",
    "FlightSession",
    "HoldStats",
    "LegStats",
    "MissionPlan",
    "MissionResult",
    "Outcome",
    "SessionConfig",
    "SitlLaunch",
    "Waypoint",
    "fly",
    "load_mission",
]
