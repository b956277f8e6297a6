"""A scenario file: what to provision, how to fly, which faults when, what must hold.

    description = "RC lost in a hover: DROP disarms after failsafe_delay"
    firmware = ["master-lockstep", "4.6.0-gps-lockstep"]   # default builds to run on
    duration_s = 20          # simulation seconds from arming; the run ends then at the latest
    seed = 1                 # disturbances (gusts, sensor noise) repeat with the seed
    cli = ["set failsafe_procedure = DROP"]   # provisioned before the flight

    [vehicle]                # optional: the simulated quad (default Gazebo's IRIS)
    model = "iris"           # a shipped vehicle (`bfsitl vehicle list`) or a
                             # profile file, relative to this file (docs/vehicles.md)
    mass_kg = 1.9            # heavier: a payload
    heading_deg = 90         # where the nose points at the start (default north)

    [wind]                   # optional: north/east m/s (the air's motion), gusts
    north_m_s = 2.0
    gust_std_m_s = 0.5

    [flight]                 # what bfsitl's autopilot flies: a mission table (docs/missions.md)
    takeoff_alt_m = 3.0
    hold_s = 30.0
    land = false

    [[fault]]                # at_s after arming; see bfsitl.scenario.faults for the kinds
    at_s = 8.0
    kind = "rc_loss"

    [expect]                 # see bfsitl.scenario.expectations for the keys
    disarmed_within_s = 2.5
    failsafe_phase = "LANDED"

    [[known_failure]]        # optional: a firmware defect it flies into on purpose
    finding = "crash"        # (see bfsitl.scenario.known_failures)
    generation = "master"
    why = "master's LAND leg aims 200 m below the quad"

A real flight's log flown again (``[replay]`` instead of ``[flight]``) is a scenario too:
see :mod:`bfsitl.scenario.replay_spec`.

Everything is checked when the file is read, so a typo fails before any SITL starts, with
the file, the table and the key in the message.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, cast

from bfsitl.backend.options import Physics
from bfsitl.build.binary_scan import FEATURE_MARKERS
from bfsitl.errors import MissionError, ScenarioError, SimInputError, VehicleProfileError
from bfsitl.mission.plan import MissionPlan, plan_from_dict
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.physics.wind import (
    MAX_GUST_STD_M_S,
    MAX_GUST_TIME_CONSTANT_S,
    MAX_WIND_COMPONENT_M_S,
    MIN_GUST_TIME_CONSTANT_S,
    Wind,
)
from bfsitl.scenario.faults import FaultSpec, read_fault_spec
from bfsitl.scenario.fc_mission import FcWaypoint, read_fc_waypoints
from bfsitl.scenario.known_failures import KnownFailure, read_known_failures
from bfsitl.scenario.replay_spec import DEFAULT_REPLAY_VEHICLE, ReplaySpec, read_replay_spec
from bfsitl.scenario.values import number_in
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ, MAX_RC_RATE_HZ, MIN_RC_RATE_HZ
from bfsitl.vehicles.catalogue import DEFAULT_VEHICLE, load_vehicle

#: A scenario's file name pattern inside a directory.
SCENARIO_GLOB = "*.toml"
MAX_DURATION_S = 3600.0
DEFAULT_SETTLE_S = 2.0

_TOP_KEYS = {
    "name",
    "description",
    "firmware",
    "requires_gps",
    "requires",
    "duration_s",
    "settle_s",
    "seed",
    "cli",
    "vehicle",
    "wind",
    "flight",
    "fault",
    "expect",
    "fc_waypoint",
    "cli_for",
    "known_failure",
    "replay",
    "physics",
    "rc",
}
#: ``physics``: bfsitl's embedded physics, or Gazebo's (a stock build, real time; only the
#: RC link and a constant wind can be disturbed there).
PHYSICS_CHOICES = ("embedded", "gazebo")
_WIND_KEYS = {"north_m_s", "east_m_s", "down_m_s", "gust_std_m_s", "gust_time_constant_s"}


@dataclass(frozen=True, slots=True)
class Scenario:
    """A scenario as read from its file (or built in Python).

    Attributes:
        name: The scenario's name (its file's stem unless it names itself).
        plan: What bfsitl's autopilot flies (the ``[flight]`` table).
        duration_s: Simulation seconds from arming; the run ends then at the latest (0 for
            a replay: it lasts as long as its log).
        faults: What is done to the flight and when (``[[fault]]``), seconds after arming.
        expect: ``[expect]`` as written: key and value pairs, checked by
            :mod:`bfsitl.scenario.expectations`.
        description: One line saying what it tests.
        cli: CLI lines provisioned before the flight.
        cli_for: ``[cli_for]``: lines for one firmware generation only, after ``cli``
            (settings the other does not have): ``(("master", (...)), ("4.6", (...)))``.
        wind: Wind and gusts (``[wind]``); None is still air.
        quad: The simulated quad (``[vehicle]``); Gazebo's IRIS by default.
        initial_heading_deg: Where the nose points at the start (``[vehicle]
            heading_deg``), degrees clockwise from north.
        seed: Seeds the gusts and the sensor noise: the same seed, the same disturbances.
        firmware: Builds to run on when the command line names none.
        requires_gps: Only firmware with a GPS can fly it (a GPS Rescue); others skip it.
        requires: Build features it needs (``flight_plan``, ``geofence``, ...: the names of
            :data:`bfsitl.build.binary_scan.FEATURE_MARKERS`); a build without one skips it.
        fc_waypoints: The FC's own mission (``[[fc_waypoint]]``, master's flight plans),
            written to it as ``waypoint`` CLI lines before the scenario's own lines.
        settle_s: The run ends early once the FC is disarmed and the vehicle at rest this
            many seconds.
        source: The file it was read from; None when built in Python.
        own_vehicle: ``[vehicle]`` names a model or a mass: the scenario is about that quad,
            and ``--vehicle`` (:func:`on_vehicle`) leaves it.
        known_failures: Firmware defects it flies into on purpose (``[[known_failure]]``,
            :mod:`bfsitl.scenario.known_failures`).
        replay: ``[replay]``: a real flight's log flown again instead of ``plan``
            (:mod:`bfsitl.scenario.replay_spec`); None for a flown scenario.
        side_cli: A comparison side's lines, before ``cli``.
        rc_rate_hz: The RC link's frame rate on a lockstep build (``[rc] rate_hz``, 16 to
            1000 Hz, 250 by default); None (``"packet"``): a frame in every fdm packet, and
            4.6.0's stock receiver, which never loses the link.
        physics: ``"embedded"`` (bfsitl's) or ``"gazebo"`` (Gazebo Harmonic with the
            BetaflightPlugin, docs/gazebo.md: a stock build, real time, its world's IRIS).
    """

    name: str
    plan: MissionPlan
    duration_s: float
    faults: tuple[FaultSpec, ...] = ()
    #: ``[expect]`` as written: key -> value (checked by :mod:`bfsitl.scenario.expectations`).
    expect: tuple[tuple[str, Any], ...] = ()
    description: str = ""
    cli: tuple[str, ...] = ()
    #: ``[cli_for]``: lines for one firmware generation only, after ``cli`` (settings the
    #: other does not have): ``(("master", (...)), ("4.6", (...)))``.
    cli_for: tuple[tuple[str, tuple[str, ...]], ...] = ()
    wind: Wind | None = None
    #: The simulated quad (``[vehicle]``).
    quad: QuadParams = IRIS
    #: Where its nose points at the start (``[vehicle] heading_deg``), clockwise from north.
    initial_heading_deg: float = 0.0
    seed: int = 0
    #: Builds to run on when the command line names none.
    firmware: tuple[str, ...] = ()
    #: ``"embedded"`` or ``"gazebo"`` (``physics``).
    physics: Physics = "embedded"
    #: Only firmware with a GPS can fly it (a GPS Rescue); others skip it.
    requires_gps: bool = False
    #: Build features it needs (``flight_plan``, ``geofence``, ...: the names of
    #: :data:`bfsitl.build.binary_scan.FEATURE_MARKERS`); a build without one skips it.
    requires: tuple[str, ...] = ()
    #: The FC's own mission (``[[fc_waypoint]]``, master's flight plans), written to it as
    #: ``waypoint`` CLI lines before the scenario's own lines.
    fc_waypoints: tuple[FcWaypoint, ...] = ()
    #: The run ends early once the FC is disarmed and the vehicle at rest this long.
    settle_s: float = DEFAULT_SETTLE_S
    source: Path | None = None
    #: ``[vehicle]`` names a model or a mass: ``--vehicle`` does not replace its quad.
    own_vehicle: bool = False
    #: Firmware defects it flies into on purpose (``[[known_failure]]``).
    known_failures: tuple[KnownFailure, ...] = ()
    #: ``[replay]``: a real flight's log flown again instead of ``plan``.
    replay: ReplaySpec | None = None
    #: A comparison side's CLI lines (``scenario compare --a-cli/--b-cli``), applied before
    #: the scenario's own, so a scenario that sets the value itself keeps it.
    side_cli: tuple[str, ...] = ()
    #: ``[rc] rate_hz``: the RC link's frames per second on a lockstep build (None:
    #: ``"packet"``, one in every fdm packet); a replay flies its log's rate.
    rc_rate_hz: float | None = DEFAULT_RC_RATE_HZ

    @property
    def where(self) -> str:
        return str(self.source) if self.source is not None else f"scenario {self.name}"


def _strings(where: str, key: str, value: Any) -> tuple[str, ...]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ScenarioError(f"{where}: {key} must be a string or a list of strings, got {value!r}")
    return tuple(value)


def _rc_rate_hz(where: str, data: dict[str, Any], replay: bool) -> float | None:
    """``[rc] rate_hz``: 16 to 1000, or ``"packet"`` (None)."""
    if "rc" not in data:
        return DEFAULT_RC_RATE_HZ
    raw = data["rc"]
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: [rc] must be a table")
    unknown = set(raw) - {"rate_hz"}
    if unknown:
        raise ScenarioError(
            f"{where}: [rc] has unknown key(s) {', '.join(sorted(unknown))}; known: rate_hz"
        )
    if replay:
        raise ScenarioError(
            f"{where}: [rc] with [replay]: a replay sends its log's frames at the rate its "
            f"receiver had"
        )
    rate = raw.get("rate_hz", DEFAULT_RC_RATE_HZ)
    if rate == "packet":
        return None
    if isinstance(rate, str):
        raise ScenarioError(
            f"{where}: rc.rate_hz = {rate!r}: give frames a second "
            f'({MIN_RC_RATE_HZ:g} to {MAX_RC_RATE_HZ:g}) or "packet"'
        )
    return number_in(where, "rc.rate_hz", rate, MIN_RC_RATE_HZ, MAX_RC_RATE_HZ)


def _wind(where: str, raw: Any) -> Wind:
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: [wind] must be a table")
    unknown = set(raw) - _WIND_KEYS
    if unknown:
        raise ScenarioError(
            f"{where}: [wind] has unknown key(s) {', '.join(sorted(unknown))}; "
            f"known: {', '.join(sorted(_WIND_KEYS))}"
        )
    limits = {
        "gust_std_m_s": (0.0, MAX_GUST_STD_M_S),
        "gust_time_constant_s": (MIN_GUST_TIME_CONSTANT_S, MAX_GUST_TIME_CONSTANT_S),
    }
    component = (-MAX_WIND_COMPONENT_M_S, MAX_WIND_COMPONENT_M_S)
    values = {
        k: number_in(where, f"wind.{k}", v, *limits.get(k, component)) for k, v in raw.items()
    }
    return Wind(
        (values.get("north_m_s", 0.0), values.get("east_m_s", 0.0), values.get("down_m_s", 0.0)),
        values.get("gust_std_m_s", 0.0),
        values.get("gust_time_constant_s", 2.0),
    )


def _vehicle(
    where: str, raw: Any, source: Path | None, default: str = DEFAULT_VEHICLE
) -> QuadParams:
    """``[vehicle]``: a shipped vehicle or a profile file (relative to the scenario file),
    optionally heavier or lighter (payload, battery); ``default`` when it names none."""
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: [vehicle] must be a table")
    unknown = set(raw) - {"model", "mass_kg", "heading_deg"}
    if unknown:
        raise ScenarioError(
            f"{where}: [vehicle] has unknown key(s) "
            f"{', '.join(sorted(unknown))}; known: heading_deg, mass_kg, model"
        )
    model = raw.get("model", default)
    if not isinstance(model, str) or not model:
        raise ScenarioError(f"{where}: [vehicle] model must be a vehicle's name or a file")
    try:
        quad = load_vehicle(model, relative_to=source.parent if source is not None else None)
    except VehicleProfileError as exc:
        raise ScenarioError(f"{where}: [vehicle] {exc}") from None
    if "mass_kg" in raw:
        mass_kg = number_in(where, "vehicle.mass_kg", raw["mass_kg"], 0.05, 20.0)
        quad = replace(quad, name=f"{quad.name}, {mass_kg:g} kg", mass_kg=mass_kg)
        try:
            quad.hover_command  # noqa: B018 - raises when its motors cannot lift it
        except SimInputError as exc:
            raise ScenarioError(f"{where}: [vehicle] {exc}") from None
    return quad


#: ``[cli_for]`` tables: the firmware generations (bfsitl.protocol.firmware_profile).
CLI_GENERATIONS = ("4.6", "master")


def _cli_for(where: str, data: dict[str, Any]) -> tuple[tuple[str, tuple[str, ...]], ...]:
    raw = data.get("cli_for", {})
    if not isinstance(raw, dict):
        raise ScenarioError(f"{where}: [cli_for] must be a table of generation = [lines]")
    unknown = set(raw) - set(CLI_GENERATIONS)
    if unknown:
        raise ScenarioError(
            f"{where}: [cli_for] has unknown generation(s) "
            f"{', '.join(sorted(unknown))}; known: {', '.join(CLI_GENERATIONS)}"
        )
    return tuple((name, _strings(where, f"cli_for.{name}", lines)) for name, lines in raw.items())


def scenario_from_dict(data: dict[str, Any], *, name: str, source: Path | None = None) -> Scenario:
    """A scenario from a file's tables; ``name`` is used unless the file names itself."""
    where = str(source) if source is not None else f"scenario {name}"
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ScenarioError(
            f"{where}: unknown key(s) {', '.join(sorted(unknown))}; known: "
            f"{', '.join(sorted(_TOP_KEYS))}"
        )
    replay = read_replay_spec(data, where=where, source=source) if "replay" in data else None
    default_model = DEFAULT_VEHICLE if replay is None else DEFAULT_REPLAY_VEHICLE
    if replay is None:
        plan, duration_s, faults = _flown(data, where)
    else:
        plan, duration_s, faults = MissionPlan(), 0.0, ()
    expect = data.get("expect", {})
    if not isinstance(expect, dict) or not expect:
        raise ScenarioError(
            f"{where}: [expect] is missing or empty: a scenario must say what "
            f"has to hold (see docs/scenarios.md)"
        )
    own_name = data.get("name", name)
    if not isinstance(own_name, str) or not own_name.strip():
        raise ScenarioError(f"{where}: name must be a non-empty string")
    description = data.get("description", "")
    if not isinstance(description, str):
        raise ScenarioError(f"{where}: description must be a string")
    seed = data.get("seed", 0)
    if isinstance(seed, bool) or not isinstance(seed, int):
        raise ScenarioError(f"{where}: seed must be an integer, got {seed!r}")
    waypoints = read_fc_waypoints(data.get("fc_waypoint", []), where=where)
    requires = _strings(where, "requires", data.get("requires", []))
    unknown_features = sorted(set(requires) - set(FEATURE_MARKERS))
    if unknown_features:
        raise ScenarioError(
            f"{where}: requires: unknown feature(s) "
            f"{', '.join(unknown_features)}; known: "
            f"{', '.join(sorted(FEATURE_MARKERS))}"
        )
    if waypoints and "flight_plan" not in requires:
        requires = (*requires, "flight_plan")
    physics = data.get("physics", "embedded")
    if physics not in PHYSICS_CHOICES:
        raise ScenarioError(f"{where}: physics must be one of {', '.join(PHYSICS_CHOICES)}")
    requires_gps = data.get("requires_gps", plan.needs_position or bool(waypoints))
    if not isinstance(requires_gps, bool):
        raise ScenarioError(f"{where}: requires_gps must be true or false")
    return Scenario(
        name=own_name.strip(),
        plan=plan,
        duration_s=duration_s,
        faults=faults,
        expect=tuple(expect.items()),
        description=description,
        cli=_strings(where, "cli", data.get("cli", [])),
        cli_for=_cli_for(where, data),
        wind=_wind(where, data["wind"]) if "wind" in data else None,
        seed=seed,
        quad=_vehicle(where, data["vehicle"], source, default_model)
        if "vehicle" in data
        else load_vehicle(default_model),
        own_vehicle=bool({"model", "mass_kg"} & set(data.get("vehicle", {}))),
        known_failures=read_known_failures(data.get("known_failure", []), where),
        initial_heading_deg=number_in(
            where,
            "vehicle.heading_deg",
            data.get("vehicle", {}).get("heading_deg", 0.0),
            0.0,
            360.0,
        )
        if isinstance(data.get("vehicle"), dict)
        else 0.0,
        firmware=_strings(where, "firmware", data.get("firmware", [])),
        requires_gps=requires_gps,
        requires=requires,
        physics=cast("Physics", physics),
        fc_waypoints=waypoints,
        settle_s=number_in(where, "settle_s", data.get("settle_s", DEFAULT_SETTLE_S), 0.0, 60.0),
        source=source,
        replay=replay,
        rc_rate_hz=_rc_rate_hz(where, data, replay is not None),
    )


def _flown(data: dict[str, Any], where: str) -> tuple[MissionPlan, float, tuple[FaultSpec, ...]]:
    """What a flown scenario flies: ``[flight]``, ``duration_s`` and its ``[[fault]]``s."""
    for key in ("duration_s", "flight"):
        if key not in data:
            raise ScenarioError(
                f"{where}: {key} is missing"
                + (
                    " (simulation seconds from arming)"
                    if key == "duration_s"
                    else " ([flight] says what the autopilot flies, [replay] which log to "
                    "fly again)"
                )
            )
    duration_s = number_in(where, "duration_s", data["duration_s"], 1.0, MAX_DURATION_S)
    if not isinstance(data["flight"], dict):
        raise ScenarioError(f"{where}: [flight] must be a table")
    try:
        plan = plan_from_dict(data["flight"], source=f"{where}, [flight]")
    except MissionError as exc:
        raise ScenarioError(str(exc)) from None
    raw_faults = data.get("fault", [])
    if not isinstance(raw_faults, list):
        raise ScenarioError(f"{where}: faults are written as [[fault]] tables")
    faults = tuple(
        read_fault_spec(raw, where=where, number=n, run_s=duration_s)
        for n, raw in enumerate(raw_faults, 1)
    )
    return plan, duration_s, faults


def on_vehicle(scenarios: list[Scenario], quad: QuadParams | None) -> list[Scenario]:
    """The scenarios flown on ``quad`` (``--vehicle``), but for those about a quad of their
    own (``[vehicle] model`` or ``mass_kg``); None changes nothing."""
    if quad is None:
        return scenarios
    return [s if s.own_vehicle else replace(s, quad=quad) for s in scenarios]
