"""The analysers of control in the air: ``loss_of_control``, ``oscillation``,
``motor_saturation``, ``failsafe`` and ``gps_glitch`` (the table in
:mod:`bfsitl.analysis.analysers`)."""

from __future__ import annotations

import math
from collections.abc import Callable

from bfsitl.analysis.findings import Finding, Severity
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.series import (
    evidence_of,
    finite,
    require,
    runs,
    span_s,
    sustained_swing,
    window_means,
)
from bfsitl.analysis.track import Track, TrackPoint
from bfsitl.errors import TrackDataMissingError
from bfsitl.protocol.failsafe_phase import FailsafePhase


def loss_of_control(track: Track, limits: Limits) -> Finding | None:
    points = track.points
    in_air = [p for p in points if p.armed and p.airborne is not False]
    # A tilt is a loss of control only where the FC levels the quad: in acro a pilot flips
    # it on purpose (a freestyle flight's roll), and the gyro against its setpoint says
    # whether the FC kept control.
    levelled = [p for p in in_air if p.self_levelling is not False]
    findings: list[Finding] = []
    if track.has("tilt_deg"):
        inverted = [
            p for p in levelled if finite(p.tilt_deg) and p.tilt_deg >= limits.upside_down_deg
        ]
        if inverted:
            worst = max(inverted, key=lambda p: p.tilt_deg)
            findings.append(
                Finding(
                    "loss_of_control",
                    Severity.FAILURE,
                    f"upside down in the air ({worst.tilt_deg:.0f} deg) from "
                    f"t={inverted[0].time_s:.2f} s",
                    inverted[0].time_s,
                    worst.tilt_deg,
                    "deg",
                    {
                        "max_tilt_deg": worst.tilt_deg,
                        "first_s": inverted[0].time_s,
                        "sample": evidence_of(worst),
                    },
                    track.source,
                )
            )
        else:
            for first, last in runs(
                levelled, lambda p: finite(p.tilt_deg) and p.tilt_deg >= limits.lost_attitude_deg
            ):
                worst = max(levelled[first : last + 1], key=lambda p: p.tilt_deg)
                findings.append(
                    Finding(
                        "loss_of_control",
                        Severity.WARNING,
                        f"tilted {worst.tilt_deg:.0f} deg in the air, past the "
                        f"{limits.lost_attitude_deg:.0f} deg the FC commands at most",
                        levelled[first].time_s,
                        worst.tilt_deg,
                        "deg",
                        {
                            "max_tilt_deg": worst.tilt_deg,
                            "lasted_s": span_s(levelled, first, last),
                            "sample": evidence_of(worst),
                        },
                        track.source,
                    )
                )
    if track.has("gyro_deg_s") and track.has("setpoint_deg_s"):
        rated = [p for p in points if len(p.gyro_deg_s) >= 2 and len(p.setpoint_deg_s) >= 2]

        def error(p: TrackPoint) -> float:
            return 0.5 * (
                abs(p.gyro_deg_s[0] - p.setpoint_deg_s[0])
                + abs(p.gyro_deg_s[1] - p.setpoint_deg_s[1])
            )

        worst_index, worst_mean = -1, 0.0
        for index, mean in window_means(rated, error, limits.rate_error_window_s):
            if mean > worst_mean:
                worst_index, worst_mean = index, mean
        if worst_mean >= limits.rate_error_deg_s:
            point = rated[worst_index]
            findings.append(
                Finding(
                    "loss_of_control",
                    Severity.FAILURE,
                    f"the gyro {worst_mean:.0f} deg/s off the setpoint (roll and pitch, mean over "
                    f"{limits.rate_error_window_s:g} s)",
                    point.time_s,
                    worst_mean,
                    "deg/s",
                    {
                        "gyro_deg_s": list(point.gyro_deg_s),
                        "setpoint_deg_s": list(point.setpoint_deg_s),
                        "sample": evidence_of(point),
                    },
                    track.source,
                )
            )
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
        points = [p for p in track.points if len(p.gyro_deg_s) >= 3 and len(p.setpoint_deg_s) >= 3]
        axes: list[tuple[str, Callable[[TrackPoint], float]]] = [
            (name, _rate_error(axis)) for axis, name in enumerate(("roll", "pitch", "yaw"))
        ]
        swing = sustained_swing(
            points,
            axes,
            0.5,
            limits.oscillation_rate_rms_deg_s,
            limits.oscillation_min_rate_hz,
            limits.oscillation_windows,
        )
        unit, what = "deg/s", "the gyro's error"
    else:
        # Betaflight's quad X: motor 1 rear right, 2 front right, 3 rear left, 4 front left;
        # the left pair against the right rolls, the rear pair against the front pitches.
        require(track, "motors")
        points = [
            p for p in track.points if p.armed and p.airborne is not False and len(p.motors) == 4
        ]
        axes = [("roll", _roll_split), ("pitch", _pitch_split)]
        swing = sustained_swing(
            points,
            axes,
            1.0,
            limits.oscillation_motor_rms,
            limits.oscillation_min_motor_hz,
            limits.oscillation_windows,
        )
        unit, what = "of full", "the motors' split"
    if swing is None:
        return None
    axis, rms, hz, started_s, lasted_s = swing
    return Finding(
        "oscillation",
        Severity.WARNING,
        f"{axis}: {what} swings {rms:.1f} {unit} RMS at {hz:.1f} Hz for {lasted_s:.1f} s",
        started_s,
        rms,
        unit,
        {"axis": axis, "rms": rms, "frequency_hz": hz, "lasted_s": lasted_s},
        track.source,
    )


