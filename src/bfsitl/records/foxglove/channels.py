"""A flight's rows as Foxglove channels: what is logged on which topic, in which units.

Every per-row topic gets exactly one message per control step, stamped with the step's
simulation time, so an MCAP file lines up row for row with the CSV log and plays back at the
simulation's pace whatever the wall clock did (lockstep flies many times faster).

| topic | schema | content |
| --- | --- | --- |
| ``/sim/pose`` | foxglove.FrameTransform | ``world`` -> ``sim_body``: the simulated truth |
| ``/fc/pose`` | foxglove.FrameTransform | ``world`` -> ``fc_body``: the FC's attitude, at its GPS
  position (the truth's where it has none) and its own altitude |
| ``/flight/altitude`` | JSON | target, truth, FC (m, up), climb rates (m/s) |
| ``/flight/position`` | JSON | target, truth, FC GPS (m north/east of take-off), headings |
| ``/rc`` | JSON | the six channels sent, microseconds |
| ``/motors`` | JSON | motor commands 0..1, Betaflight numbering |
| ``/fc/state`` | JSON | armed, phase, waypoint, arming blockers, flight modes |
| ``/events`` | foxglove.Log | the mission's events; an arming change is one too |

Frames: ``world`` is ENU (x east, y north, z up) with its origin at the take-off point; bodies
are FLU (see :mod:`bfsitl.records.foxglove.frames`).  Unknown values (NaN) are JSON nulls.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from bfsitl.records.foxglove.frames import betaflight_to_enu_quaternion

if TYPE_CHECKING:
    from bfsitl.mission.flight_row import FlightRow
    from bfsitl.mission.vehicle import FlightSample

WORLD_FRAME = "world"
SIM_BODY_FRAME = "sim_body"
FC_BODY_FRAME = "fc_body"

_NUMBER = {"type": ["number", "null"]}
_INTEGER = {"type": "integer"}


def _schema(title: str, properties: dict[str, Any]) -> dict[str, Any]:
    return {"title": title, "type": "object", "properties": properties}


#: JSON topics and their schemas (what Foxglove's plot and raw-message panels show).
JSON_TOPICS: dict[str, dict[str, Any]] = {
    "/flight/altitude": _schema(
        "bfsitl.Altitude",
        {
            name: _NUMBER
            for name in (
                "target_alt_m",
                "sim_alt_m",
                "fc_alt_m",
                "climb_m_s",
                "sim_climb_m_s",
                "fc_accel_up_m_s2",
            )
        },
    ),
    "/flight/position": _schema(
        "bfsitl.Position",
        {
            name: _NUMBER
            for name in (
                "target_north_m",
                "target_east_m",
                "sim_north_m",
                "sim_east_m",
                "fc_north_m",
                "fc_east_m",
                "target_heading_deg",
                "sim_yaw_deg",
                "yaw_deg",
            )
        },
    ),
    "/rc": _schema(
        "bfsitl.Rc",
        {
            name: _INTEGER
            for name in ("roll_us", "pitch_us", "throttle_us", "yaw_us", "aux1_us", "aux2_us")
        },
    ),
    "/motors": _schema("bfsitl.Motors", {f"motor{n}": _NUMBER for n in range(1, 5)}),
    "/fc/state": _schema(
        "bfsitl.FcState",
        {
            "armed": {"type": "boolean"},
            "phase": {"type": "string"},
            "waypoint": _INTEGER,
            "arming_blockers": {"type": "array", "items": {"type": "string"}},
            "flight_modes": {"type": "array", "items": {"type": "string"}},
        },
    ),
}
TRANSFORM_TOPICS = ("/sim/pose", "/fc/pose")
EVENT_TOPIC = "/events"
#: Every topic with one message per row.
PER_ROW_TOPICS: tuple[str, ...] = (*TRANSFORM_TOPICS, *JSON_TOPICS)


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _or(value: float, fallback: float) -> float:
    return value if math.isfinite(value) else fallback


def time_ns(time_s: float) -> int:
    """Simulation seconds as the integer nanoseconds MCAP and Foxglove stamp messages with."""
    return round(time_s * 1e9)


def row_messages(row: FlightRow, sample: FlightSample | None = None) -> dict[str, dict[str, Any]]:
    """The JSON messages of one row, by topic."""
    return {
        "/flight/altitude": {
            "target_alt_m": _finite(row.target_alt_m),
            "sim_alt_m": _finite(row.sim_alt_m),
            "fc_alt_m": _finite(row.fc_alt_m),
            "climb_m_s": _finite(row.climb_m_s),
            "sim_climb_m_s": _finite(row.sim_climb_m_s),
            "fc_accel_up_m_s2": _finite(row.fc_accel_up_m_s2),
        },
        "/flight/position": {
            "target_north_m": _finite(row.target_north_m),
            "target_east_m": _finite(row.target_east_m),
            "sim_north_m": _finite(row.sim_north_m),
            "sim_east_m": _finite(row.sim_east_m),
            "fc_north_m": _finite(row.fc_north_m),
            "fc_east_m": _finite(row.fc_east_m),
            "target_heading_deg": _finite(row.target_heading_deg),
            "sim_yaw_deg": _finite(row.sim_yaw_deg),
            "yaw_deg": _finite(row.yaw_deg),
        },
        "/rc": {
            "roll_us": row.rc_roll_us,
            "pitch_us": row.rc_pitch_us,
            "throttle_us": row.rc_throttle_us,
            "yaw_us": row.rc_yaw_us,
            "aux1_us": row.rc_aux1_us,
            "aux2_us": row.rc_aux2_us,
        },
        "/motors": {
            "motor1": row.motor1,
            "motor2": row.motor2,
            "motor3": row.motor3,
            "motor4": row.motor4,
        },
        "/fc/state": {
            "armed": row.armed,
            "phase": row.phase,
            "waypoint": row.waypoint,
            "arming_blockers": list(sample.arming_blockers) if sample is not None else [],
            "flight_modes": list(sample.flight_modes) if sample is not None else [],
        },
    }


def pose_of(
    row: FlightRow, which: str
) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
    """(translation ENU m, rotation xyzw) of the truth (``"sim"``) or the FC (``"fc"``).

    Unknown truth (Gazebo) sits at the origin, level; the FC without a GPS position is drawn at
    the truth's, so the two bodies can be compared in one view.
    """
    sim_east, sim_north = _or(row.sim_east_m, 0.0), _or(row.sim_north_m, 0.0)
    if which == "sim":
        translation = (sim_east, sim_north, _or(row.sim_alt_m, 0.0))
        angles = (row.sim_roll_deg, row.sim_pitch_deg, row.sim_yaw_deg)
    else:
        translation = (
            _or(row.fc_east_m, sim_east),
            _or(row.fc_north_m, sim_north),
            _or(row.fc_alt_m, 0.0),
        )
        angles = (row.roll_deg, row.pitch_deg, row.yaw_deg)
    roll, pitch, yaw = (_or(angle, 0.0) for angle in angles)
    return translation, betaflight_to_enu_quaternion(roll, pitch, yaw)


class FlightChannels:
    """The flight's channels in one Foxglove context, and how a row and an event are logged."""

    def __init__(self, context: Any) -> None:
        import foxglove
        from foxglove.channels import FrameTransformChannel, LogChannel

        self._foxglove = foxglove
        self.transforms = {
            topic: FrameTransformChannel(topic, context=context) for topic in TRANSFORM_TOPICS
        }
        self.json = {
            topic: foxglove.Channel(
                topic,
                schema=foxglove.Schema(
                    name=schema["title"], encoding="jsonschema", data=json.dumps(schema).encode()
                ),
                message_encoding="json",
                context=context,
            )
            for topic, schema in JSON_TOPICS.items()
        }
        self.events = LogChannel(EVENT_TOPIC, context=context)
        self._armed: bool | None = None

    def log_row(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        from foxglove.messages import FrameTransform, Quaternion, Timestamp, Vector3

        stamp_ns = time_ns(row.time_s)
        stamp = Timestamp(sec=stamp_ns // 1_000_000_000, nsec=stamp_ns % 1_000_000_000)
        for topic, which, child in (
            ("/sim/pose", "sim", SIM_BODY_FRAME),
            ("/fc/pose", "fc", FC_BODY_FRAME),
        ):
            (x, y, z), (qx, qy, qz, qw) = pose_of(row, which)
            self.transforms[topic].log(
                FrameTransform(
                    timestamp=stamp,
                    parent_frame_id=WORLD_FRAME,
                    child_frame_id=child,
                    translation=Vector3(x=x, y=y, z=z),
                    rotation=Quaternion(x=qx, y=qy, z=qz, w=qw),
                ),
                log_time=stamp_ns,
            )
        for topic, message in row_messages(row, sample).items():
            self.json[topic].log(json.dumps(message).encode(), log_time=stamp_ns)
        if self._armed is not None and row.armed != self._armed:
            self.log_event(row.time_s, "FC armed" if row.armed else "FC disarmed")
        self._armed = row.armed

    def log_event(
        self, time_s: float, text: str, *, level: str = "Info", name: str = "bfsitl"
    ) -> None:
        from foxglove.messages import Log, LogLevel, Timestamp

        stamp_ns = time_ns(time_s)
        self.events.log(
            Log(
                timestamp=Timestamp(sec=stamp_ns // 1_000_000_000, nsec=stamp_ns % 1_000_000_000),
                level=getattr(LogLevel, level),
                message=text,
                name=name,
            ),
            log_time=stamp_ns,
        )


#: A callback taking one line of text.
EventSink = Callable[[str], None]
