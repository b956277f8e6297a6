"""The analysers hold on real quads as well as on the simulated IRIS: a punch-out's thrust is
no impact and its full motors no saturation; an impact that ends a flight is a hard landing,
a bump the quad flies on from is not.  Made-up logs for each rule, then the real logs beside
the repository (tests/support/real_logs.py), whose own traces the findings must agree with."""

from __future__ import annotations

from pathlib import Path

import pytest
from support.real_logs import require_real_logs

from bfsitl.analysis import Track, TrackPoint, analyse
from bfsitl.analysis.track import track_from_blackbox
from bfsitl.blackbox import decode_blackbox

RATE_HZ = 500.0


def segment(
    seconds: float,
    *,
    motors: float,
    accel_g: float,
    throttle: float,
    gyro_off_deg_s: float = 0.0,
    start_s: float = 0.0,
) -> list[TrackPoint]:
    return [
        TrackPoint(
            time_s=start_s + i / RATE_HZ,
            armed=True,
            motors=(motors,) * 4,
            gyro_deg_s=(gyro_off_deg_s, 0.0, 0.0),
            setpoint_deg_s=(0.0, 0.0, 0.0),
            accel_g=accel_g,
            throttle=throttle,
        )
        for i in range(max(1, round(seconds * RATE_HZ)))
    ]


def log_of(*segments: dict[str, float]) -> Track:
    points: list[TrackPoint] = []
    for spec in segments:
        start = points[-1].time_s + 1 / RATE_HZ if points else 0.0
        points += segment(start_s=start, **spec)  # type: ignore[arg-type]
    return Track("blackbox", points, disarm_reason="SWITCH")


HOVER = {"seconds": 5.0, "motors": 0.25, "accel_g": 1.0, "throttle": 0.3}
REST = {"seconds": 1.0, "motors": 0.05, "accel_g": 1.0, "throttle": 0.0}
SPIKE = {"seconds": 0.002, "motors": 0.25, "accel_g": 8.0, "throttle": 0.3}


def names(track: Track) -> set[str]:
    return {f.analyser for f in analyse(track).findings}


def test_a_punch_out_is_neither_an_impact_nor_saturation() -> None:
    punch = {"seconds": 1.0, "motors": 0.99, "accel_g": 6.2, "throttle": 1.0}
    assert names(log_of(HOVER, punch, HOVER, REST)) == set()


def test_full_motors_without_full_throttle_are_saturation() -> None:
    stuck = {"seconds": 1.0, "motors": 0.99, "accel_g": 2.0, "throttle": 0.5}
    assert "motor_saturation" in names(log_of(HOVER, stuck, HOVER, REST))


def test_an_impact_that_ends_the_flight_is_a_hard_landing() -> None:
    (finding,) = analyse(log_of(HOVER, SPIKE, REST)).findings
    assert (
        finding.analyser == "hard_landing" and "7.0 g more than the motors push" in finding.summary
    )
    # The log cut by the impact ends the flight too.
    assert "hard_landing" in names(log_of(HOVER, SPIKE))


@pytest.mark.parametrize(
    "after",
    [
        {"seconds": 0.5, "motors": 0.45, "accel_g": 1.6, "throttle": 0.5},  # flies on
        {"seconds": 0.5, "motors": 0.02, "accel_g": 0.1, "throttle": 0.0},  # falls freely
    ],
    ids=["flies-on", "falls"],
)
def test_a_bump_the_quad_goes_on_from_is_no_landing(after: dict[str, float]) -> None:
    assert "hard_landing" not in names(log_of(HOVER, SPIKE, after, HOVER, REST))


def test_an_impact_the_motors_explain_is_no_landing() -> None:
    # 3.5 g in a climb the motors make (their 3.5 g level is the log's own).
    climb = {"seconds": 0.5, "motors": 0.6, "accel_g": 3.5, "throttle": 0.7}
    assert "hard_landing" not in names(log_of(HOVER, climb, HOVER, climb, REST))


def _tracks(path: Path) -> list[Track]:
    return [track_from_blackbox(log) for log in decode_blackbox(path) if log.frames]


def test_on_real_logs_a_hard_landing_ends_the_flight_and_no_finding_sits_in_a_punch_out() -> None:
    punch_outs_seen = 0
    for path in require_real_logs():
        for track in _tracks(path):
            points = track.points
            end_s = points[-1].time_s
            punch = [
                p.time_s for p in points if p.motors and min(p.motors) >= 0.9 and p.throttle >= 0.9
            ]
            punch_outs_seen += bool(punch)
            for finding in analyse(track).findings:
                if finding.analyser == "hard_landing":
                    assert end_s - finding.time_s < 1.0, (path.name, finding.summary)
                if finding.analyser in ("hard_landing", "motor_saturation"):
                    assert not any(abs(t - finding.time_s) < 0.1 for t in punch), (
                        path.name,
                        finding.summary,
                    )
    # The logs do hold punch-outs (5-inch freestyle): the rules above were put to the test.
    assert punch_outs_seen >= 1


def test_a_logs_mode_switches_say_whether_the_fc_levelled_the_quad() -> None:
    """``flightModeFlags`` holds the box switches by the firmware's internal ``boxId_e``
    (4.6.0 blackbox.c copies rcModeActivationMask; fc/rc_modes.h: ARM 0, ANGLE 1, HORIZON 2,
    MAG 3, ...): ANGLE and HORIZON level, the others do not; a failsafe levels whatever the
    switches say."""
    import dataclasses

    import numpy as np
    from support.synthetic_log import synthetic_log

    time_s = np.arange(6) / 100.0
    masks = np.array([0, 1 << 1, 1 << 2, 1 << 0, 1 << 3, 1 << 11])  # acro, ANGLE, HORIZON,
    # ARM alone, MAG (whose MSP permanent id 5 would be HEADFREE), ANTIGRAVITY
    log = synthetic_log(time_s, np.full((6, 4), 1500.0), mode_mask=masks)
    track = track_from_blackbox(log)
    assert [p.self_levelling for p in track.points] == [False, True, True, False, False, False]
    landing = dataclasses.replace(
        log, frames=tuple(dataclasses.replace(f, failsafe_phase=2) for f in log.frames)
    )
    assert all(p.self_levelling for p in track_from_blackbox(landing).points)
