"""A real flight as arrays on a uniform clock: what a blackbox log gives a fit.

From the log's frames: each motor's command as the ESC gets it (0..1 of its throttle: DShot's
48..2047, or PWM's 1000..2000), the gyro turned into the body's FRD rates (Betaflight's sensor
frame is FLU: roll as is, pitch and yaw negated), the accelerometer's up axis in g (what the
thrust pushes, read through the FC's own low-pass), and the throttle stick.  Frames are put
on a uniform clock at the log's median frame interval.  What a fit must not read is kept out
of :attr:`FlightData.usable`: the time inside a gap in the log (logging paused, or corrupt
frames skipped), a second either side of a saturated gyro (a crash or a tumble), and the first
and last :data:`EDGE_S` of each stretch in the air (the take-off and the touchdown, where the
ground pushes on the quad), and what follows an impact in that stretch (a touchdown the motors
did not see coming).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bfsitl.blackbox.decode import BlackboxLog
from bfsitl.errors import FitError
from bfsitl.fit.motor_model import delayed

#: DShot's throttle values run from 48 (0 %) to 2047 (100 %).
DSHOT_ZERO, DSHOT_FULL = 48.0, 2047.0
#: Below this mean motor command a frame counts as on the ground or disarmed.
FLYING_MOTOR = 0.08
#: Below this share of the hover's motor level, reading more than GROUND_ACCEL_G, the ground
#: holds the quad up.
GROUND_MOTOR_SHARE = 0.75
GROUND_ACCEL_G = 0.6
#: A log needs this much usable flight to be fitted.
MIN_FLIGHT_S = 10.0
#: The gyro reads at most 2000 deg/s: near it the rates are clipped (a crash, a tumble).
GYRO_SATURATED_DEG_S = 1900.0
#: Kept out around a saturated gyro, and at each end of a stretch in the air.
SATURATION_MARGIN_S = 1.0
EDGE_S = 1.5
#: An impact reads more than IMPACT_G and more than IMPACT_SHARE times the g the motors of the
#: last IMPACT_LOOKBACK_S could give (a punch-out reads as much, with the motors up).
IMPACT_G = 2.0
IMPACT_SHARE = 2.0
IMPACT_LOOKBACK_S = 0.3
IMPACT_REACTION_S = 0.02
TOUCHDOWN_S = 5.0


@dataclass(frozen=True)
class FlightData:
    """One log's flight on a uniform clock (``dt_s``); arrays of shape (N,), (4, N) or (3, N).

    Attributes:
        label: The log, for messages (``file log N``).
        firmware: The firmware that flew, from the header.
        craft: The craft name in the header ("" when none).
        dt_s: The clock's step: the log's median frame interval.
        time_s: Seconds from the first frame.
        motors: Each motor's command, 0..1 of its ESC's throttle, Betaflight's order.
        gyro_frd_rad_s: Body rates, FRD (roll right, pitch nose up, yaw nose right).
        accel_up_g: The accelerometer's up axis, g (1 at rest), as the FC filtered it.
        throttle: The throttle stick, 0..1.
        acc_lpf_hz: The FC's accelerometer low-pass cut-off (0: none).
        flying: Frames in the air (the motors above idle).
        usable: Frames a fit may read (the module doc says what is left out).
        gaps_s: Time of the gaps in the log (left out of ``usable``).
    """

    label: str
    firmware: str
    craft: str
    dt_s: float
    time_s: np.ndarray
    motors: np.ndarray
    gyro_frd_rad_s: np.ndarray
    accel_up_g: np.ndarray
    throttle: np.ndarray
    acc_lpf_hz: float
    flying: np.ndarray
    usable: np.ndarray
    gaps_s: float

    @property
    def usable_s(self) -> float:
        return float(self.usable.sum()) * self.dt_s

    def split_index(self, share: float) -> int:
        """The frame before which ``share`` (0..1) of the usable time lies."""
        usable_index = np.flatnonzero(self.usable)
        return int(usable_index[int(share * (len(usable_index) - 1))])


def motor_command_share(raw: np.ndarray, high: float) -> np.ndarray:
    """The ESC's throttle share: DShot (the range ends at 2047) or PWM (1000..2000)."""
    if high >= DSHOT_FULL - 1:
        return np.clip((raw - DSHOT_ZERO) / (DSHOT_FULL - DSHOT_ZERO), 0.0, 1.0)
    return np.clip((raw - 1000.0) / 1000.0, 0.0, 1.0)


