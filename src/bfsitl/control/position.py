"""Horizontal position control through ANGLE mode: a target north/east in, roll/pitch sticks out.

Sans-I/O: :class:`PositionController` gets the FC's own position and velocity (its GPS, made
local by the caller) and the FC's heading, and returns the stick positions that tilt the
vehicle towards the target.  Nothing here reads a clock or a socket.

The cascade, each stage limited:

1. position error -> target velocity (``kp_pos_per_s``, at most ``max_speed_m_s``), plus the
   target's own velocity when it moves (and its acceleration, added in stage 2);
2. velocity error -> horizontal acceleration (``kp_vel_per_s`` plus an integral that learns
   the steady push of the wind, ``ki_vel_per_s2``; the total at most ``max_tilt_deg``);
3. acceleration -> tilt: ``atan(a / g)`` about the body axes (the heading turns north/east
   into forward/right), Betaflight's signs: pitch positive nose down accelerates forward, roll
   positive right wing down accelerates right.

Which stick holds that tilt is :mod:`bfsitl.control.angle_sticks`'s business (the FC's rate
curve shapes it).

The GPS lags the truth (about 0.1 s in SITL, more on a real receiver), so the position is
extrapolated by ``lead_s`` along the GPS velocity before it is compared with the target.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import ControllerConfigError
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2

#: Loops at least this fast get the stiff default gains (:meth:`PositionGains.for_loop_rate`).
STIFF_GAINS_MIN_RATE_HZ = 80.0


@dataclass(frozen=True, slots=True)
class PositionGains:
    # Tuned on the hold in 3 m/s wind with 1.5 m/s gusts (benchmarks/position.py): the
    # previous 0.9 / 1.6 / 0.5 held within 0.41-0.61 m RMS, these within 0.19-0.21 m;
    # twice as stiff again gained nothing (the GPS's and ANGLE mode's lags limit it).
    kp_pos_per_s: float = 1.5
    max_speed_m_s: float = 2.0
    kp_vel_per_s: float = 4.0
    ki_vel_per_s2: float = 2.0
    max_tilt_deg: float = 25.0
    lead_s: float = 0.1

    @classmethod
    def for_loop_rate(cls, rate_hz: float, *, lockstep: bool = True) -> PositionGains:
        """The gains for a control loop at ``rate_hz``: the stiff defaults need 100 Hz and a
        physics in lockstep with the FC.  A slower loop (a board at its default serial rate
        runs about 25 Hz) gets the gentler first set, which the stiff one made oscillate by
        30 deg at 25 Hz; so does a loop beside a physics on the wall clock (``lockstep``
        False: a stock SITL at real time, Gazebo, a board), where the stiff set rocked the
        quad +-20-40 deg on the square and tipped it over (the gentler: under 9 deg)."""
        if rate_hz >= STIFF_GAINS_MIN_RATE_HZ and lockstep:
            return cls()
        return cls(kp_pos_per_s=0.9, kp_vel_per_s=1.6, ki_vel_per_s2=0.5)

    def __post_init__(self) -> None:
        for name in ("kp_pos_per_s", "max_speed_m_s", "kp_vel_per_s", "max_tilt_deg"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ControllerConfigError(f"position gain {name} must be > 0, got {value}")
        if not (0.0 <= self.ki_vel_per_s2 < 10.0 and 0.0 <= self.lead_s < 2.0):
            raise ControllerConfigError("ki_vel_per_s2 must be in 0..10 and lead_s in 0..2 s")
        if self.max_tilt_deg >= 45.0:
            raise ControllerConfigError(
                f"max_tilt_deg {self.max_tilt_deg} must stay below 45 deg (the altitude "
                f"controller loses a third of its thrust beyond)"
            )


@dataclass(frozen=True, slots=True)
class PositionInput:
    time_s: float
    north_m: float  # where the FC's GPS puts the vehicle, local to a reference
    east_m: float
    v_north_m_s: float  # the GPS velocity
    v_east_m_s: float
    heading_deg: float  # the FC's yaw, clockwise from north
    target_north_m: float
    target_east_m: float
    #: How fast the target moves (a leg's travelling reference): fed forward, so the
    #: position loop corrects only the error around it.
    target_v_north_m_s: float = 0.0
    target_v_east_m_s: float = 0.0
    #: ... and how it accelerates, fed forward to the tilt.
    target_a_north_m_s2: float = 0.0
    target_a_east_m_s2: float = 0.0


@dataclass(frozen=True, slots=True)
class TiltCommand:
    roll_deg: float  # Betaflight's signs: roll right positive, pitch nose down positive
    pitch_deg: float
    target_speed_m_s: float


class PositionController:
    """Holds or reaches a horizontal position; one :meth:`update` per control step."""

    def __init__(self, gains: PositionGains | None = None) -> None:
        self.gains = gains or PositionGains()
        self.reset(0.0)

    def reset(self, time_s: float) -> None:
        self._last_s = time_s
        self._integral = (0.0, 0.0)  # m/s^2, north and east: the learnt wind push

    def resume(self, time_s: float) -> None:
        """Start a new manoeuvre at ``time_s``, keeping the learnt wind push: a new leg
        flies in the same wind as the last one ended in."""
        self._last_s = time_s

    @property
    def wind_accel_m_s2(self) -> tuple[float, float]:
        """The integral's acceleration (north, east): what it takes to stand against the wind."""
        return self._integral

    def update(self, state: PositionInput) -> TiltCommand:
        g = self.gains
        dt = min(max(state.time_s - self._last_s, 0.0), 0.1)
        self._last_s = state.time_s
        # 1. position -> target velocity, from the position extrapolated past the GPS lag
        north = state.north_m + state.v_north_m_s * g.lead_s
        east = state.east_m + state.v_east_m_s * g.lead_s
        vn_t, ve_t = _limit(
            g.kp_pos_per_s * (state.target_north_m - north),
            g.kp_pos_per_s * (state.target_east_m - east),
            g.max_speed_m_s,
        )
        vn_t += state.target_v_north_m_s
        ve_t += state.target_v_east_m_s
        # 2. velocity -> acceleration, with the wind integral
        en, ee = vn_t - state.v_north_m_s, ve_t - state.v_east_m_s
        a_max = STANDARD_GRAVITY_M_S2 * math.tan(math.radians(g.max_tilt_deg))
        i_n = self._integral[0] + g.ki_vel_per_s2 * en * dt
        i_e = self._integral[1] + g.ki_vel_per_s2 * ee * dt
        self._integral = _limit(i_n, i_e, a_max)
        a_n, a_e = _limit(
            g.kp_vel_per_s * en + self._integral[0] + state.target_a_north_m_s2,
            g.kp_vel_per_s * ee + self._integral[1] + state.target_a_east_m_s2,
            a_max,
        )
        # 3. acceleration -> tilt about the body axes
        psi = math.radians(state.heading_deg)
        a_fwd = a_n * math.cos(psi) + a_e * math.sin(psi)
        a_right = -a_n * math.sin(psi) + a_e * math.cos(psi)
        pitch_deg = math.degrees(math.atan2(a_fwd, STANDARD_GRAVITY_M_S2))
        roll_deg = math.degrees(math.atan2(a_right, STANDARD_GRAVITY_M_S2))
        # Per axis the angles add up to a little more than the acceleration's tilt when both
        # are large: keep the pair inside the limit as well.
        roll_deg, pitch_deg = _limit(roll_deg, pitch_deg, g.max_tilt_deg)
        return TiltCommand(roll_deg, pitch_deg, math.hypot(vn_t, ve_t))


def _limit(x: float, y: float, magnitude: float) -> tuple[float, float]:
    """(x, y) scaled down to ``magnitude`` if longer; the direction is kept."""
    length = math.hypot(x, y)
    if length <= magnitude or length == 0.0:
        return (x, y)
    k = magnitude / length
    return (x * k, y * k)
