"""Track.has: what a track's points carry, asked by every analyser."""

from __future__ import annotations

import math

from bfsitl.analysis.track import Track, TrackPoint


def test_has_tells_carried_values_from_missing_ones_and_sees_points_added_later() -> None:
    track = Track("flight", [TrackPoint(0.0, True), TrackPoint(0.1, True, tilt_deg=math.nan)])
    assert not track.has("tilt_deg") and not track.has("motors") and not track.has("phase")
    assert not track.has("failsafe_phase")  # None
    track.points.append(TrackPoint(0.2, True, tilt_deg=3.0, motors=(0.5,), phase="hold"))
    assert track.has("tilt_deg") and track.has("motors") and track.has("phase")
    assert track.has("armed")  # a bool is a value
    assert not track.has("failsafe_phase")
    track.points.append(TrackPoint(0.3, True, failsafe_phase=0))
    assert track.has("failsafe_phase")  # 0 is a phase (IDLE), not a missing one


def test_has_counts_infinite_numbers_empty_tuples_and_false_as_what_they_are() -> None:
    track = Track("flight", [TrackPoint(0.0, True, alt_m=math.inf, gyro_deg_s=())])
    assert not track.has("alt_m") and not track.has("gyro_deg_s")  # inf is no height
    track.points.append(TrackPoint(0.1, True, airborne=False, rx_ok=False, alt_m=-math.inf))
    assert track.has("airborne") and track.has("rx_ok")  # False is an answer, None is not
    assert not track.has("alt_m")
    track.points.append(TrackPoint(0.2, True, alt_m=0.0, gyro_deg_s=(0.0, 0.0, 0.0)))
    assert track.has("alt_m") and track.has("gyro_deg_s")  # zeros are values