def header_number(log: BlackboxLog, key: str, default: float, *, position: int = 0) -> float:
    """The header's number (the ``position``-th of a comma list), or ``default``."""
    try:
        return float(log.headers.get(key, "").split(",")[position])
    except (ValueError, IndexError):
        return default


def flight_data(log: BlackboxLog) -> FlightData:
    """The log's flight on a uniform clock.

    Raises:
        FitError: No motors, gyro or accelerometer in the log, or less than
            :data:`MIN_FLIGHT_S` of flight.
    """
    label = f"{log.path.name} log {log.index}"
    frames = log.frames
    if len(frames) < 100:
        raise FitError(f"{label}: {len(frames)} frames, too few to fit anything")
    first = frames[0]
    if len(first.motors) < 4 or len(first.gyro_adc) < 3 or len(first.acc) < 3:
        raise FitError(f"{label}: the log has no motors, gyro or accelerometer fields to fit")
    if len(first.motors) > 4:
        raise FitError(
            f"{label}: {len(first.motors)} motors; the fit and the physics are for a quad-X"
        )
    times = np.array([f.time_s for f in frames])
    order = np.argsort(times, kind="stable")
    times = times[order] - times[order[0]]
    steps = np.diff(times)
    if not (steps > 0).any():
        raise FitError(f"{label}: every frame has the same time; the log's clock is broken")
    dt_s = float(np.median(steps[steps > 0]))
    grid = np.arange(0.0, times[-1], dt_s)
    gap_starts = np.flatnonzero(steps > 3 * dt_s)
    in_gap = np.zeros(len(grid), dtype=bool)
    for start in gap_starts:
        in_gap |= (grid > times[start]) & (grid < times[start + 1])

    def column(values: list[tuple[int, ...]], index: int) -> np.ndarray:
        raw = np.array([v[index] if len(v) > index else math.nan for v in values], float)
        return np.interp(grid, times, raw[order])

    scale = log.value_scale
    high = header_number(log, "motorOutput", DSHOT_FULL, position=1)
    motors = np.vstack(
        [motor_command_share(column([f.motors for f in frames], i), high) for i in range(4)]
    )
    gyro_flu = np.vstack([column([f.gyro_adc for f in frames], i) for i in range(3)]) / scale
    gyro_frd = np.radians(gyro_flu * np.array([[1.0], [-1.0], [-1.0]]))
    one_g = header_number(log, "acc_1G", 1.0) or 1.0
    accel_up_g = column([f.acc for f in frames], 2) / one_g
    throttle = np.clip(
        (column([f.rc_command for f in frames], 3) / scale - 1000.0) / 1000.0, 0.0, 1.0
    )
    flying = _airborne(motors.mean(axis=0), accel_up_g)
    usable = _usable(flying, in_gap, gyro_flu, dt_s) & ~_after_impact(
        flying, motors.mean(axis=0), accel_up_g, dt_s
    )
    data = FlightData(
        label=label,
        firmware=log.firmware_revision,
        craft=log.headers.get("Craft name", "").strip(),
        dt_s=dt_s,
        time_s=grid,
        motors=motors,
        gyro_frd_rad_s=gyro_frd,
        accel_up_g=accel_up_g,
        throttle=throttle,
        acc_lpf_hz=header_number(log, "acc_lpf_hz", 0.0) / 100.0,
        flying=flying,
        usable=usable,
        gaps_s=float(np.sum(steps[gap_starts])),
    )
    if data.usable_s < MIN_FLIGHT_S:
        raise FitError(
            f"{label}: {data.usable_s:.1f} s of usable flight (in the air, away from take-off, "
            f"touchdown, crashes and gaps); a fit needs at least {MIN_FLIGHT_S:g} s "
            "(give another log with --index)"
        )
    return data


