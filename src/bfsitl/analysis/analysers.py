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
                       past 75 deg (warning), where the FC levels   attitude; a log's gyro
                       (not in acro); the gyro 200 deg/s off its    and setpoint
                       setpoint for 0.25 s
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

from collections.abc import Callable
from dataclasses import dataclass, field

from bfsitl.analysis.excursions import altitude_estimate, altitude_excursion, position_excursion
from bfsitl.analysis.findings import Finding
from bfsitl.analysis.ground_contact import crash, fly_away, hard_landing
from bfsitl.analysis.in_flight import (
    failsafe,
    gps_glitch,
    loss_of_control,
    motor_saturation,
    oscillation,
)
from bfsitl.analysis.limits import Limits
from bfsitl.analysis.track import Track
from bfsitl.errors import TrackDataMissingError


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
ANALYSERS: tuple[Analyser, ...] = (
    Analyser("crash", "ground contact at crash speed, or tipped over", crash),
    Analyser("hard_landing", "ground contact faster than a landing", hard_landing),
    Analyser("fly_away", "beyond the farthest target plus a margin", fly_away),
    Analyser(
        "loss_of_control",
        "upside down, tilted past any command, gyro off its setpoint",
        loss_of_control,
    ),
    Analyser("oscillation", "attitude or gyro error swinging, sustained", oscillation),
    Analyser("motor_saturation", "a motor at full, sustained", motor_saturation),
    Analyser("failsafe", "the failsafe's phases and when", failsafe),
    Analyser("gps_glitch", "the FC's GPS off the truth, and the vehicle's response", gps_glitch),
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
