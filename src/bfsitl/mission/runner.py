"""Missions, importable from one place as before the split: the flight loop
(:mod:`~bfsitl.mission.loop`), its hooks (:mod:`~bfsitl.mission.hooks`), the results
(:mod:`~bfsitl.mission.results`), the figures (:mod:`~bfsitl.mission.flight_metrics`) and the
plan driver (:mod:`~bfsitl.mission.plan_driver`)."""

from bfsitl.mission.flight_metrics import (
    AttitudeTracking,
    HoldStats,
    attitude_tracking,
    cross_track_rms,
    hold_stats,
    judged_alt_m,
    landed_from_start_m,
    takeoff_metrics,
)
from bfsitl.mission.hooks import EventCallback, FlightHooks, RowCallback, StopCondition
from bfsitl.mission.loop import (
    CRASH_TILT_DEG,
    CRASH_TOUCHDOWN_M_S,
    DEFAULT_RATE_HZ,
    REACHED_BAND_M,
    REACHED_CLIMB_M_S,
    REACHED_HOLD_S,
    REACHED_PATIENCE_S,
    Mission,
)
from bfsitl.mission.plan import MissionPlan, Waypoint
from bfsitl.mission.plan_driver import STEP_STEADY_WINDOW_S, fly_plan, fly_waypoint, run_mission
from bfsitl.mission.results import MissionResult, Outcome

__all__ = [
    "CRASH_TILT_DEG", "CRASH_TOUCHDOWN_M_S", "DEFAULT_RATE_HZ", "REACHED_BAND_M",
    "REACHED_CLIMB_M_S", "REACHED_HOLD_S", "REACHED_PATIENCE_S", "STEP_STEADY_WINDOW_S",
    "AttitudeTracking", "EventCallback", "FlightHooks", "HoldStats", "Mission", "MissionPlan",
    "MissionResult", "Outcome", "RowCallback", "StopCondition", "Waypoint", "attitude_tracking",
    "cross_track_rms", "fly_plan", "fly_waypoint", "hold_stats", "judged_alt_m",
    "landed_from_start_m", "run_mission", "takeoff_metrics",
]
