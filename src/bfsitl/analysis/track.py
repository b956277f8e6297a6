"""What the analysers read: a flight as a list of :class:`TrackPoint`, from either source.

* bfsitl's own record of a flight (:func:`point_from_row`: a
  :class:`~bfsitl.mission.flight_row.FlightRow` and its sample): the simulated truth
  (height, position, attitude, ground contact), the autopilot's targets, the motors, and
  what the FC reported; about 50 points a second;
* the FC's blackbox log (:func:`track_from_blackbox`, a real flight's or a SITL's): the
  gyro against its setpoint, the motors, the FC's attitude, accelerometer and barometer,
  the failsafe phase; a few hundred points a second, and no truth.

A value a source does not have is NaN (or None, or an empty tuple); each analyser says what
it needs and is skipped on a track without it.
"""

from __future__ import annotations

import math
import operator
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, fields
from itertools import repeat
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from bfsitl.analysis.logged_attitude import compiled_attitudes_deg
from bfsitl.collector_paused import collector_paused

if TYPE_CHECKING:
    from bfsitl.blackbox import BlackboxFrame, BlackboxLog
    from bfsitl.mission.flight_row import FlightRow
    from bfsitl.mission.vehicle import FlightSample

_NAN = math.nan
#: Below this height the truth counts as on the ground when no sample says so.
GROUND_ALT_M = 0.05


@dataclass(slots=True)
class TrackPoint:
    """One look at a flight, on the track's clock.  Not frozen, though nothing changes a
    point once made: a log's track has tens of thousands, and a frozen dataclass's
    ``__init__`` (one ``object.__setattr__`` per field) took four times as long."""

    time_s: float
    armed: bool
    #: The vehicle is off the ground (None: the source cannot tell, a blackbox log).
    airborne: bool | None = None
    #: Height above the take-off point: the truth for a flight, the barometer for a log.
    alt_m: float = _NAN
    climb_m_s: float = _NAN  # vertical speed, up positive (truth)
    north_m: float = _NAN  # position from the take-off point (truth)
    east_m: float = _NAN
    #: Attitude: the truth for a flight, the FC's estimate for a log (Betaflight's signs).
    tilt_deg: float = _NAN
    roll_deg: float = _NAN
    pitch_deg: float = _NAN
    #: The autopilot's phase (hold, goto, land, watch, ...); "" when no autopilot flies.
    phase: str = ""
    target_alt_m: float = _NAN
    target_north_m: float = _NAN
    target_east_m: float = _NAN
    #: Motor commands 0..1, Betaflight's order.
    motors: tuple[float, ...] = ()
    #: Roll, pitch, yaw rates (deg/s): the filtered gyro and the PID loop's setpoint.
    gyro_deg_s: tuple[float, ...] = ()
    setpoint_deg_s: tuple[float, ...] = ()
    #: The accelerometer's magnitude, g (1 at rest; NaN when not known).
    accel_g: float = _NAN
    #: The throttle commanded, a share of the stick's travel (0 low, 1 full; NaN: not known).
    throttle: float = _NAN
    #: ``failsafePhase_e`` (None: not read).
    failsafe_phase: int | None = None
    #: The receiver: a signal and valid flight channels (None: not known).
    rx_ok: bool | None = None
    modes: tuple[str, ...] = ()
    #: The FC levels the quad itself (ANGLE, HORIZON, a failsafe); False: a log's switches say
    #: it flies rates (acro), where a pilot may turn it any way up; None: not known (a flight
    #: bfsitl flies levels it).
    self_levelling: bool | None = None
    #: What the FC believes: its altitude and its GPS position (NaN: not reported).
    fc_alt_m: float = _NAN
    fc_north_m: float = _NAN
    fc_east_m: float = _NAN

    @property
    def distance_m(self) -> float:
        return math.hypot(self.north_m, self.east_m)


@dataclass(slots=True)
class Track:
    """A flight for the analysers."""

    #: ``flight`` (bfsitl's record, with the truth) or ``blackbox`` (the FC's log).
    source: str
    points: list[TrackPoint] = field(default_factory=list)
    #: A log's disarm reason (FAILSAFE, CRASH_PROTECTION, ...); None when unknown.
    disarm_reason: str | None = None
    #: Where it came from, for messages (a file, a run).
    label: str = ""
    #: How far from home the flight was meant to go (the FC's own waypoints, which no
    #: row's target shows); the fly-away bound starts from the farther of this and the
    #: targets.
    planned_reach_m: float = 0.0

    #: What :meth:`has` found, per name, and the number of points it looked at.
    _found: dict[str, tuple[int, bool]] = field(default_factory=dict, repr=False, compare=False)

    def has(self, name: str) -> bool:
        """Whether some point has attribute ``name`` (a finite number, a non-empty tuple).
        Each analyser asks for what it needs: the answer is kept until points are added (a
        name no point has costs a walk over every point, thousands in a log)."""
        count = len(self.points)
        known = self._found.get(name)
        if known is not None and known[0] == count:
            return known[1]
        found = _any_present(self.points, name)
        self._found[name] = (count, found)
        return found


