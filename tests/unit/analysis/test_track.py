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
