"""Horizontal position and velocity *now*, from a late GPS and an on-time accelerometer.

The same idea as :mod:`bfsitl.control.altitude_estimator`, on north and east: the FC's
accelerometer (MSP_RAW_IMU, turned to north/east with the FC's attitude) is integrated every
control step, and the GPS (MSP_RAW_GPS), which arrives late and in steps, corrects what
integration cannot know: where the vehicle is, and the accelerometer's bias (on master, an
attitude estimate a degree off reads as 0.17 m/s^2 of horizontal acceleration).

The GPS is compared with the estimate of ``gps_delay_s`` ago (kept in a short history), not
with the estimate now, so a moving vehicle is not pulled back by a fix that simply has not
caught up; the correction then moves the whole history, so it shows at once.  Only new fixes
correct: a reading equal to the last one is the same fix read again.

Per axis, with ``w = bandwidth_rad_s``: position innovation gain ``2 w``, velocity
innovation gain ``2 w`` (on velocity), bias gain ``w^2 / 2`` (from the velocity innovation).

Sans-I/O: numbers in, numbers out.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2

#: A gap this long between updates (no position control meanwhile) restarts from the GPS.
RESTART_AFTER_S = 1.0


@dataclass(frozen=True, slots=True)
class HorizontalEstimate:
    north_m: float
    east_m: float
    v_north_m_s: float
    v_east_m_s: float
    bias_north_m_s2: float
    bias_east_m_s2: float


def specific_force_north_east(
    acc_flu_m_s2: tuple[float, float, float], roll_deg: float, pitch_deg: float, heading_deg: float
) -> tuple[float, float]:
    """The accelerometer's specific force turned to north and east (m/s^2): what makes the
    vehicle accelerate horizontally (gravity has no horizontal part).

    Betaflight's accelerometer axes are FLU (x forward, y left, z up), its pitch is positive
    nose down and its roll positive right wing down; this is the standard ZYX rotation of the
    FRD vector (x, -y, -z) with pitch negated, whose vertical row is what
    ``Telemetry.accel_up_m_s2`` uses.
    """
    ax, ay, az = acc_flu_m_s2
    fx, fy, fz = ax, -ay, -az
    phi = math.radians(roll_deg)
    theta = -math.radians(pitch_deg)
    psi = math.radians(heading_deg)
    sphi, cphi = math.sin(phi), math.cos(phi)
    sth, cth = math.sin(theta), math.cos(theta)
    spsi, cpsi = math.sin(psi), math.cos(psi)
    north = (
        cpsi * cth * fx
        + (cpsi * sth * sphi - spsi * cphi) * fy
        + (cpsi * sth * cphi + spsi * sphi) * fz
    )
    east = (
        spsi * cth * fx
        + (spsi * sth * sphi + cpsi * cphi) * fy
        + (spsi * sth * cphi - cpsi * sphi) * fz
    )
    return north, east


class HorizontalEstimator:
    """Complementary filter on north and east; one :meth:`update` per control step."""

    def __init__(
        self,
        *,
        gps_delay_s: float = 0.1,
        bandwidth_rad_s: float = 1.5,
        max_step_s: float = 0.2,
        max_bias_m_s2: float = 0.2 * STANDARD_GRAVITY_M_S2,
    ) -> None:
        if not (gps_delay_s >= 0 and bandwidth_rad_s > 0 and max_step_s > 0):
            raise ValueError("gps_delay_s >= 0, bandwidth_rad_s > 0, max_step_s > 0")
        self.gps_delay_s = gps_delay_s
        self.bandwidth_rad_s = bandwidth_rad_s
        self.max_step_s = max_step_s
        self.max_bias_m_s2 = max_bias_m_s2
        self.started = False
        self._p = [0.0, 0.0]
        self._v = [0.0, 0.0]
        self._b = [0.0, 0.0]
        self._time_s = 0.0
        self._last_fix: tuple[float, float, float, float] | None = None
        self._fix_time_s = 0.0
        #: (time_s, north, east, v_north, v_east) of past steps, for the late fix.
        self._history: deque[tuple[float, float, float, float, float]] = deque()

    def reset(
        self,
        time_s: float,
        north_m: float,
        east_m: float,
        v_north_m_s: float = 0.0,
        v_east_m_s: float = 0.0,
    ) -> None:
        self.started = True
        self._time_s = time_s
        self._p = [north_m, east_m]
        self._v = [v_north_m_s, v_east_m_s]
        self._b = [0.0, 0.0]
        self._last_fix = (north_m, east_m, v_north_m_s, v_east_m_s)
        self._fix_time_s = time_s
        self._history.clear()
        self._remember()

    def update(
        self,
        time_s: float,
        accel_north_m_s2: float,
        accel_east_m_s2: float,
        fix: tuple[float, float, float, float],
    ) -> HorizontalEstimate:
        """``fix``: the GPS's (north, east, v_north, v_east) as read this step."""
        if not self.started or time_s - self._time_s > RESTART_AFTER_S:
            # First use, or back after a stretch without position control: start from the fix.
            self.reset(time_s, *fix)
        dt = min(max(time_s - self._time_s, 0.0), self.max_step_s)
        self._time_s = time_s
        accel = (accel_north_m_s2, accel_east_m_s2)
        for axis in (0, 1):
            a = accel[axis] - self._b[axis]
            self._p[axis] += self._v[axis] * dt + 0.5 * a * dt * dt
            self._v[axis] += a * dt
        if fix != self._last_fix:
            self._last_fix = fix
            self._correct(fix)
        self._remember()
        return HorizontalEstimate(
            self._p[0], self._p[1], self._v[0], self._v[1], self._b[0], self._b[1]
        )

    def _correct(self, fix: tuple[float, float, float, float]) -> None:
        then = self._state_at(self._time_s - self.gps_delay_s)
        w = self.bandwidth_rad_s
        # A fix corrects for the time since the previous one (the GPS's period), so the
        # filter's bandwidth does not depend on how often fixes come.
        span = min(self._time_s - self._fix_time_s, 0.5)
        self._fix_time_s = self._time_s
        dp, dv = [0.0, 0.0], [0.0, 0.0]
        for axis in (0, 1):
            e_p = fix[axis] - then[axis]
            e_v = fix[2 + axis] - then[2 + axis]
            dp[axis] = 2.0 * w * e_p * span
            dv[axis] = 2.0 * w * e_v * span
            self._p[axis] += dp[axis]
            self._v[axis] += dv[axis]
            bias = self._b[axis] - 0.5 * w * w * e_v * span
            self._b[axis] = max(-self.max_bias_m_s2, min(self.max_bias_m_s2, bias))
        self._shift_history(dp, dv)

    def _remember(self) -> None:
        self._history.append((self._time_s, self._p[0], self._p[1], self._v[0], self._v[1]))
        horizon = self._time_s - 2.0 * self.gps_delay_s - self.max_step_s
        while len(self._history) > 2 and self._history[1][0] < horizon:
            self._history.popleft()

    def _state_at(self, time_s: float) -> tuple[float, float, float, float]:
        best = self._history[0]
        for entry in self._history:
            if entry[0] <= time_s:
                best = entry
            else:
                break
        return best[1], best[2], best[3], best[4]

    def _shift_history(self, dp: list[float], dv: list[float]) -> None:
        """A correction says where the vehicle *was* too: move the remembered states."""
        self._history = deque(
            (t, north + dp[0], east + dp[1], v_north + dv[0], v_east + dv[1])
            for t, north, east, v_north, v_east in self._history
        )
