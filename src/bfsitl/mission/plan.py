"""What a mission flies: a take-off, an optional hold, waypoints, a landing; and its TOML file.

    takeoff_alt_m = 2.0
    speed_m_s = 2.0          # along the legs (optional, default 2)

    [[waypoint]]
    north_m = 10.0           # metres from the take-off point
    east_m = 0.0
    alt_m = 2.0              # above the take-off point
    hold_s = 2.0             # optional: hold there this long
    heading_deg = 90.0       # optional: turn to this heading there (clockwise from north)

    land = true

Every value is checked when the plan is made, so a typo fails before anything starts, with
the file, the waypoint and the key in the message.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from bfsitl.errors import MissionError
from bfsitl.toml_file import read_toml_file

#: How far from the take-off point a waypoint may be: a flying field, not a cross-country.
MAX_WAYPOINT_DISTANCE_M = 10_000.0
DEFAULT_SPEED_M_S = 2.0
#: The hold after the take-off when the plan has no waypoints (``bfsitl fly --hold``).
DEFAULT_HOLD_S = 10.0


def _check_range(what: str, value: float, low: float, high: float, unit: str) -> None:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and low <= value <= high):
        raise MissionError(f"{what} {value!r} is outside {low:g}..{high:g} {unit}")


@dataclass(frozen=True, slots=True)
class Waypoint:
    """A point to fly to, metres from the take-off point (north, east, up).

    Every value is checked when it is made.

    Attributes:
        north_m: Metres north of the take-off point, within 10 km.
        east_m: Metres east of the take-off point, within 10 km.
        alt_m: Metres above the take-off point, 0.3 to 100.
        hold_s: Seconds to hold the position there, 0 to 3600.
        heading_deg: Turn to this heading on arrival, degrees clockwise from north (0 to
            360); None keeps the heading.

    Raises:
        MissionError: A value is out of its range or no number.
    """

    north_m: float
    east_m: float
    alt_m: float
    hold_s: float = 0.0
    #: Turn to this heading on arrival (clockwise from north); None keeps the heading.
    heading_deg: float | None = None

    def __post_init__(self) -> None:
        limit = MAX_WAYPOINT_DISTANCE_M
        _check_range("waypoint north_m", self.north_m, -limit, limit, "m")
        _check_range("waypoint east_m", self.east_m, -limit, limit, "m")
        _check_range("waypoint alt_m", self.alt_m, 0.3, 100.0, "m")
        _check_range("waypoint hold_s", self.hold_s, 0.0, 3600.0, "s")
        if self.heading_deg is not None:
            _check_range("waypoint heading_deg", self.heading_deg, 0.0, 360.0, "deg")


@dataclass(frozen=True, slots=True)
class MissionPlan:
    """Take off to ``target_alt_m``, hold ``hold_s``, fly the ``waypoints`` in order (each a
    leg at ``speed_m_s``, then its own hold), land and disarm (``land``).

    Every value is checked when it is made; :func:`load_mission` reads one from a file.

    Attributes:
        target_alt_m: The take-off's height, metres above the take-off point (0.3 to 100).
        hold_s: Seconds to hold after the take-off (0 to 3600).
        takeoff_timeout_s: Seconds of simulation time allowed for the climb to be reached
            and settled.
        land_timeout_s: Seconds of simulation time allowed for the landing to touch down.
        ground_s: Seconds armed at idle before the take-off, while the barometer settles
            (:meth:`~bfsitl.mission.loop.Mission.wait_on_ground`; 0 to 60).
        waypoints: The points to fly to, in order; they need a GPS build.
        speed_m_s: Speed along the legs, metres per second (0.1 to 20).
        land: Land and disarm at the end; False ends the mission in the air (the session's
            close then disarms: in a simulation the vehicle falls).
        hold_position: On a firmware with GPS, hold the take-off point during the take-off,
            the hold and the landing even without waypoints (wind would carry the vehicle
            off); False flies the altitude alone, sticks centred.

    Raises:
        MissionError: A value is out of its range, or a waypoint is no :class:`Waypoint`.
    """

    target_alt_m: float = 2.0
    hold_s: float = DEFAULT_HOLD_S
    #: Simulation seconds allowed for the climb to be reached and settled.
    takeoff_timeout_s: float = 20.0
    land_timeout_s: float = 30.0
    #: Armed at idle before the take-off (:meth:`FlightLoop.wait_on_ground`), seconds.
    ground_s: float = 2.0
    waypoints: tuple[Waypoint, ...] = ()
    speed_m_s: float = DEFAULT_SPEED_M_S
    #: Land and disarm at the end; False ends the mission in the air (the session's close
    #: then disarms: in a simulation the vehicle falls).
    land: bool = True
    #: On a firmware with GPS, hold the take-off point during the take-off, the hold and the
    #: landing even without waypoints (wind would carry the vehicle off); False flies the
    #: altitude alone, sticks centred.
    hold_position: bool = True

    def __post_init__(self) -> None:
        _check_range("target altitude", self.target_alt_m, 0.3, 100.0, "m")
        _check_range("hold time", self.hold_s, 0.0, 3600.0, "s")
        _check_range("ground time", self.ground_s, 0.0, 60.0, "s")
        _check_range("speed", self.speed_m_s, 0.1, 20.0, "m/s")
        for waypoint in self.waypoints:
            if not isinstance(waypoint, Waypoint):
                raise MissionError(f"waypoints must be Waypoint objects, got {waypoint!r}")

    @property
    def needs_position(self) -> bool:
        """Waypoints are flown from the FC's GPS: only GPS builds can fly this plan."""
        return bool(self.waypoints)


