"""The analysers of the ground: ``crash``, ``hard_landing`` and ``fly_away`` (the table in
:mod:`bfsitl.analysis.analysers`), and the touchdowns they read."""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable
from dataclasses import dataclass

from bfsitl.analysis.findings import Finding, Severity
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.series import (
    descent_before,
    evidence_of,
    finite,
    require,
)
from bfsitl.analysis.track import Track, TrackPoint
from bfsitl.errors import TrackDataMissingError

#: A log's disarm reasons that mean the FC itself saw a crash or a runaway.
CRASH_DISARM_REASONS = ("CRASH_PROTECTION", "RUNAWAY_TAKEOFF")


@dataclass(frozen=True, slots=True)
class Touchdown:
    """A ground contact after flight."""

    index: int
    time_s: float
    speed_m_s: float  # downward, at contact (the fastest in the 0.3 s before)
    tilt_deg: float  # the most in the 0.3 s before and 0.5 s after
    rest_tilt_deg: float  # at the end of the stretch on the ground
    from_alt_m: float  # the highest in the 10 s before


def touchdowns(track: Track) -> list[Touchdown]:
    points = track.points
    found = []
    for index in range(1, len(points)):
        if not (points[index - 1].airborne and points[index].airborne is False):
            continue
        t = points[index].time_s
        before = [p for p in points[max(0, index - 60) : index + 1] if t - 0.3 <= p.time_s <= t]
        around = [
            p for p in points[max(0, index - 60) : index + 60] if t - 0.3 <= p.time_s <= t + 0.5
        ]
        ground_end = index
        while ground_end + 1 < len(points) and points[ground_end + 1].airborne is False:
            ground_end += 1
        earlier = [p.alt_m for p in points[: index + 1] if t - 10.0 <= p.time_s and finite(p.alt_m)]
        found.append(
            Touchdown(
                index,
                t,
                max((-p.climb_m_s for p in before if finite(p.climb_m_s)), default=0.0),
                max((p.tilt_deg for p in around if finite(p.tilt_deg)), default=math.nan),
                points[ground_end].tilt_deg,
                max(earlier, default=math.nan),
            )
        )
    return found


def _contact_evidence(touch: Touchdown, track: Track) -> dict[str, object]:
    point = track.points[touch.index]
    return {
        "touchdown_speed_m_s": touch.speed_m_s,
        "tilt_at_contact_deg": touch.tilt_deg,
        "tilt_at_rest_deg": touch.rest_tilt_deg,
        "fell_from_m": touch.from_alt_m,
        "distance_from_home_m": point.distance_m,
        "sample": evidence_of(point),
    }


def crash(track: Track, limits: Limits) -> Finding | None:
    if track.source == "blackbox":
        return _crash_in_log(track)
    require(track, "airborne", "climb_m_s")
    contacts = touchdowns(track)
    crashes = [
        t
        for t in contacts
        if t.speed_m_s >= limits.crash_speed_m_s
        or (finite(t.tilt_deg) and t.tilt_deg >= limits.tipped_over_deg)
        or (finite(t.rest_tilt_deg) and t.rest_tilt_deg >= limits.tipped_over_deg)
    ]
    if not crashes:
        return None
    worst = max(crashes, key=lambda t: (t.speed_m_s, t.rest_tilt_deg))
    how = [f"hit the ground at {worst.speed_m_s:.1f} m/s"]
    if finite(worst.rest_tilt_deg) and worst.rest_tilt_deg >= limits.tipped_over_deg:
        how.append(
            "upside down"
            if worst.rest_tilt_deg >= limits.upside_down_deg
            else f"on its side ({worst.rest_tilt_deg:.0f} deg)"
        )
    elif finite(worst.tilt_deg):
        how.append(f"tilted {worst.tilt_deg:.0f} deg")
    if finite(worst.from_alt_m):
        how.append(f"from {worst.from_alt_m:.1f} m")
    evidence = _contact_evidence(worst, track)
    evidence["crashes"] = len(crashes)
    return Finding(
        "crash",
        Severity.FAILURE,
        ", ".join(how),
        worst.time_s,
        worst.speed_m_s,
        "m/s",
        evidence,
        track.source,
    )


def _crash_in_log(track: Track) -> Finding | None:
    if track.disarm_reason is None:
        raise TrackDataMissingError("the log has no disarm reason (it was cut)")
    if track.disarm_reason not in CRASH_DISARM_REASONS:
        return None
    last = track.points[-1] if track.points else TrackPoint(0.0, True)
    return Finding(
        "crash",
        Severity.FAILURE,
        f"the FC disarmed itself: {track.disarm_reason}",
        last.time_s,
        math.nan,
        "",
        {"disarm_reason": track.disarm_reason, "sample": evidence_of(last)},
        track.source,
    )


def _thrust_explained_g(track: Track) -> Callable[[TrackPoint], float]:
    """What the motors explain of the accelerometer: the log's own median reading at each
    level of the mean motor command (bins of 5 %).  A quad's thrust-to-weight ratio is in
    it without being known: a punch-out's 6 g sits in its own bin."""

    def level(point: TrackPoint) -> int:
        return min(19, int(20 * sum(point.motors) / len(point.motors)))

    bins: dict[int, list[float]] = {}
    for p in track.points:
        if p.motors and finite(p.accel_g):
            bins.setdefault(level(p), []).append(p.accel_g)
    medians = {key: statistics.median(values) for key, values in bins.items()}

    def explained(point: TrackPoint) -> float:
        return medians.get(level(point), 1.0) if point.motors else 1.0

    return explained