def _any_present(points: list[TrackPoint], name: str) -> bool:
    """Whether some point's ``name`` is a finite number, a non-empty tuple, or any other
    value but None and "" (loops in C where the field's type allows: a log has tens of
    thousands of points, and a field its source never fills is looked at in every one)."""
    values = map(operator.attrgetter(name), points)
    if name in _FLOAT_FIELDS:
        return any(map(math.isfinite, values))
    if name in _TUPLE_FIELDS:
        return any(values)
    return any(value is not None and value != "" for value in values)


_FLOAT_FIELDS = frozenset(f.name for f in fields(TrackPoint) if f.type == "float")
_TUPLE_FIELDS = frozenset(f.name for f in fields(TrackPoint) if str(f.type).startswith("tuple"))


def stick_share(throttle_us: float) -> float:
    """A throttle in microseconds (rcCommand: 1000 low, 2000 full) as a share of the stick."""
    return min(1.0, max(0.0, (throttle_us - 1000.0) / 1000.0))


def point_from_row(
    row: FlightRow,
    sample: FlightSample | None = None,
    *,
    time_s: float | None = None,
    failsafe_phase: int | None = None,
) -> TrackPoint:
    """A point of bfsitl's record of a flight; ``time_s`` replaces the row's clock (a
    scenario counts from arming)."""
    if sample is not None:
        airborne = not sample.on_ground
        modes = sample.flight_modes
        accel = math.sqrt(sum(a * a for a in sample.fc_accel_flu_m_s2)) / 9.80665
    else:
        airborne = row.sim_alt_m > GROUND_ALT_M
        modes = ()
        accel = _NAN
    return TrackPoint(
        time_s=row.time_s if time_s is None else time_s,
        armed=row.armed,
        airborne=airborne,
        alt_m=row.sim_alt_m,
        climb_m_s=row.sim_climb_m_s,
        north_m=row.sim_north_m,
        east_m=row.sim_east_m,
        tilt_deg=row.sim_tilt_deg,
        roll_deg=row.sim_roll_deg,
        pitch_deg=row.sim_pitch_deg,
        phase=row.phase,
        target_alt_m=row.target_alt_m,
        target_north_m=row.target_north_m,
        target_east_m=row.target_east_m,
        motors=(row.motor1, row.motor2, row.motor3, row.motor4),
        accel_g=accel,
        throttle=stick_share(row.rc_throttle_us),
        failsafe_phase=failsafe_phase,
        modes=modes,
        fc_alt_m=row.fc_alt_m,
        fc_north_m=row.fc_north_m,
        fc_east_m=row.fc_east_m,
    )


def track_from_rows(rows: list[FlightRow], *, label: str = "") -> Track:
    """A flight's rows as a track (no samples: ground contact from the true height)."""
    return Track("flight", [point_from_row(row) for row in rows], label=label)


def _motor_range(log: BlackboxLog) -> tuple[float, float]:
    """``motorOutput: low,high`` from the log's header (DShot 48..2047, PWM 1000..2000)."""
    low, _, high = log.headers.get("motorOutput", "").partition(",")
    try:
        lo, hi = float(low), float(high)
    except ValueError:
        lo, hi = 1000.0, 2000.0
    return (lo, hi) if hi > lo else (1000.0, 2000.0)


def _tilt_roll_pitch(xyz: tuple[int, ...]) -> tuple[float, float, float]:
    """Tilt, roll and pitch in degrees from the logged quaternion's x, y, z (w >= 0)."""
    if len(xyz) < 3:
        return _NAN, _NAN, _NAN
    x, y, z = (v / 0x7FFF for v in xyz[:3])
    w = math.sqrt(max(0.0, 1.0 - x * x - y * y - z * z))
    # Body z against the earth's vertical: cos(tilt) = 1 - 2 (x^2 + y^2).
    tilt = math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y)))))
    roll = math.degrees(math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x)))))
    return tilt, roll, pitch


#: ``flightModeFlags`` bits (the firmware's internal ``boxId_e``, not MSP's permanent box ids)
#: whose switch makes the FC level the quad: ANGLE 1 and HORIZON 2, the only levelling modes
#: at the same place from 3.x to 4.6 (ALTHOLD, POSHOLD and GPS RESCUE moved between releases,
#: [4.6] src/main/fc/rc_modes.h).  A failsafe levels whatever the switches say.
LEVELLING_BOXES = (1 << 1) | (1 << 2)


