"""A blackbox log made in memory: the frames a decoder would give, from arrays.  For the
replay's unit tests, which need a log's sticks, setpoints, gyro and motors but no file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import signal

from bfsitl.blackbox.decode import BlackboxFrame, BlackboxLog

RATE_HZ = 1000.0
SECONDS = 20.0


def synthetic_log(
    time_s: np.ndarray,
    rc_command: np.ndarray,
    *,
    setpoint: np.ndarray | None = None,
    gyro: np.ndarray | None = None,
    motors: np.ndarray | None = None,
    mode_mask: np.ndarray | None = None,
    headers: dict[str, str] | None = None,
    firmware: str = "Betaflight 4.2.9 (e097f4ab7) STM32F7X2",
) -> BlackboxLog:
    """A log of ``len(time_s)`` frames; ``rc_command`` is (N, 4), ``setpoint`` and ``gyro``
    (N, 3), ``motors`` (N, 4), all as logged (integers are rounded)."""
    count = len(time_s)
    zeros3 = np.zeros((count, 3))
    setpoint_rows = zeros3 if setpoint is None else setpoint
    gyro_rows = zeros3 if gyro is None else gyro
    frames = tuple(
        BlackboxFrame(
            time_s=float(time_s[i]),
            failsafe_phase=0,
            rx_signal_received=True,
            rx_flight_channels_valid=True,
            mode_switch_mask=int(mode_mask[i]) if mode_mask is not None else 1,
            state_flags=0,
            motors=() if motors is None else tuple(round(v) for v in motors[i]),
            rc_command=tuple(round(v) for v in rc_command[i]),
            setpoint=() if setpoint is None else (*(round(v) for v in setpoint_rows[i]), 1000),
            gyro_adc=tuple(round(v) for v in gyro_rows[i]),
            debug=(),
        )
        for i in range(count)
    )
    all_headers = {"Firmware revision": firmware, "motorOutput": "48,2047"}
    all_headers.update(headers or {})
    return BlackboxLog(
        path=Path("synthetic.bbl"),
        index=1,
        firmware_revision=firmware,
        headers=all_headers,
        frames=frames,
        events=(),
        disarm_reason=None,
        disarm_reason_name=None,
        truncated=False,
    )


def pilot_sticks(seed: int) -> np.ndarray:
    """Pilot-like sticks: held steps of random size on each axis, throttle around hover."""
    rng = np.random.default_rng(seed)
    count = int(SECONDS * RATE_HZ)
    command = np.zeros((count, 4))
    for axis in range(3):
        hold = np.repeat(rng.uniform(-300, 300, count // 250 + 1), 250)[:count]
        command[:, axis] = np.where(rng.random(count // 250 + 1).repeat(250)[:count] < 0.4, 0, hold)
    command[:, 3] = 1400.0 + 100.0 * np.sin(np.arange(count) / RATE_HZ)
    return command


def lagged_log(command: np.ndarray, *, tau_s: float, start_s: float = 0.0, rate_dps: float = 1.4):
    """A log of a quad whose rates follow the setpoint with lag ``tau_s``; its first frame
    comes ``start_s`` into the sticks (a later log start)."""
    first = round(start_s * RATE_HZ)
    command = command[first:]
    setpoint = command[:, :3] * rate_dps
    setpoint[:, 2] *= -1.0  # yaw's rcCommand and setpoint have opposite signs
    pole = np.exp(-1.0 / (tau_s * RATE_HZ))
    gyro = signal.lfilter([1 - pole], [1, -pole], setpoint, axis=0)
    motors = 400.0 + 0.8 * (command[:, 3:4] - 1000.0) + np.zeros((len(command), 4))
    time_s = 10.0 + np.arange(len(command)) / RATE_HZ
    return synthetic_log(time_s, command, setpoint=setpoint, gyro=gyro, motors=motors)
