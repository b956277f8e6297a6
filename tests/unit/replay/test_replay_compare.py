"""The comparison of two logs: aligned by their sticks, per axis, against the targets.  The
"quads" here are first-order lags from setpoint to gyro, so the right answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from bfsitl.errors import ReplayError
from bfsitl.replay.compare import compare_logs, log_traces
from bfsitl.replay.replay_report import axis_targets, targets_met
from tests.support.synthetic_log import RATE_HZ, SECONDS, lagged_log, pilot_sticks, synthetic_log


def test_the_same_quad_meets_every_target_and_the_offset_is_found() -> None:
    command = pilot_sticks(1)
    real = lagged_log(command, tau_s=0.02)
    replay = lagged_log(command, tau_s=0.02, start_s=0.137)
    result = compare_logs(real, replay)
    # The replay's log began 0.137 s into the sticks: the real log's time 0 lies before it.
    assert result.offset_s == pytest.approx(-0.137, abs=0.002)
    for axis in result.axes:
        assert axis.setpoint_correlation == pytest.approx(1.0, abs=1e-3)
        assert axis.gyro_error < 0.05
        assert axis.rise_time_ratio == pytest.approx(1.0, abs=0.05)
        assert abs(axis.overshoot_difference_pct) < 1.0
        assert all(axis_targets(axis).values())
    assert targets_met(result) is True
    assert result.motor_correlation == pytest.approx(1.0, abs=1e-3)
    assert abs(result.motor_level_difference_pct) < 0.5


def test_a_slower_quad_misses_the_rise_time() -> None:
    command = pilot_sticks(2)
    result = compare_logs(lagged_log(command, tau_s=0.02), lagged_log(command, tau_s=0.04))
    for axis in result.axes:
        assert axis.rise_time_ratio == pytest.approx(2.0, rel=0.15)
        assert axis_targets(axis)["rise_time"] is False
        assert axis_targets(axis)["setpoint"] is True
    assert targets_met(result) is False


def test_setpoints_from_other_rates_miss_the_setpoint_target() -> None:
    command = pilot_sticks(3)
    real = lagged_log(command, tau_s=0.02)
    # Other rates: the same sticks ask for a cubic of themselves.
    bent = lagged_log(command, tau_s=0.02)
    changed = []
    for frame in bent.frames:
        cubed = tuple(round(v * abs(v) / 300.0) for v in frame.setpoint[:3])
        changed.append(type(frame)(**{**_fields(frame), "setpoint": (*cubed, 1000)}))
    bent = type(bent)(**{**_fields(bent), "frames": tuple(changed)})
    result = compare_logs(real, bent)
    assert all(axis.setpoint_correlation < 0.99 for axis in result.axes)
    assert all(axis_targets(axis)["setpoint"] is False for axis in result.axes)


def test_the_comparison_ends_before_the_real_quad_lost_control() -> None:
    command = pilot_sticks(6)
    real = lagged_log(command, tau_s=0.02)
    crashed = []
    for frame in real.frames:
        if frame.time_s - real.frames[0].time_s >= 15.0:  # a tumble at 2000 deg/s from 15 s
            frame = type(frame)(**{**_fields(frame), "gyro_adc": (2000, -1900, 300)})
        crashed.append(frame)
    real = type(real)(**{**_fields(real), "frames": tuple(crashed)})
    # The replay's log began 0.3 s into the sticks: the cut counts from the real log's start.
    result = compare_logs(real, lagged_log(command, tau_s=0.02, start_s=0.3))
    assert result.lost_control_s == pytest.approx(15.0, abs=0.002)
    assert result.overlap_s == pytest.approx(13.7, abs=0.01)
    assert all(axis.gyro_error < 0.05 for axis in result.axes)


def test_a_slow_log_sets_the_common_clock() -> None:
    command = pilot_sticks(7)
    real = lagged_log(command, tau_s=0.02)
    every_fourth = type(real)(**{**_fields(real), "frames": real.frames[::4]})
    result = compare_logs(every_fourth, lagged_log(command, tau_s=0.02))
    assert result.rate_hz == pytest.approx(250.0)
    assert result.overlap_s == pytest.approx(SECONDS, abs=0.05)


def test_a_log_without_setpoints_leaves_those_figures_out() -> None:
    command = pilot_sticks(4)
    real = lagged_log(command, tau_s=0.02)
    frames = tuple(type(f)(**{**_fields(f), "setpoint": ()}) for f in real.frames)
    old = type(real)(**{**_fields(real), "frames": frames})
    result = compare_logs(old, lagged_log(command, tau_s=0.02))
    for axis in result.axes:
        assert axis.setpoint_correlation is None and axis.real_step is None
        assert axis_targets(axis) == {"setpoint": None, "rise_time": None, "overshoot": None}
        assert axis.gyro_error < 0.05
    assert targets_met(result) is None


def test_a_log_too_short_to_compare_is_refused() -> None:
    command = pilot_sticks(5)[:500]
    short = synthetic_log(np.arange(500) / RATE_HZ, command)
    with pytest.raises(ReplayError, match="under a second"):
        log_traces(short)


def _fields(value: object) -> dict[str, object]:
    return {name: getattr(value, name) for name in value.__slots__}  # type: ignore[attr-defined]


def test_a_replay_that_never_followed_its_setpoint_misses() -> None:
    command = pilot_sticks(9)
    real = lagged_log(command, tau_s=0.02)
    still = lagged_log(command, tau_s=0.02)
    frames = tuple(type(f)(**{**_fields(f), "gyro_adc": (0, 0, 0)}) for f in still.frames)
    result = compare_logs(real, type(still)(**{**_fields(still), "frames": frames}))
    assert all(axis.replay_step is None for axis in result.axes)
    assert all(axis_targets(axis)["rise_time"] is False for axis in result.axes)
    assert targets_met(result) is False


def test_frames_before_a_gap_in_the_clock_are_left_out() -> None:
    command = pilot_sticks(10)
    real = lagged_log(command, tau_s=0.02)
    # A 3.x log opens with frames stamped near zero, then jumps to the flight.
    early = tuple(
        type(f)(**{**_fields(f), "time_s": 0.001 * (3 - i), "rc_command": (0, 0, 0, 0)})
        for i, f in enumerate(real.frames[:3])
    )
    opened = type(real)(**{**_fields(real), "frames": early + real.frames})
    result = compare_logs(opened, lagged_log(command, tau_s=0.02))
    assert result.offset_s == pytest.approx(0.0, abs=0.002)
    assert result.overlap_s == pytest.approx(SECONDS, abs=0.05)
    assert targets_met(result) is True


def test_a_high_resolution_log_is_read_at_its_scale() -> None:
    command = pilot_sticks(12)
    real = lagged_log(command, tau_s=0.02)
    fine = lagged_log(command, tau_s=0.02)
    # 4.6's blackbox_high_resolution: rcCommand, setpoint and gyro logged ten times larger.
    frames = tuple(
        type(f)(
            **{
                **_fields(f),
                "rc_command": (*(10 * v for v in f.rc_command[:3]), 10 * f.rc_command[3]),
                "setpoint": (*(10 * v for v in f.setpoint[:3]), f.setpoint[3]),
                "gyro_adc": tuple(10 * v for v in f.gyro_adc),
            }
        )
        for f in fine.frames
    )
    headers = {**fine.headers, "blackbox_high_resolution": "1"}
    fine = type(fine)(**{**_fields(fine), "frames": frames, "headers": headers})
    result = compare_logs(real, fine)
    for axis in result.axes:
        assert axis.setpoint_rms_ratio == pytest.approx(1.0, abs=0.01)
        assert axis.gyro_error < 0.05
