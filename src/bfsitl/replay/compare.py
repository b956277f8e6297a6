"""The real flight against its replay, per axis, from the two blackbox logs.

Both logs go onto one uniform clock (:data:`RATE_HZ`), each from its first frame; the
replay's log starts a little later after arming than the real one's did, so the two are
aligned where their sticks (``rcCommand``, which the replaying FC computes back to the real
one's, :mod:`.sticks`) agree best.  Then, per axis:

* the setpoint: correlation and RMS ratio.  It is what the firmware asked of the quad from
  the same sticks; a low correlation means a setting (rates, RC smoothing, feedforward) did
  not come across, or self-levelling flew another attitude;
* the gyro: correlation and the RMS of the difference over the RMS of the real gyro (the
  quad did what the real one did, not only was asked the same);
* the step response from setpoint to gyro of each flight (:mod:`.step_response`): rise
  time, overshoot and settling, so tuning and physics are compared on the same footing as a
  pilot's step-response tool does.

And the motors: the average command's correlation and its mean level difference.  A log
without setpoint (3.x) or motors leaves those figures out (None) and says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from bfsitl.blackbox.decode import BlackboxFrame, BlackboxLog
from bfsitl.errors import ReplayError
from bfsitl.fit.log_data import DSHOT_FULL, header_number, motor_command_share
from bfsitl.replay.step_response import StepResponse, step_response
from bfsitl.replay.sticks import continuous_frames, deflection_scales

AXES = ("roll", "pitch", "yaw")
#: The common clock both logs are resampled to, at most: a log written more slowly sets it
#: lower, so that both logs are resampled alike (interpolating a 250 Hz log up to 1 kHz
#: slows its response by 1-2 ms, which the other log would not share).
RATE_HZ = 1000.0
#: The real quad has lost control where its gyro is this far from its setpoint on an axis
#: (without setpoints: this fast at all): a crash or a tumble, after which the sticks no
#: longer say what the quad did.  The comparison ends a second before.
LOST_CONTROL_DPS = 1000.0
LOST_CONTROL_NO_SETPOINT_DPS = 1500.0
BEFORE_LOSS_S = 1.0
#: How far apart the two logs' first frames may be, seconds: the replay's lead-in (at most
#: 2 s, :func:`~bfsitl.replay.flight.lead_in_s`) and its log's start after arming.
MAX_OFFSET_S = 3.0


@dataclass(frozen=True, slots=True)
class LogTraces:
    """A log on a uniform clock.  Arrays are None where the log does not hold the field.

    Attributes:
        time_s: From the log's first frame.
        sticks: rcCommand roll, pitch, yaw as a share of full deflection, throttle 0-1;
            shape (4, N).
        setpoint_dps: Roll, pitch, yaw setpoint, deg/s; shape (3, N).
        gyro_dps: Roll, pitch, yaw rate (the FC's filtered gyro), deg/s; shape (3, N).
        motor_level: The four motors' mean command, 0-1.
    """

    time_s: np.ndarray
    sticks: np.ndarray
    setpoint_dps: np.ndarray | None
    gyro_dps: np.ndarray
    motor_level: np.ndarray | None


@dataclass(frozen=True, slots=True)
class AxisComparison:
    """One axis of the real flight against the replay (None: not in a log)."""

    axis: str
    setpoint_correlation: float | None
    setpoint_rms_ratio: float | None
    gyro_correlation: float
    gyro_error: float
    real_step: StepResponse | None
    replay_step: StepResponse | None

    @property
    def rise_time_ratio(self) -> float | None:
        """Replay's rise time over the real one's (None: either has none to read)."""
        if self.real_step is None or self.replay_step is None:
            return None
        real_ms = self.real_step.rise_time_ms
        if not (math.isfinite(real_ms) and real_ms > 0):
            return None
        return self.replay_step.rise_time_ms / real_ms

    @property
    def overshoot_difference_pct(self) -> float | None:
        """Replay's overshoot minus the real one's, percentage points."""
        if self.real_step is None or self.replay_step is None:
            return None
        return self.replay_step.overshoot_pct - self.real_step.overshoot_pct


@dataclass(frozen=True, slots=True)
class ReplayComparison:
    """The whole comparison (see the module docstring).

    Attributes:
        offset_s: Where the real log's first frame lies on the replay's log clock.
        overlap_s: Seconds compared: both logs cover them, and the real quad was in control.
        rate_hz: The common clock's rate.
        lost_control_s: When the real quad lost control (see :data:`LOST_CONTROL_DPS`),
            seconds into its log; None if it never did.
        axes: Roll, pitch and yaw.
        motor_correlation: Of the mean motor command (None: a log has no motors).
        motor_level_difference_pct: Replay's mean motor command minus the real one's, over
            the flight, percentage points of full throttle.
    """

    offset_s: float
    overlap_s: float
    rate_hz: float
    lost_control_s: float | None
    axes: tuple[AxisComparison, ...]
    motor_correlation: float | None
    motor_level_difference_pct: float | None
    #: The two logs on the common clock, and where the compared stretch starts in each.
    real: LogTraces = field(repr=False)
    replay: LogTraces = field(repr=False)
    real_start: int = 0
    replay_start: int = 0
    samples: int = 0


def comparable_frames(log: BlackboxLog) -> list[BlackboxFrame]:
    """The frames of ``log`` a comparison reads: with sticks and gyro, without a gap.

    Raises:
        ReplayError: No rcCommand or gyro in the log, or under a second of it.
    """
    label = f"{log.path.name} log {log.index}"
    first = log.frames[0] if log.frames else None
    if first is None or len(first.rc_command) < 4 or len(first.gyro_adc) < 3:
        raise ReplayError(f"{label} has no rcCommand and gyro fields to compare")
    frames = continuous_frames(
        [f for f in log.frames if len(f.rc_command) == 4 and len(f.gyro_adc) == 3]
    )
    if len(frames) < 2 or frames[-1].time_s - frames[0].time_s < 1.0:
        raise ReplayError(f"{label}: under a second of rcCommand and gyro without a gap")
    return frames


def log_traces(log: BlackboxLog, *, rate_hz: float = RATE_HZ) -> LogTraces:
    """``log`` on a uniform clock (see :class:`LogTraces`).

    Raises:
        ReplayError: No rcCommand or gyro in the log, or under a second of it.
    """
    frames = comparable_frames(log)
    times = np.array([f.time_s for f in frames])
    times -= times[0]
    grid = np.arange(0.0, times[-1], 1.0 / rate_hz)
    scale = log.value_scale

    def columns(rows: list[tuple[int, ...]], count: int) -> np.ndarray:
        raw = np.array(rows, dtype=float).reshape(len(rows), count).T
        return np.vstack([np.interp(grid, times, row) for row in raw])

    command = columns([f.rc_command for f in frames], 4) / scale
    roll_scale, yaw_scale = deflection_scales(log)
    sticks = np.vstack(
        [
            command[0] * roll_scale / 500.0,
            command[1] * roll_scale / 500.0,
            command[2] * yaw_scale / 500.0,
            np.clip((command[3] - 1000.0) / 1000.0, 0.0, 1.0),
        ]
    )
    has_setpoint = all(len(f.setpoint) >= 3 for f in frames)
    setpoint = columns([f.setpoint[:3] for f in frames], 3) / scale if has_setpoint else None
    gyro = columns([f.gyro_adc for f in frames], 3) / scale
    motor_level = None
    if all(len(f.motors) >= 4 for f in frames):
        motors = columns([f.motors[:4] for f in frames], 4)
        high = header_number(log, "motorOutput", DSHOT_FULL, position=1)
        motor_level = motor_command_share(motors, high).mean(axis=0)
    return LogTraces(grid, sticks, setpoint, gyro, motor_level)


def log_rate_hz(log: BlackboxLog) -> float:
    """The log's frame rate (from the median interval between frames)."""
    times = np.sort(np.array([f.time_s for f in log.frames]))
    steps = np.diff(times)
    steps = steps[steps > 0]
    return 1.0 / float(np.median(steps)) if steps.size else RATE_HZ


def lost_control_s(traces: LogTraces) -> float | None:
    """When the quad lost control (see :data:`LOST_CONTROL_DPS`); None if it never did."""
    if traces.setpoint_dps is not None:
        lost = np.any(np.abs(traces.gyro_dps - traces.setpoint_dps) > LOST_CONTROL_DPS, axis=0)
    else:
        lost = np.any(np.abs(traces.gyro_dps) > LOST_CONTROL_NO_SETPOINT_DPS, axis=0)
    first = np.flatnonzero(lost)
    return float(traces.time_s[first[0]]) if first.size else None


def stick_offset_s(real: LogTraces, replay: LogTraces, *, rate_hz: float = RATE_HZ) -> float:
    """Where the real log's time 0 lies on the replay log's clock: the lag within
    :data:`MAX_OFFSET_S` at which their sticks agree best."""
    # Imported here: scipy.signal takes a second to import, and every scenario run imports
    # this module (the replay expectations) whether it replays or not.
    from scipy import signal

    length = min(real.sticks.shape[1], replay.sticks.shape[1])
    lags = signal.correlation_lags(length, length, mode="full")
    total = np.zeros(len(lags))
    for a, b in zip(real.sticks[:, :length], replay.sticks[:, :length], strict=True):
        total += signal.correlate(b - b.mean(), a - a.mean(), mode="full", method="fft")
    allowed = np.abs(lags) <= MAX_OFFSET_S * rate_hz
    return float(lags[allowed][np.argmax(total[allowed])]) / rate_hz


def _correlation(a: np.ndarray, b: np.ndarray) -> float:
    if np.std(a) == 0 or np.std(b) == 0:
        return float("nan")
    return float(np.corrcoef(a, b)[0, 1])


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def compare_logs(real_log: BlackboxLog, replay_log: BlackboxLog) -> ReplayComparison:
    """Compare ``replay_log`` (the replaying FC's) with ``real_log`` (see the module doc).

    Raises:
        ReplayError: A log has no sticks or gyro to compare, or they do not overlap.
    """
    rate_hz = min(RATE_HZ, log_rate_hz(real_log), log_rate_hz(replay_log))
    real, replay = log_traces(real_log, rate_hz=rate_hz), log_traces(replay_log, rate_hz=rate_hz)
    offset_s = stick_offset_s(real, replay, rate_hz=rate_hz)
    shift = round(offset_s * rate_hz)
    real_from, replay_from = max(0, -shift), max(0, shift)
    length = min(real.time_s.size - real_from, replay.time_s.size - replay_from)
    lost_s = lost_control_s(real)
    if lost_s is not None:
        length = min(length, round((lost_s - BEFORE_LOSS_S) * rate_hz) - real_from)
    if length < rate_hz:
        raise ReplayError(
            "the replay's log and the real one overlap by under a second"
            + ("" if lost_s is None else f" before the real quad lost control at {lost_s:.2f} s")
        )
    a, b = slice(real_from, real_from + length), slice(replay_from, replay_from + length)
    axes = []
    for index, axis in enumerate(AXES):
        real_gyro, replay_gyro = real.gyro_dps[index, a], replay.gyro_dps[index, b]
        real_set = replay_set = None
        if real.setpoint_dps is not None and replay.setpoint_dps is not None:
            real_set, replay_set = real.setpoint_dps[index, a], replay.setpoint_dps[index, b]
        axes.append(_axis(axis, real_set, replay_set, real_gyro, replay_gyro, rate_hz))
    motor_correlation = motor_difference = None
    if real.motor_level is not None and replay.motor_level is not None:
        motor_correlation = _correlation(real.motor_level[a], replay.motor_level[b])
        motor_difference = 100.0 * float(np.mean(replay.motor_level[b] - real.motor_level[a]))
    return ReplayComparison(
        offset_s=offset_s,
        overlap_s=length / rate_hz,
        rate_hz=rate_hz,
        lost_control_s=lost_s,
        axes=tuple(axes),
        motor_correlation=motor_correlation,
        motor_level_difference_pct=motor_difference,
        real=real,
        replay=replay,
        real_start=real_from,
        replay_start=replay_from,
        samples=length,
    )


def _axis(
    axis: str,
    real_set: np.ndarray | None,
    replay_set: np.ndarray | None,
    real_gyro: np.ndarray,
    replay_gyro: np.ndarray,
    rate_hz: float,
) -> AxisComparison:
    gyro = {
        "gyro_correlation": _correlation(real_gyro, replay_gyro),
        "gyro_error": _rms(replay_gyro - real_gyro) / max(_rms(real_gyro), 1e-9),
    }
    if real_set is None or replay_set is None:
        return AxisComparison(axis, None, None, real_step=None, replay_step=None, **gyro)
    return AxisComparison(
        axis,
        setpoint_correlation=_correlation(real_set, replay_set),
        setpoint_rms_ratio=_rms(replay_set) / _rms(real_set) if _rms(real_set) > 0 else None,
        real_step=step_response(real_set, real_gyro, rate_hz),
        replay_step=step_response(replay_set, replay_gyro, rate_hz),
        **gyro,
    )
