"""A flight's record: one row per control step, written to CSV as it happens.

Each row is flushed when written, so a crash, a killed process or Ctrl-C loses nothing that
was flown.  The columns carry their units in their names.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import BfsitlError


@dataclass(frozen=True, slots=True)
class FlightRow:
    """One control step: the target, the truth, the FC's view, what was commanded."""

    time_s: float            # simulation time
    phase: str               # a Phase (arming, takeoff, hold, goto, land, landed, or how it
                             # ended); a str, so a log read back compares alike
    target_alt_m: float
    sim_alt_m: float         # simulated truth above the take-off point
    fc_alt_m: float          # what the FC reports (MSP_ALTITUDE)
    climb_m_s: float         # climb rate the controller was given (slope of fc_alt_m)
    sim_climb_m_s: float
    fc_accel_up_m_s2: float  # FC accelerometer (MSP_RAW_IMU) made vertical, gravity removed
    roll_deg: float          # FC attitude
    pitch_deg: float
    yaw_deg: float
    sim_tilt_deg: float
    sim_roll_deg: float      # simulated truth in Betaflight's convention: roll right wing
    sim_pitch_deg: float     # down positive, pitch nose down positive, yaw the heading
    sim_yaw_deg: float       # clockwise from north, 0..360
    rc_roll_us: int
    rc_pitch_us: int
    rc_throttle_us: int
    rc_yaw_us: int
    rc_aux1_us: int
    rc_aux2_us: int
    motor1: float            # applied motor commands 0..1, Betaflight numbering
    motor2: float
    motor3: float
    motor4: float
    armed: bool
    wall_s: float            # seconds since the mission started, wall clock
    # Horizontal position, metres north/east of the take-off point (empty where unknown):
    sim_north_m: float = math.nan      # the truth
    sim_east_m: float = math.nan
    fc_north_m: float = math.nan       # the FC's GPS, during position control
    fc_east_m: float = math.nan
    target_north_m: float = math.nan   # the position target, during position control
    target_east_m: float = math.nan
    target_heading_deg: float = math.nan  # the heading held or turned to (position control)
    waypoint: int = 0                  # the mission waypoint being flown to or held, 1-based


COLUMNS: tuple[str, ...] = tuple(f.name for f in dataclasses.fields(FlightRow))


def _cell(value: object) -> str:
    if isinstance(value, bool):
        return "1" if value else "0"
    if isinstance(value, float):
        # Unknown values (no simulated truth with Gazebo) are empty cells, not "nan".
        return f"{value:.4f}" if math.isfinite(value) else ""
    return str(value)


class CsvFlightLog:
    """Writes :class:`FlightRow` lines to a CSV file, flushed row by row."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file: io.TextIOWrapper | None = self.path.open("w", newline="")
        except OSError as exc:
            raise BfsitlError(f"cannot write the flight log {self.path}: {exc}") from exc
        self._writer = csv.writer(self._file)
        self._writer.writerow(COLUMNS)
        self._file.flush()
        self.rows_written = 0

    def write(self, row: FlightRow) -> None:
        if self._file is None:
            raise BfsitlError(f"flight log {self.path} is closed")
        self._writer.writerow([_cell(getattr(row, name)) for name in COLUMNS])
        self._file.flush()
        self.rows_written += 1

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
            self._file = None

    def __enter__(self) -> CsvFlightLog:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def read_flight_log(path: str | Path) -> list[dict[str, str]]:
    """The rows of a log as dicts of strings (for tools and tests)."""
    with Path(path).open(newline="") as file:
        reader = csv.DictReader(file)
        if reader.fieldnames is None or tuple(reader.fieldnames) != COLUMNS:
            raise BfsitlError(f"{path} is not a bfsitl flight log (columns "
                              f"{reader.fieldnames})")
        return list(reader)