def _hover_level(motor_level: np.ndarray, accel_up_g: np.ndarray) -> float | None:
    """The median motor level where the quad reads about 1 g with its motors running."""
    near_1g = (motor_level > FLYING_MOTOR) & (np.abs(accel_up_g - 1.0) < 0.1)
    return float(np.median(motor_level[near_1g])) if near_1g.any() else None


def _after_impact(
    flying: np.ndarray, motor_level: np.ndarray, accel_up_g: np.ndarray, dt_s: float
) -> np.ndarray:
    """From :data:`SATURATION_MARGIN_S` before a touchdown's impact to the end of that
    stretch in the air (the impact at most :data:`TOUCHDOWN_S` before it): the ground is not
    in the physics the fit replays.  An impact reads more than
    :data:`IMPACT_G`, and more than :data:`IMPACT_SHARE` times what the motors could give: the
    thrust grows about as the command squared (the hover's level gives 1 g), from the highest
    motor level of the last :data:`IMPACT_LOOKBACK_S` before the hit (the accelerometer is
    low-passed, so a punch-out's g outlasts its motors; the FC answers a hit with its motors
    in the same frame, so the last :data:`IMPACT_REACTION_S` are not counted)."""
    hover_level = _hover_level(motor_level, accel_up_g)
    hit = np.zeros_like(flying)
    if hover_level is None:
        return hit
    lookback = max(1, int(IMPACT_LOOKBACK_S / dt_s))
    from scipy import ndimage  # here: a scenario run imports this module, seldom uses it

    trailing = ndimage.maximum_filter1d(motor_level, size=lookback, origin=(lookback - 1) // 2)
    # The motors before the hit, not the FC's answer to it (in the same frame as the spike).
    before = delayed(trailing, max(1, int(IMPACT_REACTION_S / dt_s)))
    thrust_g = (before / hover_level) ** 2
    impacts = np.flatnonzero(
        flying & (accel_up_g > IMPACT_G) & (accel_up_g > IMPACT_SHARE * thrust_g)
    )
    margin = max(1, int(SATURATION_MARGIN_S / dt_s))
    for impact in impacts:
        if hit[impact]:
            continue
        landed = np.flatnonzero(~flying[impact:])
        end = impact + int(landed[0]) if len(landed) else len(flying)
        # Only a touchdown: mid-flight, a fast quad's rotors give more than the hover's
        # thrust per command (they meet more air), which reads the same.
        if (end - impact) * dt_s <= TOUCHDOWN_S:
            hit[max(0, impact - margin) : end] = True
    return hit


def _airborne(motor_level: np.ndarray, accel_up_g: np.ndarray) -> np.ndarray:
    """Frames in the air: the motors above idle, and not held up by the ground (the
    accelerometer reading more than :data:`GROUND_ACCEL_G` while the motors give less than
    the hover's thrust: in the air a quad at idle falls, and reads nearly nothing)."""
    running = motor_level > FLYING_MOTOR
    hover_level = _hover_level(motor_level, accel_up_g)
    if hover_level is None:
        return running
    grounded = (motor_level < GROUND_MOTOR_SHARE * hover_level) & (accel_up_g > GROUND_ACCEL_G)
    return np.asarray(running & ~grounded)


def _usable(
    flying: np.ndarray, in_gap: np.ndarray, gyro_deg_s: np.ndarray, dt_s: float
) -> np.ndarray:
    """Frames in the air, away from the ground, a saturated gyro and the log's gaps."""
    saturated = np.any(np.abs(gyro_deg_s) >= GYRO_SATURATED_DEG_S, axis=0) | in_gap
    near_saturation = _widened(saturated, max(1, int(SATURATION_MARGIN_S / dt_s)))
    near_ground = _widened(~(flying & ~in_gap), max(1, int(EDGE_S / dt_s)))
    return np.asarray(~near_ground & ~near_saturation)


def _widened(mask: np.ndarray, frames: int) -> np.ndarray:
    """``mask`` grown by ``frames`` on each side (a running count, not a loop per frame)."""
    counts = np.concatenate([[0], np.cumsum(mask.astype(np.int64))])
    index = np.arange(len(mask))
    low = np.clip(index - frames, 0, len(mask))
    high = np.clip(index + frames + 1, 0, len(mask))
    return np.asarray(counts[high] - counts[low] > 0)
