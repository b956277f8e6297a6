"""Legs between waypoints: the moving reference a leg is flown along, and how a leg went.

A leg is flown by following a point that travels from the leg's start to its end with a
trapezoidal speed profile (accelerate at ``accel_m_s2``, cruise at ``speed_m_s``, brake to a
stop at the end), not by steering at the end point: steering at a point flies a curve in
wind and arrives at full speed; a travelling reference keeps the vehicle on the line and
brings it in slowly.  The altitude target moves with it, in proportion.

The judgement is geometric and works on any rows: the arrival error is the distance from
the waypoint where the leg was declared reached, the cross-track error the distance from
the straight line between the leg's ends.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from bfsitl.errors import MissionError

#: Acceleration of the travelling reference: about 6 degrees of tilt, gentle next to gusts.
DEFAULT_LEG_ACCEL_M_S2 = 1.0


@dataclass(frozen=True, slots=True)
class LegPoint:
    """Where the reference is at one instant, and how fast it moves (north/east/up)."""

    north_m: float
    east_m: float
    alt_m: float
    v_north_m_s: float
    v_east_m_s: float
    a_north_m_s2: float
    a_east_m_s2: float
    finished: bool  # the reference has stopped at the leg's end


class LegReference:
    """The travelling reference of one leg, as a function of the time since it began."""

    def __init__(
        self,
        start: tuple[float, float, float],
        end: tuple[float, float, float],
        speed_m_s: float,
        accel_m_s2: float = DEFAULT_LEG_ACCEL_M_S2,
    ) -> None:
        if not (math.isfinite(speed_m_s) and 0.0 < speed_m_s <= 20.0):
            raise MissionError(f"leg speed {speed_m_s} m/s is outside 0..20 m/s")
        if not (math.isfinite(accel_m_s2) and accel_m_s2 > 0.0):
            raise MissionError(f"leg acceleration {accel_m_s2} m/s^2 must be > 0")
        self.start, self.end = start, end
        self.length_m = math.hypot(end[0] - start[0], end[1] - start[1])
        self._accel = accel_m_s2
        # Too short to reach the cruise speed: a triangle, peaking half way.
        self._peak_m_s = min(speed_m_s, math.sqrt(self.length_m * accel_m_s2))
        ramp_s = self._peak_m_s / accel_m_s2
        ramp_m = 0.5 * accel_m_s2 * ramp_s * ramp_s
        cruise_s = (self.length_m - 2 * ramp_m) / self._peak_m_s if self._peak_m_s > 0 else 0.0
        self._ramp_s, self._ramp_m, self._cruise_s = ramp_s, ramp_m, max(0.0, cruise_s)
        self.duration_s = 2 * ramp_s + self._cruise_s

    @property
    def peak_speed_m_s(self) -> float:
        """The fastest the reference goes: the speed asked, or less on a leg too short to
        reach it before braking (the square root of length times acceleration)."""
        return self._peak_m_s

    def at(self, elapsed_s: float) -> LegPoint:
        t = max(0.0, elapsed_s)
        a, peak, ramp_s = self._accel, self._peak_m_s, self._ramp_s
        if t >= self.duration_s:
            along_m, speed, accel = self.length_m, 0.0, 0.0
        elif t < ramp_s:
            along_m, speed, accel = 0.5 * a * t * t, a * t, a
        elif t < ramp_s + self._cruise_s:
            along_m, speed, accel = self._ramp_m + peak * (t - ramp_s), peak, 0.0
        else:
            left_s = self.duration_s - t
            along_m, speed, accel = self.length_m - 0.5 * a * left_s * left_s, a * left_s, -a
        share = along_m / self.length_m if self.length_m > 0 else 1.0
        (n0, e0, h0), (n1, e1, h1) = self.start, self.end
        un, ue = (
            ((n1 - n0) / self.length_m, (e1 - e0) / self.length_m)
            if self.length_m > 0
            else (0.0, 0.0)
        )
        return LegPoint(
            n0 + (n1 - n0) * share,
            e0 + (e1 - e0) * share,
            h0 + (h1 - h0) * share,
            un * speed,
            ue * speed,
            un * accel,
            ue * accel,
            t >= self.duration_s,
        )


def cross_track_m(
    north_m: float, east_m: float, start: tuple[float, float], end: tuple[float, float]
) -> float:
    """Distance from the track: the line through ``start`` and ``end``, perpendicular to it
    (running past the end is along the track, not across it).  A leg of no length has no
    direction: the distance from its point."""
    dn, de = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dn, de)
    if length == 0.0:
        return math.hypot(north_m - start[0], east_m - start[1])
    return abs((north_m - start[0]) * de - (east_m - start[1]) * dn) / length


@dataclass(frozen=True, slots=True)
class LegStats:
    """How one leg went, judged on the simulated truth (the FC's GPS where there is none)."""

    waypoint: int  # 1-based, in the order flown
    target_north_m: float
    target_east_m: float
    target_alt_m: float
    took_s: float  # simulation time from the leg's start to "reached"
    arrival_error_m: float  # horizontal distance from the waypoint when reached
    arrival_alt_error_m: float  # height minus the waypoint's altitude then
    cross_track_rms_m: float  # distance from the straight line, over the leg
    cross_track_max_m: float
    overshoot_m: float  # furthest past the waypoint along the track
    samples: int


def leg_stats(
    waypoint: int,
    start: tuple[float, float],
    end: tuple[float, float, float],
    positions: Sequence[tuple[float, float, float]],
    took_s: float,
) -> LegStats:
    """``positions``: (north, east, altitude) of every step of the leg, the last at arrival."""
    if not positions:
        raise MissionError(f"leg {waypoint} has no samples to judge")
    off = [cross_track_m(n, e, start, (end[0], end[1])) for n, e, _h in positions]
    dn, de = end[0] - start[0], end[1] - start[1]
    length = math.hypot(dn, de)
    beyond = (
        [((n - end[0]) * dn + (e - end[1]) * de) / length for n, e, _h in positions]
        if length > 0
        else [0.0]
    )
    last_n, last_e, last_h = positions[-1]
    return LegStats(
        waypoint,
        end[0],
        end[1],
        end[2],
        took_s,
        arrival_error_m=math.hypot(last_n - end[0], last_e - end[1]),
        arrival_alt_error_m=last_h - end[2],
        cross_track_rms_m=math.sqrt(sum(x * x for x in off) / len(off)),
        cross_track_max_m=max(off),
        overshoot_m=max(0.0, max(beyond)),
        samples=len(off),
    )
