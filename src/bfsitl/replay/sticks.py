"""A log's sticks as RC frames the replaying FC turns back into the same commands.

A blackbox log holds ``rcCommand``, what the FC made of the receiver's pulses (deadband
taken off, yaw's sign flipped, throttle through ``min_check`` and the throttle curve,
``[4.6] src/main/fc/rc.c:761-791``), not the pulses.  Rather than undo each real FC's
settings, the replaying FC is set so that its own path is the identity
(:data:`IDENTITY_RC_LINES`: no deadband, centre 1500, a linear throttle curve, ``min_check``
one above the bottom), and the frames carry ``rcCommand`` back:

* roll and pitch: 1500 + rcCommand, yaw: 1500 - rcCommand (4.6.0 negates yaw unless
  ``yaw_control_reversed``);
* the stick's deflection is rcCommand over 500 minus the deadband in 4.6
  (``rcCommandDivider``, ``[4.6] src/main/fc/rc.c:77-78,729-731,887-888``) and over 500 in
  older sources; which release brought the divider is not established here, so it is taken
  as 4.3 (a deadband of 2-5 makes the difference 0.4-1 %).  The replaying FC divides by 500,
  so a 4.3+ log's command is scaled up by 500 / (500 - deadband) to keep the deflection, and
  with it the setpoint;
* throttle: a logged 1000 is a stick below the real FC's ``min_check`` and is sent as 1000
  (below the replaying FC's 1001: arming and "throttle low" agree); above it, the pulse
  whose ``(pulse - 1001) * 1000 / 999`` is the logged command.

4.6.0 logs every one of these ten times larger with ``blackbox_high_resolution`` on
(``[4.6] src/main/blackbox/blackbox.c:1272-1274,2307``).

The frames come at the real receiver's rate, not at every step: the firmware's feedforward
and RC smoothing work on the frames as they arrive.  A header says the rate the FC measured
when it has one (4.2: ``rc_smoothing_rx_average``, µs; 4.3 on: ``rc_smoothing_rx_smoothed``,
Hz, ``[4.6] src/main/blackbox/blackbox.c:1768``, 0 when not measured yet); otherwise the
median interval between changes of the sticks is taken.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from bfsitl.blackbox.decode import BlackboxFrame, BlackboxLog
from bfsitl.errors import BlackboxError, ReplayError
from bfsitl.fc.rc_link import RC_MID_US
from bfsitl.fit.log_data import header_number

#: What makes the replaying FC's stick path the identity (see the module docstring).
IDENTITY_RC_LINES = (
    "set deadband = 0",
    "set yaw_deadband = 0",
    "set mid_rc = 1500",
    "set min_check = 1001",
    "set thr_mid = 50",
    "set thr_hover = 50",
    "set thr_expo = 0",
)
THROTTLE_LOW_US = 1000.0
_MIN_CHECK_US = 1001.0
#: Box ids of the self-levelling modes in ``flightModeFlags`` (``boxId_e``: ARM 0, ANGLE 1,
#: HORIZON 2, the same from 3.x to 4.6, ``[4.6] src/main/fc/rc_modes.h``).
ANGLE_BOX_BIT = 1
HORIZON_BOX_BIT = 2
#: Receiver frame intervals believed from a header or from the sticks, seconds.
_FRAME_INTERVAL_RANGE_S = (0.001, 0.05)
#: A stretch without frames this long splits a log (see :func:`continuous_frames`).
MAX_GAP_S = 0.5
#: Shorter than this, a log holds too little to compare (the comparison needs a second).
MIN_REPLAY_S = 1.5
_VERSION = re.compile(r"(\d+)\.(\d+)(?:\.(\d+))?")


@dataclass(frozen=True, slots=True)
class StickStream:
    """The frames to send, on the log's clock from its first frame.

    Attributes:
        time_s: When each frame is due, seconds from the log's first frame.
        roll_us, pitch_us, throttle_us, yaw_us: The pulses, one per frame.
        angle, horizon: The self-levelling switches as the pilot had them, one per frame.
        frame_interval_s: The receiver's frame interval the frames are spaced by.
        interval_source: Where that interval came from (the header, or the sticks).
        deflection_scale: What the logged roll and pitch commands were multiplied by.
        loop_frames: The log's FC counted a receiver frame at every loop, whatever arrived
            (a 4.x SITL's own receiver, :func:`counts_frames_every_loop`): the replaying FC
            is left to do the same, and a frame goes out at every step.
    """

    time_s: np.ndarray
    roll_us: np.ndarray
    pitch_us: np.ndarray
    throttle_us: np.ndarray
    yaw_us: np.ndarray
    angle: np.ndarray
    horizon: np.ndarray
    frame_interval_s: float
    interval_source: str
    deflection_scale: float
    loop_frames: bool = False

    def __len__(self) -> int:
        return len(self.time_s)


def firmware_version(revision: str) -> tuple[int, int, int] | None:
    """(major, minor, patch) of ``Betaflight 4.2.9 (e097f4ab7) STM32F7X2``; None for another
    firmware (INAV's or EmuFlight's numbers mean other versions) or none named."""
    if not revision.startswith("Betaflight"):
        return None
    match = _VERSION.search(revision)
    if match is None:
        return None
    return int(match[1]), int(match[2]), int(match[3] or 0)


def counts_frames_every_loop(log: BlackboxLog) -> bool:
    """A 4.x SITL's own receiver wrote ``log``: it calls every check a complete frame
    (``rxRCFrameStatus``, ``[4.6] src/platform/SIMULATOR/sitl.c:259-263``), so its FC saw a
    receiver at its loop rate whatever bfsitl sent, and measured no rate (the header's
    ``rc_smoothing_rx_smoothed`` is 0).  Master's counts the frames that come, and so does
    bfsitl's lockstep 4.6.0 flown at an RC link's rate: its header holds that rate."""
    version = firmware_version(log.firmware_revision)
    if "SITL" not in log.firmware_revision or version is None or version[0] != 4:
        return False
    rate_hz = header_number(log, "rc_smoothing_rx_smoothed", 0.0)
    low, high = _FRAME_INTERVAL_RANGE_S
    return not (rate_hz > 0 and low <= 1.0 / rate_hz <= high)


def deflection_scales(log: BlackboxLog) -> tuple[float, float]:
    """(roll and pitch, yaw): what keeps the deflection of a log's commands on an FC with no
    deadband (see the module docstring)."""
    version = firmware_version(log.firmware_revision)
    if version is None or version < (4, 3, 0):
        return 1.0, 1.0
    deadband = header_number(log, "deadband", 0.0)
    yaw_deadband = header_number(log, "yaw_deadband", 0.0)
    return 500.0 / (500.0 - deadband), 500.0 / (500.0 - yaw_deadband)


def frame_interval_s(
    log: BlackboxLog, times_s: np.ndarray, commands: np.ndarray
) -> tuple[float, str]:
    """The receiver's frame interval and where it came from."""
    low, high = _FRAME_INTERVAL_RANGE_S
    averaged_us = header_number(log, "rc_smoothing_rx_average", 0.0)
    if low <= averaged_us / 1e6 <= high:
        return averaged_us / 1e6, "header rc_smoothing_rx_average"
    rate_hz = header_number(log, "rc_smoothing_rx_smoothed", 0.0)
    if rate_hz > 0 and low <= 1.0 / rate_hz <= high:
        return 1.0 / rate_hz, "header rc_smoothing_rx_smoothed"
    changed = np.flatnonzero(np.any(np.diff(commands, axis=0) != 0, axis=1)) + 1
    if len(changed) >= 10:
        median = float(np.median(np.diff(times_s[changed])))
        if median < low:
            # Changing at (nearly) every logged loop: an FC that interpolated its sticks
            # (3.x, 4.2 before smoothing moved to the setpoint) logs them smoothed.
            return low, "sticks interpolated by the FC: a frame every millisecond"
        if median <= high:
            return median, "median interval between stick changes"
    return 0.01, "a 100 Hz receiver (the sticks hardly moved)"


def continuous_frames(frames: Sequence[BlackboxFrame]) -> list[BlackboxFrame]:
    """The longest run of ``frames`` without a gap in their clock, in time order.  3.x logs
    open with a few frames stamped near zero before the flight's first (measured on the CS110
    logs: 3-7 frames, then a jump of 34-75 s); a gap of :data:`MAX_GAP_S` or more splits."""
    ordered = sorted(frames, key=lambda frame: frame.time_s)
    if not ordered:
        return []
    times = np.array([frame.time_s for frame in ordered])
    cuts = [0, *(np.flatnonzero(np.diff(times) >= MAX_GAP_S) + 1).tolist(), len(ordered)]
    start, end = max(zip(cuts, cuts[1:], strict=False), key=lambda run: run[1] - run[0])
    return ordered[start:end]


def stick_stream(log: BlackboxLog) -> StickStream:
    """The frames that replay ``log``'s sticks.

    Raises:
        BlackboxError: The log has no ``rcCommand``, or no frames.
    """
    frames = continuous_frames([f for f in log.frames if len(f.rc_command) == 4])
    if len(frames) < 2:
        raise BlackboxError(
            f"{log.path.name} log {log.index} has no rcCommand frames: nothing to replay"
        )
    times_s = np.array([f.time_s for f in frames]) - frames[0].time_s
    if times_s[-1] < MIN_REPLAY_S:
        raise ReplayError(
            f"{log.path.name} log {log.index} holds {times_s[-1]:.2f} s of sticks; a replay "
            f"needs at least {MIN_REPLAY_S:g} s (give another log with --index)"
        )
    scale = log.value_scale
    commands = np.array([f.rc_command for f in frames], dtype=float) / scale
    loop_frames = counts_frames_every_loop(log)
    if loop_frames:
        interval_s, source = 0.001, "a 4.x SITL's receiver: a frame at every loop, sent every step"
    else:
        interval_s, source = frame_interval_s(log, times_s, commands)
    due_s = np.arange(0.0, times_s[-1] + 1e-9, interval_s)
    # The frame carries what the log held at its time (the last logged frame at or before).
    rows = np.clip(np.searchsorted(times_s, due_s, side="right") - 1, 0, len(frames) - 1)
    sampled = commands[rows]
    roll_scale, yaw_scale = deflection_scales(log)
    masks = np.array([f.mode_switch_mask for f in frames], dtype=np.int64)[rows]
    return StickStream(
        time_s=due_s,
        roll_us=RC_MID_US + np.clip(sampled[:, 0] * roll_scale, -500, 500),
        pitch_us=RC_MID_US + np.clip(sampled[:, 1] * roll_scale, -500, 500),
        throttle_us=throttle_pulse_us(sampled[:, 3]),
        yaw_us=RC_MID_US - np.clip(sampled[:, 2] * yaw_scale, -500, 500),
        angle=(masks >> ANGLE_BOX_BIT) & 1 == 1,
        horizon=(masks >> HORIZON_BOX_BIT) & 1 == 1,
        frame_interval_s=interval_s,
        interval_source=source,
        deflection_scale=roll_scale,
        loop_frames=loop_frames,
    )


def throttle_pulse_us(command: np.ndarray) -> np.ndarray:
    """The pulses the replaying FC (``min_check`` 1001, linear curve) reads as ``command``."""
    above = np.clip(command, THROTTLE_LOW_US, 2000.0) - THROTTLE_LOW_US
    pulse = _MIN_CHECK_US + np.ceil(above * (2000.0 - _MIN_CHECK_US) / 1000.0 - 1e-9)
    return np.where(above <= 0, THROTTLE_LOW_US, np.minimum(pulse, 2000.0))
