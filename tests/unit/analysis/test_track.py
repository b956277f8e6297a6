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


def _frame(time_s: float, motors: tuple[int, ...], gyro: tuple[int, ...], acc: tuple[int, ...]):
    from bfsitl.blackbox import BlackboxFrame

    return BlackboxFrame(
        time_s=time_s,
        failsafe_phase=0,
        rx_signal_received=True,
        rx_flight_channels_valid=True,
        mode_switch_mask=0b10,
        state_flags=0,
        motors=motors,
        rc_command=(0, 0, 0, 1500),
        setpoint=(100, -200, 30, 1500),
        gyro_adc=gyro,
        debug=(),
        acc=acc,
        quaternion_xyz=(0, 0, 0),
        baro_alt_cm=250,
    )


def test_a_log_s_track_is_each_frame_scaled_even_where_a_damaged_frame_is_cut_short() -> None:
    """The columns are computed at once; a frame whose groups stop early (a damaged log)
    keeps its own length and gets what it got one frame at a time."""
    from pathlib import Path

    from bfsitl.analysis.track import track_from_blackbox
    from bfsitl.blackbox import BlackboxLog

    frames = (
        _frame(10.0, (1000, 1500, 2000, 2100), (10, -20, 30), (0, 0, 2048)),
        _frame(10.002, (1250,), (40,), (0, 2048)),  # cut short
        _frame(10.004, (900, 1000, 1100, 1200), (0, 0, 0), (2048, 0, 0)),
    )
    log = BlackboxLog(
        path=Path("LOG00001.BF"),
        index=1,
        firmware_revision="test",
        headers={"motorOutput": "1000,2000", "acc_1G": "2048", "blackbox_high_resolution": "1"},
        frames=frames,
        events=(),
        disarm_reason=None,
        disarm_reason_name=None,
        truncated=False,
    )
    points = track_from_blackbox(log).points
    assert [p.time_s for p in points] == [0.0, 0.002, 0.004]
    assert points[0].motors == (0.0, 0.5, 1.0, 1.0)  # clipped to 0..1
    assert points[1].motors == (0.25,) and points[1].gyro_deg_s == (4.0,)
    assert points[2].motors == (0.0, 0.0, 0.1, 0.2)
    assert points[0].gyro_deg_s == (1.0, -2.0, 3.0)  # scaled back from high resolution
    assert points[0].setpoint_deg_s == (10.0, -20.0, 3.0)
    assert points[0].accel_g == 1.0 and points[2].accel_g == 1.0
    assert math.isnan(points[1].accel_g)  # two of three axes: no magnitude
    assert points[0].alt_m == 2.5 and points[0].self_levelling and points[0].rx_ok


def test_the_columns_give_the_very_floats_one_frame_at_a_time_gave() -> None:
    """The arithmetic a column at a time against the same formulas frame by frame, on a
    SITL log of the test data: equal to the last bit (NaN where NaN)."""
    from pathlib import Path

    from bfsitl.analysis.track import _motor_range, track_from_blackbox
    from bfsitl.blackbox import decode_blackbox

    data = Path(__file__).resolve().parents[2] / "data" / "blackbox"
    for name in ("drop-4.6.0.BF", "switch-landing-master.BFL"):
        (log,) = decode_blackbox(data / name)
        low, high = _motor_range(log)
        scale, one_g = log.value_scale, float(log.headers["acc_1G"])
        points = track_from_blackbox(log).points
        assert len(points) == len(log.frames) > 100
        for point, frame in zip(points, log.frames, strict=True):
            motors = tuple(min(1.0, max(0.0, (m - low) / (high - low))) for m in frame.motors)
            assert point.motors == motors
            assert point.gyro_deg_s == tuple(g / scale for g in frame.gyro_adc)
            assert point.setpoint_deg_s == tuple(s / scale for s in frame.setpoint[:3])
            accel = math.sqrt(sum(a * a for a in frame.acc)) / one_g
            assert point.accel_g == accel or (math.isnan(point.accel_g) and math.isnan(accel))
            assert (point.tilt_deg, point.roll_deg, point.pitch_deg) == _tilt_roll_pitch(
                frame.quaternion_xyz
            )


def _tilt_roll_pitch(xyz: tuple[int, ...]) -> tuple[float, float, float]:
    from bfsitl.analysis.track import _tilt_roll_pitch as one_frame

    return one_frame(xyz)


def test_the_kernel_s_attitudes_are_math_s_to_the_last_bit() -> None:
    """The compiled attitude against ``math`` one frame at a time, on the corners (level,
    upside down, where atan2 meets y = 0 on either side, the scale's ends) and on random
    quaternions, unit or not (a log's are rounded to 15 bits)."""
    import random

    import numpy as np
    import pytest

    from bfsitl.analysis.logged_attitude import compiled_attitudes_deg

    corners = [
        (0, 0, 0),
        (32767, 0, 0),
        (-32767, 0, 0),
        (0, 32767, 0),
        (0, 0, 32767),
        (0, 0, -32767),
        (23170, 0, 23170),
        (0, -23170, 23170),
        (-32767, -32767, -32767),
        (1, -1, 1),
    ]
    rng = random.Random(7)
    spread = [tuple(rng.randint(-32767, 32767) for _ in range(3)) for _ in range(3000)]
    small = [tuple(rng.randint(-40, 40) for _ in range(3)) for _ in range(1000)]
    rows = corners + spread + small
    compiled = compiled_attitudes_deg(np.array(rows, dtype=np.int64))
    if compiled is None:
        pytest.skip("no C compiler for the kernel")
    for row, got in zip(rows, compiled, strict=True):
        assert repr(got) == repr(_tilt_roll_pitch(row)), row  # -0.0 and 0.0 told apart


def test_a_log_s_points_are_made_in_the_order_trackpoint_declares_its_fields() -> None:
    """track_from_blackbox hands TrackPoint its values by position: a field added in between
    would shift every value after it."""
    from dataclasses import fields

    assert [f.name for f in fields(TrackPoint)][:23] == [
        "time_s",
        "armed",
        "airborne",
        "alt_m",
        "climb_m_s",
        "north_m",
        "east_m",
        "tilt_deg",
        "roll_deg",
        "pitch_deg",
        "phase",
        "target_alt_m",
        "target_north_m",
        "target_east_m",
        "motors",
        "gyro_deg_s",
        "setpoint_deg_s",
        "accel_g",
        "throttle",
        "failsafe_phase",
        "rx_ok",
        "modes",
        "self_levelling",
    ]