def _flight_ended_at(track: Track, index: int, within_s: float) -> bool:
    """Whether the flight ended at the point: within ``within_s`` the vehicle comes to rest
    (1 g, the gyro quiet, the motors low, for 0.2 s) or the log ends, before it is seen
    flying on (0.15 s of controlled thrust: over 1.2 g with the motors up and the gyro near
    its setpoint) or falling freely (under 0.3 g)."""
    points = track.points
    start_s = points[index].time_s
    since: dict[str, float | None] = {"rest": None, "flying": None, "falling": None}
    needed_s = {"rest": 0.2, "flying": 0.15, "falling": 0.15}
    for p in points[index + 1 :]:
        if p.time_s - start_s > within_s:
            return False
        mean_motor = sum(p.motors) / len(p.motors) if p.motors else math.nan
        off_setpoint = max(
            (abs(g - s) for g, s in zip(p.gyro_deg_s, p.setpoint_deg_s, strict=False)),
            default=0.0,
        )
        states = {
            "rest": finite(p.accel_g)
            and abs(p.accel_g - 1.0) < 0.25
            and all(abs(g) < 50.0 for g in p.gyro_deg_s)
            and not mean_motor >= 0.3,
            "flying": finite(p.accel_g)
            and p.accel_g > 1.2
            and mean_motor >= 0.25
            and off_setpoint < 200.0,
            "falling": finite(p.accel_g) and p.accel_g < 0.3,
        }
        for state, now in states.items():
            if not now:
                since[state] = None
                continue
            began = since[state]
            if began is None:
                since[state] = p.time_s
            elif p.time_s - began >= needed_s[state]:
                return state == "rest"
    return True  # the log ended first: cut by the impact


def _impact_in_log(track: Track, limits: Limits) -> Finding | None:
    """A log's hardest landing: a peak of the accelerometer the motors do not explain, after
    a descent at landing speed (with a barometer) or that ends the flight (without one)."""
    require(track, "accel_g")
    explained = _thrust_explained_g(track)
    candidates = [
        (p.accel_g - explained(p), i, p)
        for i, p in enumerate(track.points)
        if finite(p.accel_g) and p.accel_g >= limits.impact_g
    ]
    impacts = []
    for beyond_g, index, point in candidates:
        if beyond_g < limits.impact_over_thrust_g:
            continue
        descent = descent_before(track, index)
        if finite(descent):
            # With a barometer the descent before the peak decides (a simulator's rigid
            # ground gives 4-5 g at 0.8 m/s, no landing speed).
            if descent >= limits.hard_landing_speed_m_s:
                impacts.append((beyond_g, point, descent))
        elif _flight_ended_at(track, index, limits.landing_rest_within_s):
            impacts.append((beyond_g, point, descent))
    if not impacts:
        return None
    beyond_g, peak, descent = max(impacts, key=lambda c: c[1].accel_g)
    speed = f", after descending at {descent:.1f} m/s (barometer)" if finite(descent) else ""
    return Finding(
        "hard_landing",
        Severity.WARNING,
        f"an impact of {peak.accel_g:.1f} g on the accelerometer, {beyond_g:.1f} g more "
        f"than the motors push{speed}",
        peak.time_s,
        peak.accel_g,
        "g",
        {"baro_descent_m_s": descent, "beyond_thrust_g": beyond_g, "sample": evidence_of(peak)},
        track.source,
    )


def hard_landing(track: Track, limits: Limits) -> Finding | None:
    if track.source == "blackbox":
        return _impact_in_log(track, limits)
    require(track, "airborne", "climb_m_s")
    hard = [
        t
        for t in touchdowns(track)
        if limits.hard_landing_speed_m_s <= t.speed_m_s < limits.crash_speed_m_s
    ]
    if not hard:
        return None
    worst = max(hard, key=lambda t: t.speed_m_s)
    evidence = _contact_evidence(worst, track)
    evidence["hard_landings"] = len(hard)
    return Finding(
        "hard_landing",
        Severity.WARNING,
        f"touched down at {worst.speed_m_s:.1f} m/s",
        worst.time_s,
        worst.speed_m_s,
        "m/s",
        evidence,
        track.source,
    )


# -- where it went ---------------------------------------------------------------------------
def fly_away(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m")
    reach = max(
        (
            math.hypot(p.target_north_m, p.target_east_m)
            for p in track.points
            if finite(p.target_north_m) and finite(p.target_east_m)
        ),
        default=track.planned_reach_m,
    )
    reach = max(reach, track.planned_reach_m)
    bound = reach + limits.fly_away_margin_m
    placed = [p for p in track.points if finite(p.north_m)]
    beyond = [p for p in placed if p.distance_m > bound]
    if not beyond:
        return None
    farthest = max(beyond, key=lambda p: p.distance_m)
    first, last = beyond[0], placed[-1]
    recent = [p for p in placed if p.time_s >= last.time_s - 2.0]
    leaving = last.distance_m > bound and last.distance_m - recent[0].distance_m > 0.5
    # Gone (still beyond the bound and going) is a failure; out and back again a warning.
    severity = Severity.FAILURE if leaving else Severity.WARNING
    end = (
        f"still going at the end ({last.distance_m:.0f} m)"
        if leaving
        else f"{last.distance_m:.0f} m at the end"
    )
    return Finding(
        "fly_away",
        severity,
        f"{farthest.distance_m:.0f} m from home, past the farthest target "
        f"({reach:.0f} m) + {limits.fly_away_margin_m:.0f} m from "
        f"t={first.time_s:.1f} s; {end}",
        first.time_s,
        farthest.distance_m,
        "m",
        {
            "farthest_target_m": reach,
            "bound_m": bound,
            "farthest_m": farthest.distance_m,
            "farthest_at_s": farthest.time_s,
            "final_distance_m": last.distance_m,
            "still_leaving": leaving,
            "sample": evidence_of(farthest),
        },
        track.source,
    )


# -- attitude --------------------------------------------------------------------------------
