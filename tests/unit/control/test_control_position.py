"""The position controller on a horizontal rig: a point mass tilted by the FC's ANGLE loop
(a first-order lag), pushed by rotor drag in wind, seen through a lagged GPS."""

from __future__ import annotations

import math
from collections import deque

import pytest

from bfsitl.control.position import (
    PositionController,
    PositionGains,
    PositionInput,
    TiltCommand,
)
from bfsitl.errors import ControllerConfigError

G = 9.80665
DT = 0.01  # a 100 Hz control loop


def command(target=(0.0, 0.0), *, heading=0.0, at=(0.0, 0.0), v=(0.0, 0.0)) -> TiltCommand:
    return PositionController().update(
        PositionInput(0.01, at[0], at[1], v[0], v[1], heading, target[0], target[1])
    )


@pytest.mark.parametrize(
    ("target", "heading", "axis", "sign"),
    [
        ((5.0, 0.0), 0.0, "pitch", +1),  # north ahead: nose down
        ((-5.0, 0.0), 0.0, "pitch", -1),
        ((0.0, 5.0), 0.0, "roll", +1),  # east is right when facing north: right wing down
        ((0.0, 5.0), 90.0, "pitch", +1),  # facing east, east is ahead
        ((5.0, 0.0), 90.0, "roll", -1),  # facing east, north is left
    ],
)
def test_the_tilt_points_at_the_target_in_betaflights_signs(target, heading, axis, sign):
    tilt = command(target, heading=heading)
    main = tilt.pitch_deg if axis == "pitch" else tilt.roll_deg
    other = tilt.roll_deg if axis == "pitch" else tilt.pitch_deg
    assert main * sign > 5.0 and abs(other) < 1e-6


def test_tilt_and_speed_are_limited():
    tilt = command((1000.0, 1000.0))
    assert math.hypot(tilt.roll_deg, tilt.pitch_deg) <= PositionGains().max_tilt_deg + 1e-9
    assert tilt.target_speed_m_s == pytest.approx(PositionGains().max_speed_m_s)


class Rig:
    """North/east point mass: tilt follows the command with a 0.1 s lag; rotor drag 0.55 N s/m
    on 1.75 kg against the air; the GPS reports 0.1 s late."""

    def __init__(self, wind=(0.0, 0.0), heading_deg=0.0) -> None:
        self.p = [0.0, 0.0]
        self.v = [0.0, 0.0]
        self.tilt = [0.0, 0.0]  # roll, pitch (deg)
        self.wind = wind
        self.heading = heading_deg
        self.t = 0.0
        self.max_north = 0.0
        self.gps = deque([(0.0, 0.0, 0.0, 0.0)] * 10)

    def step(self, cmd: TiltCommand) -> None:
        for i, target in enumerate((cmd.roll_deg, cmd.pitch_deg)):
            self.tilt[i] += (target - self.tilt[i]) * DT / 0.1
        psi = math.radians(self.heading)
        a_fwd = G * math.tan(math.radians(self.tilt[1]))
        a_right = G * math.tan(math.radians(self.tilt[0]))
        a_n = a_fwd * math.cos(psi) - a_right * math.sin(psi)
        a_e = a_fwd * math.sin(psi) + a_right * math.cos(psi)
        k = 0.55 / 1.75
        a_n += -k * (self.v[0] - self.wind[0])
        a_e += -k * (self.v[1] - self.wind[1])
        self.v[0] += a_n * DT
        self.v[1] += a_e * DT
        self.p[0] += self.v[0] * DT
        self.p[1] += self.v[1] * DT
        self.max_north = max(self.max_north, self.p[0])
        self.t += DT
        self.gps.append((self.p[0], self.p[1], self.v[0], self.v[1]))
        self.gps.popleft()

    def fly(self, controller: PositionController, target, seconds: float) -> list[float]:
        errors = []
        for _ in range(round(seconds / DT)):
            n, e, vn, ve = self.gps[0]
            cmd = controller.update(
                PositionInput(self.t, n, e, vn, ve, self.heading, target[0], target[1])
            )
            self.step(cmd)
            errors.append(math.hypot(self.p[0] - target[0], self.p[1] - target[1]))
        return errors


def test_a_hold_in_3_m_s_wind_learns_the_push_and_stays_within_25_cm():
    rig, controller = Rig(wind=(-3.0, 1.0)), PositionController()
    errors = rig.fly(controller, (0.0, 0.0), 30.0)
    late = errors[len(errors) // 2 :]
    assert max(late) < 0.25
    assert math.sqrt(sum(e * e for e in late) / len(late)) < 0.1
    # The integral holds what it takes: drag on 3.16 m/s of wind, about 1 m/s^2, upwind.
    wind_n, wind_e = controller.wind_accel_m_s2
    assert wind_n > 0.5 and wind_e < -0.1


@pytest.mark.parametrize("heading", [0.0, 90.0, 225.0])
def test_a_10_m_leg_arrives_within_half_a_metre_without_a_big_overshoot(heading):
    rig = Rig(heading_deg=heading)
    errors = rig.fly(PositionController(), (10.0, 0.0), 15.0)
    assert errors[-1] < 0.2
    assert rig.max_north < 10.5  # never more than half a metre past the point
    assert min(errors[: round(8.0 / DT)]) < 0.5  # there within 8 s at 2 m/s


def test_bad_gains_are_refused_with_the_name():
    with pytest.raises(ControllerConfigError, match="kp_pos_per_s"):
        PositionGains(kp_pos_per_s=0.0)
    with pytest.raises(ControllerConfigError, match="max_tilt_deg"):
        PositionGains(max_tilt_deg=50.0)


def test_slow_loops_get_the_gentler_gains():
    from bfsitl.control.position import STIFF_GAINS_MIN_RATE_HZ

    assert PositionGains.for_loop_rate(100.0) == PositionGains()
    gentle = PositionGains.for_loop_rate(25.0)
    assert gentle.kp_vel_per_s < PositionGains().kp_vel_per_s
    assert gentle.ki_vel_per_s2 < PositionGains().ki_vel_per_s2
    assert PositionGains.for_loop_rate(STIFF_GAINS_MIN_RATE_HZ) == PositionGains()
    # Beside a physics on the wall clock the stiff gains rocked the quad: the gentler ones.
    assert PositionGains.for_loop_rate(100.0, lockstep=False) == gentle
