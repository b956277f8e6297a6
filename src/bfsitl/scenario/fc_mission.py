"""The FC's own mission in a scenario file: ``[[fc_waypoint]]`` tables in metres from the
take-off point, written to master's flight plan as ``waypoint`` CLI lines.

    [[fc_waypoint]]
    north_m = 40.0
    east_m = 0.0
    alt_m = 10.0           # above the take-off point
    speed_m_s = 5.0
    type = "flyover"       # flyover, flyby, hold, land, takeoff
    duration_s = 0         # a hold's or a landing's loiter
    pattern = "none"       # a hold's: none, orbit, figure8

Master stores a waypoint as latitude and longitude in 1e-7 degrees, altitude in cm above mean
sea level, speed in cm/s and duration in deciseconds (``pg/flight_plan.h``), and its CLI
takes ``waypoint insert IDX LAT LON ALT SPEED TYPE DURATION PATTERN``.  bfsitl's physics puts
the take-off point at :data:`HOME` (the simulator's default home), so the conversion is the
simulator's own flat-earth projection.  The mission flies once a ``mode_switch`` raises
AUTOPILOT (or a failsafe hands it over).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from bfsitl.errors import ScenarioError
from bfsitl.physics.frames import GeodeticProjection, GeoPoint
from bfsitl.scenario.values import number_in

#: The simulator's home (bfsitl.physics.multirotor: latitude and longitude 0, sea level).
HOME = GeoPoint(0.0, 0.0, 0.0)
WAYPOINT_TYPES = ("flyover", "flyby", "hold", "land", "takeoff")
PATTERNS = ("none", "orbit", "figure8")
#: Master's flight plan holds this many (MAX_WAYPOINTS, pg/flight_plan.h).
MAX_FC_WAYPOINTS = 30
_KEYS = {"north_m", "east_m", "alt_m", "speed_m_s", "type", "duration_s", "pattern"}


@dataclass(frozen=True, slots=True)
class FcWaypoint:
    """One waypoint of the FC's own mission, in bfsitl's frame."""

    north_m: float
    east_m: float
    alt_m: float
    speed_m_s: float = 5.0
    type: str = "flyover"
    duration_s: float = 0.0
    pattern: str = "none"


def _word(where: str, key: str, value: Any, words: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value.lower() not in words:
        raise ScenarioError(f"{where}: {key} = {value!r} is not one of {', '.join(words)}")
    return value.lower()


def read_fc_waypoints(raw: Any, *, where: str) -> tuple[FcWaypoint, ...]:
    """``[[fc_waypoint]]`` tables, each checked (the file and the waypoint in messages)."""
    if not isinstance(raw, list):
        raise ScenarioError(f"{where}: the FC's waypoints are written as [[fc_waypoint]] tables")
    if len(raw) > MAX_FC_WAYPOINTS:
        raise ScenarioError(
            f"{where}: {len(raw)} [[fc_waypoint]] tables; the flight plan holds {MAX_FC_WAYPOINTS}"
        )
    waypoints = []
    for number, table in enumerate(raw, 1):
        here = f"{where}, fc_waypoint {number}"
        if not isinstance(table, dict):
            raise ScenarioError(f"{here}: must be a table")
        unknown = set(table) - _KEYS
        if unknown:
            raise ScenarioError(
                f"{here}: unknown key(s) {', '.join(sorted(unknown))}; known: "
                f"{', '.join(sorted(_KEYS))}"
            )
        for key in ("north_m", "east_m", "alt_m"):
            if key not in table:
                raise ScenarioError(f"{here}: {key} is missing")
        waypoints.append(
            FcWaypoint(
                north_m=number_in(here, "north_m", table["north_m"], -5000.0, 5000.0),
                east_m=number_in(here, "east_m", table["east_m"], -5000.0, 5000.0),
                alt_m=number_in(here, "alt_m", table["alt_m"], 0.0, 500.0),
                speed_m_s=number_in(here, "speed_m_s", table.get("speed_m_s", 5.0), 0.0, 50.0),
                type=_word(here, "type", table.get("type", "flyover"), WAYPOINT_TYPES),
                duration_s=number_in(here, "duration_s", table.get("duration_s", 0.0), 0.0, 6000.0),
                pattern=_word(here, "pattern", table.get("pattern", "none"), PATTERNS),
            )
        )
    return tuple(waypoints)


def fc_mission_cli(waypoints: tuple[FcWaypoint, ...], home: GeoPoint = HOME) -> tuple[str, ...]:
    """The CLI lines that make the FC's flight plan exactly ``waypoints`` (none: no lines)."""
    if not waypoints:
        return ()
    projection = GeodeticProjection(home)
    lines = ["waypoint clear"]
    for index, wp in enumerate(waypoints):
        lon, lat, alt_msl = projection.lon_lat_alt((wp.north_m, wp.east_m, -wp.alt_m))
        lines.append(
            f"waypoint insert {index} {lat:.7f} {lon:.7f} {round(alt_msl * 100)} "
            f"{round(wp.speed_m_s * 100)} {wp.type} {round(wp.duration_s * 10)} "
            f"{wp.pattern}"
        )
    return tuple(lines)
