"""The log's rcCommand back to the pulses a replaying FC (with the identity stick path) turns
into the same commands: checked against 4.6.0's own arithmetic, written out here from
``[4.6] src/main/fc/rc.c:761-791`` so that a wrong sign, centre or throttle scale fails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bfsitl.errors import BlackboxError, ReplayError
from bfsitl.replay.sticks import (
    IDENTITY_RC_LINES,
    deflection_scales,
    firmware_version,
    stick_stream,
    throttle_pulse_us,
)
from tests.support.synthetic_log import synthetic_log


def fc_rc_command(pulses: tuple[float, float, float, float]) -> tuple[float, ...]:
    """What 4.6.0 computes from roll, pitch, throttle, yaw pulses with IDENTITY_RC_LINES:
    no deadband, mid_rc 1500, min_check 1001, the linear throttle curve."""
    roll, pitch, throttle, yaw = pulses
    rc = [max(-500.0, min(500.0, p - 1500.0)) for p in (roll, pitch, yaw)]
    rc[2] = -rc[2]  # yaw_control_reversed off
    clipped = max(1001.0, min(2000.0, throttle))
    tmp = math.floor((clipped - 1001.0) * 1000.0 / (2000.0 - 1001.0))
    return rc[0], rc[1], rc[2], 1000.0 + tmp


def test_the_identity_path_is_what_the_replaying_fc_is_given() -> None:
    assert "set deadband = 0" in IDENTITY_RC_LINES
    assert "set yaw_deadband = 0" in IDENTITY_RC_LINES
    assert "set min_check = 1001" in IDENTITY_RC_LINES
    assert "set thr_expo = 0" in IDENTITY_RC_LINES


def test_each_axis_comes_back_with_its_sign() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([120.0, -80.0, 45.0, 1430.0], (len(time_s), 1))
    stream = stick_stream(synthetic_log(time_s, command))
    pulses = (stream.roll_us[5], stream.pitch_us[5], stream.throttle_us[5], stream.yaw_us[5])
    assert pulses[0] == 1620.0 and pulses[1] == 1420.0 and pulses[3] == 1455.0
    back = fc_rc_command(pulses)
    assert back[:3] == (120.0, -80.0, 45.0)
    assert abs(back[3] - 1430.0) <= 1.0


def test_every_throttle_command_comes_back_within_one() -> None:
    commands = np.arange(1000.0, 2001.0)
    pulses = throttle_pulse_us(commands)
    back = np.array([fc_rc_command((1500, 1500, p, 1500))[3] for p in pulses])
    assert np.max(np.abs(back - commands)) <= 1.0
    # Exact but where 999 us of stick cannot hold 1000 steps (one command in the range).
    assert np.count_nonzero(back != commands) <= 1
    # A logged 1000 is a stick below min_check: it must read as throttle low.
    assert pulses[0] == 1000.0 and pulses[1] > 1000.0


def test_a_high_resolution_log_is_scaled_down() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([1200.0, 0.0, 0.0, 15000.0], (len(time_s), 1))
    log = synthetic_log(
        time_s,
        command,
        headers={"blackbox_high_resolution": "1"},
        firmware="Betaflight 4.6.0 (c155f5830) SITL",
    )
    stream = stick_stream(log)
    assert stream.roll_us[0] == pytest.approx(1620.0)
    assert fc_rc_command((1500, 1500, stream.throttle_us[0], 1500))[3] == pytest.approx(
        1500.0, abs=1.0
    )


def test_a_4_3_log_keeps_its_deflection_without_the_deadband() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([99.0, 0.0, 99.0, 1000.0], (len(time_s), 1))
    newer = synthetic_log(
        time_s,
        command,
        headers={"deadband": "5", "yaw_deadband": "10"},
        firmware="Betaflight 4.4.2 (abc) STM32F405",
    )
    assert deflection_scales(newer) == (500.0 / 495.0, 500.0 / 490.0)
    assert stick_stream(newer).roll_us[0] == pytest.approx(1500.0 + 99.0 * 500.0 / 495.0)
    assert stick_stream(newer).yaw_us[0] == pytest.approx(1500.0 - 99.0 * 500.0 / 490.0)
    older = synthetic_log(time_s, command, headers={"deadband": "5"})
    assert deflection_scales(older) == (1.0, 1.0)


def test_frames_come_at_the_receivers_rate() -> None:
    time_s = np.arange(0, 2.0, 0.0005)
    command = np.zeros((len(time_s), 4))
    command[:, 3] = 1000.0
    # The sticks change every 4 ms, as a 250 Hz link delivers them.
    command[:, 0] = np.floor(time_s / 0.004) % 7
    stream = stick_stream(synthetic_log(time_s, command))
    assert stream.frame_interval_s == pytest.approx(0.004, abs=1e-4)
    assert np.diff(stream.time_s) == pytest.approx(0.004, abs=1e-9)
    told = stick_stream(
        synthetic_log(time_s, command, headers={"rc_smoothing_rx_average": "19969"})
    )
    assert told.frame_interval_s == pytest.approx(0.019969)
    assert "header" in told.interval_source
    newer = stick_stream(
        synthetic_log(time_s, command, headers={"rc_smoothing_rx_smoothed": "1000"})
    )
    assert newer.frame_interval_s == pytest.approx(0.001)
    # 0: the FC had not measured it yet; the sticks say.
    unmeasured = stick_stream(
        synthetic_log(time_s, command, headers={"rc_smoothing_rx_smoothed": "0"})
    )
    assert unmeasured.frame_interval_s == pytest.approx(0.004, abs=1e-4)


def test_each_frame_carries_the_log_at_its_time() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.zeros((len(time_s), 4))
    command[:, 3] = 1000.0
    command[time_s >= 0.5, 0] = 200.0
    stream = stick_stream(
        synthetic_log(time_s, command, headers={"rc_smoothing_rx_average": "10000"})
    )
    before = stream.roll_us[stream.time_s < 0.499]
    after = stream.roll_us[stream.time_s >= 0.5]
    assert set(before.tolist()) == {1500.0} and set(after.tolist()) == {1700.0}


def test_the_self_levelling_switches_follow_the_log() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([0.0, 0.0, 0.0, 1000.0], (len(time_s), 1))
    mask = np.where(time_s < 0.5, 0b011, 0b101)  # ARM+ANGLE, then ARM+HORIZON
    stream = stick_stream(
        synthetic_log(time_s, command, mode_mask=mask, headers={"rc_smoothing_rx_average": "10000"})
    )
    early, late = stream.time_s < 0.45, stream.time_s > 0.55
    assert stream.angle[early].all() and not stream.horizon[early].any()
    assert stream.horizon[late].all() and not stream.angle[late].any()


def test_a_log_without_sticks_is_refused() -> None:
    log = synthetic_log(np.arange(0, 1.0, 0.1), np.zeros((10, 4)))
    empty = type(log)(**{**{f: getattr(log, f) for f in log.__slots__}, "frames": ()})
    with pytest.raises(BlackboxError, match="no rcCommand"):
        stick_stream(empty)


def test_firmware_versions_are_read_from_the_revision() -> None:
    assert firmware_version("Betaflight 4.2.9 (e097f4ab7) STM32F7X2") == (4, 2, 9)
    assert firmware_version("Betaflight 4.6.0 () SITL") == (4, 6, 0)
    assert firmware_version("Cleanflight") is None
    assert firmware_version("INAV 7.1.0 (abc) MATEKF405") is None


def test_a_log_too_short_to_replay_is_refused() -> None:
    time_s = np.arange(0, 1.0, 0.001)
    with pytest.raises(ReplayError, match="at least"):
        stick_stream(synthetic_log(time_s, np.tile([0.0, 0.0, 0.0, 1000.0], (len(time_s), 1))))


def test_sticks_the_fc_interpolated_go_out_every_millisecond() -> None:
    time_s = np.arange(0, 2.0, 0.0005)  # a 2 kHz log whose sticks change at every frame
    command = np.zeros((len(time_s), 4))
    command[:, 0] = 400.0 * np.sin(2.0 * np.pi * 3.0 * time_s)
    command[:, 3] = 1000.0
    stream = stick_stream(synthetic_log(time_s, command))
    assert stream.frame_interval_s == pytest.approx(0.001)
    assert "interpolated" in stream.interval_source


def test_a_4_x_sitl_log_is_replayed_with_a_frame_every_step() -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([0.0, 0.0, 0.0, 1200.0], (len(time_s), 1))
    sitl = stick_stream(synthetic_log(time_s, command, firmware="Betaflight 4.6.0 () SITL"))
    assert sitl.loop_frames and sitl.frame_interval_s == pytest.approx(0.001)
    master = stick_stream(
        synthetic_log(
            time_s, command, firmware="Betaflight 2026.12.0-alpha (norevision) SITL",
            headers={"rc_smoothing_rx_smoothed": "1000"},
        )
    )  # fmt: skip
    assert not master.loop_frames
    board = stick_stream(synthetic_log(time_s, command))
    assert not board.loop_frames
    # bfsitl's lockstep 4.6.0 at an RC link's rate measured it: its frames are replayed.
    linked = stick_stream(
        synthetic_log(
            time_s, command, firmware="Betaflight 4.6.0 () SITL",
            headers={"rc_smoothing_rx_smoothed": "250"},
        )
    )  # fmt: skip
    assert not linked.loop_frames and linked.frame_interval_s == pytest.approx(0.004)
    stock = synthetic_log(
        time_s, command, firmware="Betaflight 4.6.0 () SITL",
        headers={"rc_smoothing_rx_smoothed": "0"},
    )  # fmt: skip
    assert stick_stream(stock).loop_frames
