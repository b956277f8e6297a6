"""The analysers that watch every flight: each looks for one way a flight goes wrong and
gives at most one :class:`~bfsitl.analysis.findings.Finding` (its worst instance, with how
often it happened), whether or not anything asked.

=====================  ===========================================  =====================
analyser               what it looks for                            reads
=====================  ===========================================  =====================
``crash``              ground contact at >= 3 m/s, or tipped over   the truth; a log's
                       (>= 60 deg) on the ground                    disarm reason
``hard_landing``       ground contact at 1.5-3 m/s; a log's         the truth; a log's
                       accelerometer peak >= 3 g                    accelerometer
``fly_away``           farther from home than the farthest target   the truth
                       plus 25 m
``loss_of_control``    upside down in the air (failure), tilted     the truth or the FC's
                       past 75 deg (warning); the gyro 200 deg/s    attitude; a log's gyro
                       off its setpoint for 0.25 s                  and setpoint
``oscillation``        the attitude (or the gyro's error) swinging  the truth; a log's
                       back and forth, sustained                    gyro and setpoint
``motor_saturation``   a motor at >= 98 % for 0.25 s or more        the motors
``failsafe``           the FC's failsafe left IDLE: its phases,     the failsafe phase
                       when                                         (or FAILSAFE mode)
``gps_glitch``         the FC's GPS >= 10 m off the truth, and how  the truth and the FC's
                       far the vehicle moved while it was           GPS
``altitude_excursion`` height off the held target by >= 2 m         the truth, targets
``position_excursion`` position off the held target by >= 3 m      the truth, targets
``altitude_estimate``  the FC's altitude off the truth by >= 2 m    the truth, the FC's
=====================  ===========================================  =====================

The thresholds are :class:`~bfsitl.analysis.limits.Limits`; what each is set from is said
there.  An analyser a track has no data for is listed as skipped with the reason, never judged
on nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from bfsitl.analysis.findings import Finding, Severity
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.series import (
    descent_before,
    evidence_of,
    finite,
    held_points,
    require,
    runs,
    span_s,
    sustained_swing,
    window_means,
)
from bfsitl.analysis.track import Track, TrackPoint
from bfsitl.errors import TrackDataMissingError
from bfsitl.protocol.failsafe_phase import FailsafePhase

#: A log's disarm reasons that mean the FC itself saw a crash or a runaway.
CRASH_DISARM_REASONS = ("CRASH_PROTECTION", "RUNAWAY_TAKEOFF")


@dataclass(frozen=True, slots=True)
class Analyser:
    name: str
    #: What it looks for, one line (``bfsitl log check --list``).
    what: str
    #: (track, limits) -> its finding, or None when the track shows nothing; raises
    #: :class:`TrackDataMissingError` when the track lacks what it reads.
    run: Callable[[Track, Limits], Finding | None]


@dataclass(slots=True)
class Analysis:
    """The analysers' results on one track."""

    findings: list[Finding] = field(default_factory=list)
    #: The analysers that ran, in order.
    watched: list[str] = field(default_factory=list)
    #: Analyser -> why it could not run on this track.
    skipped: dict[str, str] = field(default_factory=dict)


# -- ground contact --------------------------------------------------------------------------
@dataclass(frozen=True, slots=True)
class Touchdown:
    """A ground contact after flight."""

    index: int
    time_s: float
    speed_m_s: float      # downward, at contact (the fastest in the 0.3 s before)
    tilt_deg: float       # the most in the 0.3 s before and 0.5 s after
    rest_tilt_deg: float  # at the end of the stretch on the ground
    from_alt_m: float     # the highest in the 10 s before


