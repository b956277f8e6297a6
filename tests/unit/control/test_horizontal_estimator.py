"""The horizontal estimator: a late, stepped GPS and an on-time accelerometer make a position
that is closer to the truth now than the GPS is; and the accelerometer is turned to north and
east with Betaflight's axes and angle signs."""

from __future__ import annotations

import math

import pytest

from bfsitl.control.horizontal_estimator import HorizontalEstimator, specific_force_north_east

G = 9.80665


def fly(
    estimator: HorizontalEstimator,
    *,
    gps_hz: float,
    delay_s: float,
    accel_bias: float = 0.0,
    seconds: float = 20.0,
) -> tuple[float, float]:
    """A vehicle swinging north and back (1.5 m, 0.25 Hz); returns the RMS error of the
    estimate and of the raw GPS against the truth, after 5 s of settling."""
    dt, w = 0.01, 2 * math.pi * 0.25
    fix = (0.0, 0.0, 0.0, 0.0)
    next_fix_s = 0.0
    est_sq = gps_sq = 0.0
    count = 0
    for step in range(int(seconds / dt)):
        t = step * dt
        truth = 1.5 * math.sin(w * t)
        accel = -1.5 * w * w * math.sin(w * t) + accel_bias
        if t >= next_fix_s:  # the receiver's fix describes delay_s ago
            then = t - delay_s
            fix = (1.5 * math.sin(w * then), 0.0, 1.5 * w * math.cos(w * then), 0.0)
            next_fix_s += 1.0 / gps_hz
        estimate = estimator.update(t, accel, 0.0, fix)
        if t > 5.0:
            est_sq += (estimate.north_m - truth) ** 2
            gps_sq += (fix[0] - truth) ** 2
            count += 1
    return math.sqrt(est_sq / count), math.sqrt(gps_sq / count)


def test_a_late_slow_gps_is_beaten_by_the_fused_estimate():
    estimator = HorizontalEstimator(gps_delay_s=0.2)
    fused_m, gps_m = fly(estimator, gps_hz=5.0, delay_s=0.2)
    assert gps_m > 0.3  # a 5 Hz receiver 0.2 s late is this far behind a swinging vehicle
    assert fused_m < gps_m / 5


def test_an_accelerometer_bias_is_learnt():
    estimator = HorizontalEstimator(gps_delay_s=0.1)
    fused_m, _gps_m = fly(estimator, gps_hz=10.0, delay_s=0.1, accel_bias=0.3, seconds=40.0)
    assert estimator._b[0] == pytest.approx(0.3, abs=0.05)
    assert fused_m < 0.05


def test_a_gap_without_updates_restarts_from_the_gps():
    estimator = HorizontalEstimator()
    estimator.update(0.0, 5.0, 0.0, (1.0, 2.0, 0.0, 0.0))
    later = estimator.update(10.0, 0.0, 0.0, (7.0, -3.0, 0.5, 0.0))
    assert (later.north_m, later.east_m, later.v_north_m_s) == (7.0, -3.0, 0.5)


@pytest.mark.parametrize(
    ("roll", "pitch", "heading", "expected"),
    [
        (0.0, 0.0, 0.0, (0.0, 0.0)),  # level: thrust is all vertical
        (0.0, 10.0, 0.0, (G * math.tan(math.radians(10)), 0.0)),  # nose down: forward = north
        (0.0, 10.0, 90.0, (0.0, G * math.tan(math.radians(10)))),  # facing east: east
        (10.0, 0.0, 0.0, (0.0, G * math.tan(math.radians(10)))),  # right wing down: right = east
    ],
)
def test_the_thrust_of_a_tilted_hover_points_where_betaflights_angles_say(
    roll, pitch, heading, expected
):
    # A hover tilted so: the accelerometer reads the thrust along body z (FLU: +z), just
    # enough to hold the height, g / cos(tilt).
    tilt = math.acos(math.cos(math.radians(roll)) * math.cos(math.radians(pitch)))
    north, east = specific_force_north_east((0.0, 0.0, G / math.cos(tilt)), roll, pitch, heading)
    assert (north, east) == pytest.approx(expected, abs=0.05)
