"""Figures of a flight, computed from its rows: the hold's error, the take-off's step response,
the FC's attitude against the truth, the legs' cross-track error, where it landed.

Each judges the simulated truth where there is one, and the FC's own view where the physics
is not bfsitl's (Gazebo) or there is none (a real board).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.legs import LegStats
from bfsitl.mission.phase import FLOWN, Phase


@dataclass(frozen=True, slots=True)
class HoldStats:
    """Simulated truth against the target while holding."""

    rms_error_m: float
    max_abs_error_m: float
    mean_error_m: float
    samples: int


@dataclass(frozen=True, slots=True)
class AttitudeTracking:
    """How well the FC's attitude followed the simulated truth while airborne (degrees)."""

    samples: int
    roll_rms_error_deg: float
    pitch_rms_error_deg: float
    max_abs_error_deg: float  # roll or pitch, whichever is worse
    max_true_tilt_deg: float


def attitude_tracking(rows: list[FlightRow]) -> AttitudeTracking | None:
    """FC roll/pitch vs the truth over the rows flown above the ground (None without truth).

    MSP_ATTITUDE comes from the same round trip as the rest of the sample and the truth is
    read right after it, so the comparison carries at most one exchange of delay.
    """
    flown = [
        r
        for r in rows
        if r.armed and r.phase in FLOWN and math.isfinite(r.sim_roll_deg) and r.sim_alt_m > 0.2
    ]
    if not flown:
        return None
    roll = [r.roll_deg - r.sim_roll_deg for r in flown]
    pitch = [r.pitch_deg - r.sim_pitch_deg for r in flown]

    def rms(errors: list[float]) -> float:
        return math.sqrt(sum(e * e for e in errors) / len(errors))

    return AttitudeTracking(
        len(flown),
        rms(roll),
        rms(pitch),
        max(max(map(abs, roll)), max(map(abs, pitch))),
        max(r.sim_tilt_deg for r in flown),
    )


def judged_position(row: FlightRow) -> tuple[float, float, float]:
    """North, east, height: the truth, or the FC's view when the physics is external."""
    if math.isfinite(row.sim_north_m):
        return row.sim_north_m, row.sim_east_m, judged_alt_m(row)
    return row.fc_north_m, row.fc_east_m, judged_alt_m(row)


def cross_track_rms(legs: list[LegStats]) -> float | None:
    """The cross-track RMS over all legs, each step weighted alike."""
    samples = sum(leg.samples for leg in legs)
    if not samples:
        return None
    return math.sqrt(sum(leg.cross_track_rms_m**2 * leg.samples for leg in legs) / samples)


def landed_from_start_m(rows: list[FlightRow]) -> float | None:
    """How far from the take-off point (horizontally) the flight ended, if it landed."""
    if not rows or rows[-1].phase != Phase.LANDED:
        return None
    north, east, _alt = judged_position(rows[-1])
    return math.hypot(north, east) if math.isfinite(north) else None


def judged_alt_m(row: FlightRow) -> float:
    """The simulated truth, or the FC's altitude when the physics is external (Gazebo)."""
    return row.sim_alt_m if math.isfinite(row.sim_alt_m) else row.fc_alt_m


def hold_stats(rows: list[FlightRow]) -> HoldStats | None:
    errors = [judged_alt_m(r) - r.target_alt_m for r in rows if r.phase == Phase.HOLD]
    if not errors:
        return None
    return HoldStats(
        rms_error_m=math.sqrt(sum(e * e for e in errors) / len(errors)),
        max_abs_error_m=max(abs(e) for e in errors),
        mean_error_m=sum(errors) / len(errors),
        samples=len(errors),
    )


def takeoff_metrics(rows: list[FlightRow], target_alt_m: float) -> Any:
    """Step-response figures of the take-off and hold, from the simulated truth."""
    from bfsitl.control.metrics import step_response

    flown = []
    for row in rows:  # the take-off and the hold after it, up to whatever comes next
        if row.phase in (Phase.TAKEOFF, Phase.HOLD):
            flown.append(row)
        elif flown:
            break
    if len(flown) < 10:
        return None
    return step_response(
        [r.time_s for r in flown],
        [judged_alt_m(r) for r in flown],
        target_m=target_alt_m,
        start_m=0.0,
        roll_deg=[r.roll_deg for r in flown],
        pitch_deg=[r.pitch_deg for r in flown],
    )