def touchdowns(track: Track) -> list[Touchdown]:
    points = track.points
    found = []
    for index in range(1, len(points)):
        if not (points[index - 1].airborne and points[index].airborne is False):
            continue
        t = points[index].time_s
        before = [p for p in points[max(0, index - 60):index + 1] if t - 0.3 <= p.time_s <= t]
        around = [p for p in points[max(0, index - 60):index + 60]
                  if t - 0.3 <= p.time_s <= t + 0.5]
        ground_end = index
        while ground_end + 1 < len(points) and points[ground_end + 1].airborne is False:
            ground_end += 1
        earlier = [p.alt_m for p in points[:index + 1] if t - 10.0 <= p.time_s
                   and finite(p.alt_m)]
        found.append(Touchdown(
            index, t, max((-p.climb_m_s for p in before if finite(p.climb_m_s)), default=0.0),
            max((p.tilt_deg for p in around if finite(p.tilt_deg)), default=math.nan),
            points[ground_end].tilt_deg, max(earlier, default=math.nan)))
    return found


def _contact_evidence(touch: Touchdown, track: Track) -> dict[str, object]:
    point = track.points[touch.index]
    return {"touchdown_speed_m_s": touch.speed_m_s, "tilt_at_contact_deg": touch.tilt_deg,
            "tilt_at_rest_deg": touch.rest_tilt_deg, "fell_from_m": touch.from_alt_m,
            "distance_from_home_m": point.distance_m, "sample": evidence_of(point)}


def crash(track: Track, limits: Limits) -> Finding | None:
    if track.source == "blackbox":
        return _crash_in_log(track)
    require(track, "airborne", "climb_m_s")
    contacts = touchdowns(track)
    crashes = [t for t in contacts
               if t.speed_m_s >= limits.crash_speed_m_s
               or (finite(t.tilt_deg) and t.tilt_deg >= limits.tipped_over_deg)
               or (finite(t.rest_tilt_deg) and t.rest_tilt_deg >= limits.tipped_over_deg)]
    if not crashes:
        return None
    worst = max(crashes, key=lambda t: (t.speed_m_s, t.rest_tilt_deg))
    how = [f"hit the ground at {worst.speed_m_s:.1f} m/s"]
    if finite(worst.rest_tilt_deg) and worst.rest_tilt_deg >= limits.tipped_over_deg:
        how.append("upside down" if worst.rest_tilt_deg >= limits.upside_down_deg
                   else f"on its side ({worst.rest_tilt_deg:.0f} deg)")
    elif finite(worst.tilt_deg):
        how.append(f"tilted {worst.tilt_deg:.0f} deg")
    if finite(worst.from_alt_m):
        how.append(f"from {worst.from_alt_m:.1f} m")
    evidence = _contact_evidence(worst, track)
    evidence["crashes"] = len(crashes)
    return Finding("crash", Severity.FAILURE, ", ".join(how), worst.time_s, worst.speed_m_s,
                   "m/s", evidence, track.source)


def _crash_in_log(track: Track) -> Finding | None:
    if track.disarm_reason is None:
        raise TrackDataMissingError("the log has no disarm reason (it was cut)")
    if track.disarm_reason not in CRASH_DISARM_REASONS:
        return None
    last = track.points[-1] if track.points else TrackPoint(0.0, True)
    return Finding("crash", Severity.FAILURE,
                   f"the FC disarmed itself: {track.disarm_reason}", last.time_s, math.nan, "",
                   {"disarm_reason": track.disarm_reason, "sample": evidence_of(last)},
                   track.source)


def hard_landing(track: Track, limits: Limits) -> Finding | None:
    if track.source == "blackbox":
        require(track, "accel_g")
        peak = max((p for p in track.points if finite(p.accel_g)), key=lambda p: p.accel_g)
        if peak.accel_g < limits.impact_g:
            return None
        descent = descent_before(track, peak.time_s)
        if finite(descent) and descent < limits.hard_landing_speed_m_s:
            # The peak alone is no landing speed (a simulator's rigid ground gives 4-5 g at
            # 0.8 m/s); with a barometer the descent before it decides.
            return None
        speed = f" after descending at {descent:.1f} m/s (barometer)" if finite(descent) \
            else ""
        return Finding("hard_landing", Severity.WARNING,
                       f"an impact of {peak.accel_g:.1f} g on the accelerometer{speed}",
                       peak.time_s, peak.accel_g, "g",
                       {"baro_descent_m_s": descent, "sample": evidence_of(peak)}, track.source)
    require(track, "airborne", "climb_m_s")
    hard = [t for t in touchdowns(track)
            if limits.hard_landing_speed_m_s <= t.speed_m_s < limits.crash_speed_m_s]
    if not hard:
        return None
    worst = max(hard, key=lambda t: t.speed_m_s)
    evidence = _contact_evidence(worst, track)
    evidence["hard_landings"] = len(hard)
    return Finding("hard_landing", Severity.WARNING,
                   f"touched down at {worst.speed_m_s:.1f} m/s", worst.time_s,
                   worst.speed_m_s, "m/s", evidence, track.source)