def track_from_blackbox(log: BlackboxLog) -> Track:
    """One blackbox log as a track, times from its first frame.  Rates are scaled back from
    ``blackbox_high_resolution``, motors from ``motorOutput``, the accelerometer from
    ``acc_1G``."""
    frames = log.frames
    scale = log.value_scale
    low, high = _motor_range(log)
    try:
        one_g = float(log.headers.get("acc_1G", "")) or 1.0
    except ValueError:
        one_g = _NAN
    start = frames[0].time_s if frames else 0.0
    with collector_paused():  # tens of thousands of points (bfsitl.collector_paused)
        points = _points(frames, start, low, high, scale, one_g)
    return Track(
        "blackbox",
        points,
        disarm_reason=log.disarm_reason_name,
        label=f"{log.path.name} log {log.index}",
    )


def _points(
    frames: Sequence[BlackboxFrame],
    start: float,
    low: float,
    high: float,
    scale: float,
    one_g: float,
) -> list[TrackPoint]:
    # The arithmetic is done a column at a time (the same IEEE operations as one frame at a
    # time, so the same floats); the attitude is libm's as math calls it (numpy's acos and
    # atan2 need not match to the last bit).
    motors, lengths = _column(frames, "motors")
    motor_rows = _rows(np.clip((motors - low) / (high - low), 0.0, 1.0), lengths)
    gyro, lengths = _column(frames, "gyro_adc")
    gyro_rows = _rows(gyro / scale, lengths)
    setpoint, lengths = _column(frames, "setpoint")
    setpoint_rows = _rows(setpoint[:, :3] / scale, lengths and [min(n, 3) for n in lengths])
    acc, _ = _column(frames, "acc")  # a row cut short is NaN, as it was one frame at a time
    accel = (
        (np.sqrt((acc * acc).sum(axis=1).astype(np.float64)) / one_g).tolist()
        if acc.shape[1] == 3
        else [_NAN] * len(frames)
    )
    tilts, rolls, pitches = zip(*_attitudes(frames), strict=True) if frames else ((), (), ())
    # The points are made positionally, a field's values at a time, in TrackPoint's order
    # (tests/unit/analysis/test_track.py holds the order).
    return list(
        map(
            TrackPoint,
            [round(frame.time_s - start, 6) for frame in frames],
            repeat(True),  # armed: a log is written while armed
            repeat(None),  # airborne: a log cannot tell
            [_NAN if f.baro_alt_cm is None else f.baro_alt_cm / 100.0 for f in frames],
            repeat(_NAN),  # climb, north, east: the truth's
            repeat(_NAN),
            repeat(_NAN),
            tilts,
            rolls,
            pitches,
            repeat(""),  # phase, targets: the autopilot's
            repeat(_NAN),
            repeat(_NAN),
            repeat(_NAN),
            motor_rows,
            gyro_rows,
            setpoint_rows,
            accel,
            [stick_share(f.rc_command[3]) if len(f.rc_command) > 3 else _NAN for f in frames],
            [frame.failsafe_phase for frame in frames],
            [
                None
                if f.rx_signal_received is None
                else bool(f.rx_signal_received and f.rx_flight_channels_valid)
                for f in frames
            ],
            repeat(()),  # modes: MSP's names, which a log does not have
            [bool(f.mode_switch_mask & LEVELLING_BOXES) or bool(f.failsafe_phase) for f in frames],
        )
    )


def _attitudes(frames: Sequence[BlackboxFrame]) -> Iterable[tuple[float, float, float]]:
    """Each frame's (tilt, roll, pitch): by the kernel where every frame has its three
    quaternion fields as ints (:mod:`bfsitl.analysis.logged_attitude`), else one at a time."""
    xyz, lengths = _column(frames, "quaternion_xyz")
    if lengths is None and xyz.shape[1:] == (3,) and xyz.dtype.kind == "i":
        compiled = compiled_attitudes_deg(xyz)
        if compiled is not None:
            return compiled
    return map(_tilt_roll_pitch, (frame.quaternion_xyz for frame in frames))


def _column(
    frames: Sequence[BlackboxFrame], name: str
) -> tuple[npt.NDArray[Any], list[int] | None]:
    """One tuple field of every frame as rows of a 2-D array (a field the log does not have
    is zero columns wide), and each row's length where they differ (else None).  Ints stay
    ints: numpy picks the type from the values, so nothing is rounded on the way in."""
    values = [getattr(frame, name) for frame in frames]
    lengths = list(map(len, values))
    width = max(lengths, default=0)
    if all(length == width for length in lengths):
        return np.array(values).reshape(len(values), width), None
    # A damaged frame's group stops at its first missing value: padded with NaN, which the
    # arithmetic carries along, and cut back to its length by _rows.
    padded = np.full((len(values), width), np.nan)
    for row, value in zip(padded, values, strict=True):
        row[: len(value)] = value
    return padded, lengths


def _rows(array: npt.NDArray[Any], lengths: list[int] | None) -> list[tuple[float, ...]]:
    rows = array.tolist()
    if lengths is None:
        return list(map(tuple, rows))
    return [tuple(row[:length]) for row, length in zip(rows, lengths, strict=True)]