# -- motors ----------------------------------------------------------------------------------
def motor_saturation(track: Track, limits: Limits) -> Finding | None:
    require(track, "motors")
    points = track.points

    def flying(p: TrackPoint) -> bool:
        return p.armed and bool(p.motors) and p.airborne is not False

    def saturated(p: TrackPoint) -> bool:
        # Full motors under a full throttle are the pilot's punch-out, not lost authority.
        punch_out = finite(p.throttle) and p.throttle >= limits.punch_out_throttle
        return flying(p) and max(p.motors) >= limits.saturated_motor and not punch_out

    stretches = [
        (first, last, span_s(points, first, last)) for first, last in runs(points, saturated)
    ]
    long_ones = [s for s in stretches if s[2] >= limits.saturation_min_s]
    if not long_ones:
        return None
    first, last, lasted = max(long_ones, key=lambda s: s[2])
    stretch = points[first : last + 1]
    motors = sorted(
        {i + 1 for p in stretch for i, m in enumerate(p.motors) if m >= limits.saturated_motor}
    )
    total = sum(s[2] for s in stretches)
    armed_s = sum(span_s(points, a, b) for a, b in runs(points, flying)) or 1.0
    return Finding(
        "motor_saturation",
        Severity.WARNING,
        f"motor {', '.join(map(str, motors))} at full for {lasted:.2f} s "
        f"({100 * total / armed_s:.0f} % of the time in the air)",
        stretch[0].time_s,
        lasted,
        "s",
        {
            "motors": motors,
            "longest_s": lasted,
            "total_s": total,
            "share_of_flight": total / armed_s,
            "stretches": len(long_ones),
            "sample": evidence_of(stretch[0]),
        },
        track.source,
    )


# -- failsafe --------------------------------------------------------------------------------
def _phase_name(phase: int) -> str:
    try:
        return FailsafePhase(phase).name
    except ValueError:
        return f"PHASE_{phase}"  # a phase a newer firmware added


#: A failsafe finding's line names this many phase changes at most (the first ones and the
#: last); a failsafe that comes and goes (a flight channel invalid, then valid again) can
#: change phase thousands of times, all of them in the evidence.
PHASES_NAMED = 6


def _phase_sequence(changes: list[tuple[float, str]]) -> str:
    named = [f"{name} at {t:.2f} s" for t, name in changes]
    if len(named) <= PHASES_NAMED:
        return " -> ".join(named)
    left_out = len(named) - PHASES_NAMED
    return " -> ".join([*named[: PHASES_NAMED - 1], f"({left_out} more changes)", named[-1]])


def failsafe(track: Track, limits: Limits) -> Finding | None:
    changes: list[tuple[float, str]] = []
    if track.has("failsafe_phase"):
        last_phase = None
        for point in track.points:
            phase = point.failsafe_phase
            if phase is None or phase == last_phase:
                continue  # a log repeats its phase in every frame: named only when it changes
            last_phase = phase
            name = _phase_name(phase)
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
        entered = [
            (point.time_s, "FAILSAFE mode") for point in track.points if "FAILSAFE" in point.modes
        ][:1]
        changes = entered
    else:
        raise TrackDataMissingError(f"the {track.source} track has no failsafe phase and no modes")
    if not entered:
        return None
    first_s = entered[0][0]
    sequence = _phase_sequence([(t, name) for t, name in changes if t >= first_s])
    evidence: dict[str, object] = {
        "phases": [[name, t] for t, name in changes],
        "entered_s": first_s,
    }
    for t, name in entered:
        evidence.setdefault(f"to_{name.lower().replace(' ', '_')}_s", round(t - first_s, 4))
    if track.disarm_reason:
        evidence["disarm_reason"] = track.disarm_reason
    return Finding(
        "failsafe",
        Severity.INFO,
        f"failsafe: {sequence}",
        first_s,
        float(len(entered)),
        "phases",
        evidence,
        track.source,
    )


# -- the GPS and the estimate ------------------------------------------------------------------
def gps_glitch(track: Track, limits: Limits) -> Finding | None:
    require(track, "north_m", "fc_north_m")
    known = [p for p in track.points if finite(p.fc_north_m) and finite(p.north_m)]

    def off(p: TrackPoint) -> float:
        return math.hypot(p.fc_north_m - p.north_m, p.fc_east_m - p.east_m)

    episodes = []
    for first, last in runs(known, lambda p: off(p) >= limits.gps_glitch_m):
        onset = known[first]
        moved = max(
            math.hypot(p.north_m - onset.north_m, p.east_m - onset.east_m)
            for p in known[first : last + 1]
        )
        episodes.append((moved, first, last))
    if not episodes:
        return None
    moved, first, last = max(episodes)
    onset = known[first]
    error = max(off(p) for p in known[first : last + 1])
    followed = moved >= limits.gps_followed_m
    return Finding(
        "gps_glitch",
        Severity.WARNING if followed else Severity.INFO,
        f"the FC's GPS {error:.0f} m off the truth for "
        f"{span_s(known, first, last):.1f} s; the vehicle "
        + (f"followed it {moved:.1f} m" if followed else f"held within {moved:.1f} m"),
        onset.time_s,
        moved,
        "m",
        {
            "gps_error_m": error,
            "moved_m": moved,
            "lasted_s": span_s(known, first, last),
            "glitches": len(episodes),
            "sample": evidence_of(onset),
        },
        track.source,
    )