# -- where it went ---------------------------------------------------------------------------
def fly_away(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m")
    reach = max((math.hypot(p.target_north_m, p.target_east_m) for p in track.points
                 if finite(p.target_north_m) and finite(p.target_east_m)),
                default=track.planned_reach_m)
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
    end = (f"still going at the end ({last.distance_m:.0f} m)" if leaving
           else f"{last.distance_m:.0f} m at the end")
    return Finding("fly_away", severity,
                   f"{farthest.distance_m:.0f} m from home, past the farthest target "
                   f"({reach:.0f} m) + {limits.fly_away_margin_m:.0f} m from "
                   f"t={first.time_s:.1f} s; {end}", first.time_s, farthest.distance_m, "m",
                   {"farthest_target_m": reach, "bound_m": bound,
                    "farthest_m": farthest.distance_m, "farthest_at_s": farthest.time_s,
                    "final_distance_m": last.distance_m, "still_leaving": leaving,
                    "sample": evidence_of(farthest)}, track.source)


# -- attitude --------------------------------------------------------------------------------
def loss_of_control(track: Track, limits: Limits) -> Finding | None:
    points = track.points
    in_air = [p for p in points if p.armed and p.airborne is not False]
    findings: list[Finding] = []
    if track.has("tilt_deg"):
        inverted = [p for p in in_air if finite(p.tilt_deg)
                    and p.tilt_deg >= limits.upside_down_deg]
        if inverted:
            worst = max(inverted, key=lambda p: p.tilt_deg)
            findings.append(Finding(
                "loss_of_control", Severity.FAILURE,
                f"upside down in the air ({worst.tilt_deg:.0f} deg) from "
                f"t={inverted[0].time_s:.2f} s", inverted[0].time_s, worst.tilt_deg, "deg",
                {"max_tilt_deg": worst.tilt_deg, "first_s": inverted[0].time_s,
                 "sample": evidence_of(worst)}, track.source))
        else:
            for first, last in runs(in_air, lambda p: finite(p.tilt_deg)
                                     and p.tilt_deg >= limits.lost_attitude_deg):
                worst = max(in_air[first:last + 1], key=lambda p: p.tilt_deg)
                findings.append(Finding(
                    "loss_of_control", Severity.WARNING,
                    f"tilted {worst.tilt_deg:.0f} deg in the air, past the "
                    f"{limits.lost_attitude_deg:.0f} deg the FC commands at most",
                    in_air[first].time_s, worst.tilt_deg, "deg",
                    {"max_tilt_deg": worst.tilt_deg,
                     "lasted_s": span_s(in_air, first, last), "sample": evidence_of(worst)},
                    track.source))
    if track.has("gyro_deg_s") and track.has("setpoint_deg_s"):
        rated = [p for p in points if len(p.gyro_deg_s) >= 2 and len(p.setpoint_deg_s) >= 2]

        def error(p: TrackPoint) -> float:
            return 0.5 * (abs(p.gyro_deg_s[0] - p.setpoint_deg_s[0])
                          + abs(p.gyro_deg_s[1] - p.setpoint_deg_s[1]))

        worst_index, worst_mean = -1, 0.0
        for index, mean in window_means(rated, error, limits.rate_error_window_s):
            if mean > worst_mean:
                worst_index, worst_mean = index, mean
        if worst_mean >= limits.rate_error_deg_s:
            point = rated[worst_index]
            findings.append(Finding(
                "loss_of_control", Severity.FAILURE,
                f"the gyro {worst_mean:.0f} deg/s off the setpoint (roll and pitch, mean over "
                f"{limits.rate_error_window_s:g} s)", point.time_s, worst_mean, "deg/s",
                {"gyro_deg_s": list(point.gyro_deg_s), "setpoint_deg_s":
                 list(point.setpoint_deg_s), "sample": evidence_of(point)}, track.source))
    if not track.has("tilt_deg") and not track.has("gyro_deg_s"):
        raise TrackDataMissingError(f"the {track.source} track has no attitude and no gyro")
    return max(findings, key=lambda f: (f.severity, f.value), default=None)


def _rate_error(axis: int) -> Callable[[TrackPoint], float]:
    def error(p: TrackPoint) -> float:
        return p.gyro_deg_s[axis] - p.setpoint_deg_s[axis]
    return error


def _roll_split(p: TrackPoint) -> float:
    return (p.motors[2] + p.motors[3] - p.motors[0] - p.motors[1]) / 2


def _pitch_split(p: TrackPoint) -> float:
    return (p.motors[0] + p.motors[2] - p.motors[1] - p.motors[3]) / 2


def oscillation(track: Track, limits: Limits) -> Finding | None:
    if track.has("gyro_deg_s") and track.has("setpoint_deg_s"):
        points = [p for p in track.points if len(p.gyro_deg_s) >= 3
                  and len(p.setpoint_deg_s) >= 3]
        axes: list[tuple[str, Callable[[TrackPoint], float]]] = [
            (name, _rate_error(axis)) for axis, name in enumerate(("roll", "pitch", "yaw"))]
        swing = sustained_swing(points, axes, 0.5, limits.oscillation_rate_rms_deg_s,
                                limits.oscillation_min_rate_hz, limits.oscillation_windows)
        unit, what = "deg/s", "the gyro's error"
    else:
        # Betaflight's quad X: motor 1 rear right, 2 front right, 3 rear left, 4 front left;
        # the left pair against the right rolls, the rear pair against the front pitches.
        require(track, "motors")
        points = [p for p in track.points if p.armed and p.airborne is not False
                  and len(p.motors) == 4]
        axes = [("roll", _roll_split), ("pitch", _pitch_split)]
        swing = sustained_swing(points, axes, 1.0, limits.oscillation_motor_rms,
                                limits.oscillation_min_motor_hz, limits.oscillation_windows)
        unit, what = "of full", "the motors' split"
    if swing is None:
        return None
    axis, rms, hz, started_s, lasted_s = swing
    return Finding("oscillation", Severity.WARNING,
                   f"{axis}: {what} swings {rms:.1f} {unit} RMS at {hz:.1f} Hz for "
                   f"{lasted_s:.1f} s", started_s, rms, unit,
                   {"axis": axis, "rms": rms, "frequency_hz": hz, "lasted_s": lasted_s},
                   track.source)


# -- motors ----------------------------------------------------------------------------------
def motor_saturation(track: Track, limits: Limits) -> Finding | None:
    require(track, "motors")
    points = track.points

    def flying(p: TrackPoint) -> bool:
        return p.armed and bool(p.motors) and p.airborne is not False

    stretches = [(first, last, span_s(points, first, last)) for first, last in runs(
        points, lambda p: flying(p) and max(p.motors) >= limits.saturated_motor)]
    long_ones = [s for s in stretches if s[2] >= limits.saturation_min_s]
    if not long_ones:
        return None
    first, last, lasted = max(long_ones, key=lambda s: s[2])
    stretch = points[first:last + 1]
    motors = sorted({i + 1 for p in stretch for i, m in enumerate(p.motors)
                     if m >= limits.saturated_motor})
    total = sum(s[2] for s in stretches)
    armed_s = sum(span_s(points, a, b) for a, b in runs(points, flying)) or 1.0
    return Finding("motor_saturation", Severity.WARNING,
                   f"motor {', '.join(map(str, motors))} at full for {lasted:.2f} s "
                   f"({100 * total / armed_s:.0f} % of the time in the air)",
                   stretch[0].time_s, lasted, "s",
                   {"motors": motors, "longest_s": lasted, "total_s": total,
                    "share_of_flight": total / armed_s, "stretches": len(long_ones),
                    "sample": evidence_of(stretch[0])}, track.source)


# -- failsafe --------------------------------------------------------------------------------
def _phase_name(phase: int) -> str:
    try:
        return FailsafePhase(phase).name
    except ValueError:
        return f"PHASE_{phase}"  # a phase a newer firmware added


def failsafe(track: Track, limits: Limits) -> Finding | None:
    changes: list[tuple[float, str]] = []
    if track.has("failsafe_phase"):
        for point in track.points:
            if point.failsafe_phase is None:
                continue
            name = _phase_name(point.failsafe_phase)
            if not changes or changes[-1][1] != name:
                changes.append((point.time_s, name))
        lost = next((p.time_s for p in track.points if p.rx_ok is False), None)
        if lost is not None:
            # A log: phases that end in one pass (RX_LOSS_DETECTED, LANDED) never reach it;
            # the receiver's state and the disarm reason do.
            changes = sorted([*changes, (lost, "RX lost")])
        if track.disarm_reason == "FAILSAFE":
            changes.append((track.points[-1].time_s, "disarmed by the failsafe"))
        entered = [(t, name) for t, name in changes if name != "IDLE"]
    elif track.has("modes"):
        entered = [(point.time_s, "FAILSAFE mode") for point in track.points
                   if "FAILSAFE" in point.modes][:1]
        changes = entered
    else:
        raise TrackDataMissingError(f"the {track.source} track has no failsafe phase and no modes")
    if not entered:
        return None
    first_s = entered[0][0]
    sequence = " -> ".join(f"{name} at {t:.2f} s" for t, name in changes if t >= first_s)
    evidence: dict[str, object] = {"phases": [[name, t] for t, name in changes],
                                   "entered_s": first_s}
    for t, name in entered:
        evidence.setdefault(f"to_{name.lower().replace(' ', '_')}_s", round(t - first_s, 4))
    if track.disarm_reason:
        evidence["disarm_reason"] = track.disarm_reason
    return Finding("failsafe", Severity.INFO, f"failsafe: {sequence}", first_s,
                   float(len(entered)), "phases", evidence, track.source)


# -- the GPS and the estimate ------------------------------------------------------------------
def gps_glitch(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m", "fc_north_m")
    known = [p for p in track.points if finite(p.fc_north_m) and finite(p.north_m)]

    def off(p: TrackPoint) -> float:
        return math.hypot(p.fc_north_m - p.north_m, p.fc_east_m - p.east_m)

    episodes = []
    for first, last in runs(known, lambda p: off(p) >= limits.gps_glitch_m):
        onset = known[first]
        moved = max(math.hypot(p.north_m - onset.north_m, p.east_m - onset.east_m)
                    for p in known[first:last + 1])
        episodes.append((moved, first, last))
    if not episodes:
        return None
    moved, first, last = max(episodes)
    onset = known[first]
    error = max(off(p) for p in known[first:last + 1])
    followed = moved >= limits.gps_followed_m
    return Finding("gps_glitch", Severity.WARNING if followed else Severity.INFO,
                   f"the FC's GPS {error:.0f} m off the truth for "
                   f"{span_s(known, first, last):.1f} s; the vehicle "
                   + (f"followed it {moved:.1f} m" if followed else
                      f"held within {moved:.1f} m"), onset.time_s, moved, "m",
                   {"gps_error_m": error, "moved_m": moved,
                    "lasted_s": span_s(known, first, last), "glitches": len(episodes),
                    "sample": evidence_of(onset)}, track.source)


def _graded(value: float, bounds: tuple[float, float]) -> Severity | None:
    if value >= bounds[1]:
        return Severity.FAILURE
    if value >= bounds[0]:
        return Severity.WARNING
    return None


def _worst_graded(points: list[TrackPoint], off: Callable[[TrackPoint], float],
                  bounds: tuple[float, float]) -> tuple[TrackPoint, float, Severity] | None:
    """The point farthest off, how far, and its grade; None when none reaches a bound."""
    if not points:
        return None
    worst = max(points, key=off)
    severity = _graded(off(worst), bounds)
    return None if severity is None else (worst, off(worst), severity)


def altitude_excursion(track: Track, limits: Limits) -> Finding | None:
    require(track, "alt_m", "target_alt_m", "phase")
    held = [p for p in held_points(track, limits.hold_settle_s)
            if finite(p.target_alt_m) and finite(p.alt_m)]
    graded = _worst_graded(held, lambda p: abs(p.alt_m - p.target_alt_m),
                           limits.altitude_excursion_m)
    if graded is None:
        return None
    worst, error, severity = graded
    return Finding("altitude_excursion", severity,
                   f"{error:.1f} m {'above' if worst.alt_m > worst.target_alt_m else 'below'} "
                   f"the held {worst.target_alt_m:.1f} m", worst.time_s, error, "m",
                   {"target_alt_m": worst.target_alt_m, "sample": evidence_of(worst)},
                   track.source)


def position_excursion(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m", "target_north_m", "phase")
    held = [p for p in held_points(track, limits.hold_settle_s) if finite(p.target_north_m)
            and finite(p.north_m)]
    graded = _worst_graded(held, lambda p: math.hypot(p.north_m - p.target_north_m,
                                                      p.east_m - p.target_east_m),
                           limits.position_excursion_m)
    if graded is None:
        return None
    worst, off, severity = graded
    return Finding("position_excursion", severity, f"{off:.1f} m off the held position",
                   worst.time_s, off, "m",
                   {"target_north_m": worst.target_north_m,
                    "target_east_m": worst.target_east_m, "sample": evidence_of(worst)},
                   track.source)


def altitude_estimate(track: Track, limits: Limits) -> Finding | None:
    require(track, "alt_m", "fc_alt_m", "airborne")
    flying = [p for p in track.points if p.armed and p.airborne and finite(p.fc_alt_m)
              and finite(p.alt_m)]
    graded = _worst_graded(flying, lambda p: abs(p.fc_alt_m - p.alt_m),
                           limits.altitude_estimate_m)
    if graded is None:
        return None
    worst, error, severity = graded
    return Finding("altitude_estimate", severity,
                   f"the FC's altitude {error:.1f} m off the truth ({worst.fc_alt_m:.1f} m "
                   f"against {worst.alt_m:.1f} m)", worst.time_s, error, "m",
                   {"fc_alt_m": worst.fc_alt_m, "sample": evidence_of(worst)}, track.source)


ANALYSERS: tuple[Analyser, ...] = (
    Analyser("crash", "ground contact at crash speed, or tipped over", crash),
    Analyser("hard_landing", "ground contact faster than a landing", hard_landing),
    Analyser("fly_away", "beyond the farthest target plus a margin", fly_away),
    Analyser("loss_of_control", "upside down, tilted past any command, gyro off its setpoint",
             loss_of_control),
    Analyser("oscillation", "attitude or gyro error swinging, sustained", oscillation),
    Analyser("motor_saturation", "a motor at full, sustained", motor_saturation),
    Analyser("failsafe", "the failsafe's phases and when", failsafe),
    Analyser("gps_glitch", "the FC's GPS off the truth, and the vehicle's response",
             gps_glitch),
    Analyser("altitude_excursion", "height off the held target", altitude_excursion),
    Analyser("position_excursion", "position off the held target", position_excursion),
    Analyser("altitude_estimate", "the FC's altitude off the truth", altitude_estimate),
)


def analyse(track: Track, limits: Limits | None = None) -> Analysis:
    """Every analyser on ``track``: its findings, worst first, and what ran."""
    limits = limits or Limits()
    result = Analysis()
    if not track.points:
        result.skipped = {a.name: f"the {track.source} track is empty" for a in ANALYSERS}
        return result
    for analyser in ANALYSERS:
        try:
            finding = analyser.run(track, limits)
        except TrackDataMissingError as why:
            result.skipped[analyser.name] = str(why)
            continue
        result.watched.append(analyser.name)
        if finding is not None:
            result.findings.append(finding)
    result.findings.sort(key=lambda f: (-f.severity, f.time_s))
    return result
