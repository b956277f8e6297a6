"""A flight's record, one row per control step: the target, the truth, the FC's view, what
was commanded.  The columns carry their units in their names; where rows go (CSV, MCAP,
plots) is :mod:`bfsitl.records`' business."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from bfsitl.mission.vehicle import FlightSample


@dataclass(frozen=True, slots=True)
class FlightRow:
    """One control step: the target, the truth, the FC's view, what was commanded."""

    time_s: float  # simulation time
    phase: str  # a Phase (arming, takeoff, hold, goto, land, landed, or how it
    # ended); a str, so a log read back compares alike
    target_alt_m: float
    sim_alt_m: float  # simulated truth above the take-off point
    fc_alt_m: float  # what the FC reports (MSP_ALTITUDE)
    climb_m_s: float  # climb rate the controller was given (slope of fc_alt_m)
    sim_climb_m_s: float
    fc_accel_up_m_s2: float  # FC accelerometer (MSP_RAW_IMU) made vertical, gravity removed
    roll_deg: float  # FC attitude
    pitch_deg: float
    yaw_deg: float
    sim_tilt_deg: float
    sim_roll_deg: float  # simulated truth in Betaflight's convention: roll right wing
    sim_pitch_deg: float  # down positive, pitch nose down positive, yaw the heading
    sim_yaw_deg: float  # clockwise from north, 0..360
    rc_roll_us: int
    rc_pitch_us: int
    rc_throttle_us: int
    rc_yaw_us: int
    rc_aux1_us: int
    rc_aux2_us: int
    motor1: float  # applied motor commands 0..1, Betaflight numbering
    motor2: float
    motor3: float
    motor4: float
    armed: bool
    wall_s: float  # seconds since the mission started, wall clock
    # Horizontal position, metres north/east of the take-off point (empty where unknown):
    sim_north_m: float = math.nan  # the truth
    sim_east_m: float = math.nan
    fc_north_m: float = math.nan  # the FC's GPS, during position control
    fc_east_m: float = math.nan
    target_north_m: float = math.nan  # the position target, during position control
    target_east_m: float = math.nan
    target_heading_deg: float = math.nan  # the heading held or turned to (position control)
    waypoint: int = 0  # the mission waypoint being flown to or held, 1-based


#: The CSV columns, in order.
COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(FlightRow))


class RowWriter(Protocol):
    """Where a mission writes each row as it is recorded (a CSV log, any record sink)."""

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None: ...