#: The file's top-level keys and the plan's fields they fill.
_TOP_KEYS = {
    "takeoff_alt_m": "target_alt_m",
    "hold_s": "hold_s",
    "ground_s": "ground_s",
    "speed_m_s": "speed_m_s",
    "land": "land",
    "hold_position": "hold_position",
    "takeoff_timeout_s": "takeoff_timeout_s",
    "land_timeout_s": "land_timeout_s",
}
_WAYPOINT_KEYS = {f.name for f in fields(Waypoint)}


def plan_from_dict(data: dict[str, Any], *, source: str = "the mission") -> MissionPlan:
    """A plan from a mission file's table (see the module docstring); ``source`` names it in
    errors."""
    unknown = set(data) - set(_TOP_KEYS) - {"waypoint"}
    if unknown:
        raise MissionError(
            f"{source}: unknown key(s) {', '.join(sorted(unknown))}; known: "
            f"{', '.join(sorted([*_TOP_KEYS, 'waypoint']))}"
        )
    if "takeoff_alt_m" not in data:
        raise MissionError(f"{source}: takeoff_alt_m is missing (the take-off altitude, m)")
    raw_points = data.get("waypoint", [])
    if not isinstance(raw_points, list):
        raise MissionError(f"{source}: waypoints are written as [[waypoint]] tables")
    waypoints = []
    for number, raw in enumerate(raw_points, start=1):
        where = f"{source}, waypoint {number}"
        if not isinstance(raw, dict):
            raise MissionError(f"{where}: expected a table, got {raw!r}")
        unknown = set(raw) - _WAYPOINT_KEYS
        missing = {"north_m", "east_m", "alt_m"} - set(raw)
        if unknown or missing:
            problems = [f"unknown key(s) {', '.join(sorted(unknown))}"] if unknown else []
            if missing:
                problems.append(f"missing {', '.join(sorted(missing))}")
            raise MissionError(
                f"{where}: {'; '.join(problems)} (keys: {', '.join(sorted(_WAYPOINT_KEYS))})"
            )
        _check_types(where, raw)
        try:
            waypoints.append(Waypoint(**raw))
        except MissionError as exc:
            raise MissionError(f"{where}: {exc}") from None
    values = {field: data[key] for key, field in _TOP_KEYS.items() if key in data}
    _check_types(source, {k: v for k, v in values.items() if k not in ("land", "hold_position")})
    for flag in ("land", "hold_position"):
        if flag in values and not isinstance(values[flag], bool):
            raise MissionError(f"{source}: {flag} must be true or false, got {values[flag]!r}")
    # A file's hold means "after the take-off"; with waypoints it defaults to none.
    values.setdefault("hold_s", 0.0 if waypoints else DEFAULT_HOLD_S)
    try:
        return MissionPlan(waypoints=tuple(waypoints), **values)
    except MissionError as exc:
        raise MissionError(f"{source}: {exc}") from None


def _check_types(where: str, values: dict[str, Any]) -> None:
    for key, value in values.items():
        if value is None and key == "heading_deg":
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise MissionError(f"{where}: {key} must be a number, got {value!r}")


def load_mission(path: str | Path) -> MissionPlan:
    """Read a mission TOML file (see the module docstring).

    Args:
        path: The mission file.

    Returns:
        The plan, every value checked.

    Raises:
        MissionError: The file cannot be read, is no TOML, or holds an unknown key, a
            missing one or a value out of range (the message names the file, the waypoint
            and the key).
    """
    path = Path(path)
    data = read_toml_file(path, "mission", MissionError)
    return plan_from_dict(data, source=str(path))
