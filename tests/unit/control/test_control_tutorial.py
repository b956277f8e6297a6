"""The tutorial's PID and open-loop take-off: the arithmetic, the clamps, the schedule."""

from __future__ import annotations

import pytest

from bfsitl.control.base import AltitudeInput
from bfsitl.control.tutorial import OpenLoopGains, OpenLoopTakeoff, TutorialPid, TutorialPidGains
from bfsitl.errors import ControllerConfigError


def sample(t: float, alt: float, target: float = 2.0) -> AltitudeInput:
    return AltitudeInput(time_s=t, altitude_m=alt, climb_rate_m_s=0.0, target_alt_m=target)


def test_pid_is_hover_plus_p_plus_i_plus_d():
    g = TutorialPidGains(
        hover_base_us=1500,
        kp=100,
        ki=20,
        kd=50,
        integral_limit=10,
        throttle_min_us=1000,
        throttle_max_us=2000,
    )
    pid = TutorialPid(g)
    pid.reset(0.0)
    # First step: error 2, integral 2 x 0.1, no derivative yet.
    assert pid.update(sample(0.1, 0.0)) == pytest.approx(1500 + 200 + 20 * 0.2)
    # Second: error 1.9 (down 0.1 in 0.1 s: derivative -1), integral 0.2 + 0.19.
    expected = 1500 + 100 * 1.9 + 20 * (0.2 + 0.19) + 50 * (-1.0)
    assert pid.update(sample(0.2, 0.1)) == pytest.approx(expected)


def test_integral_is_clamped_and_output_is_clamped():
    g = TutorialPidGains(
        kp=0, ki=100, kd=0, integral_limit=0.5, throttle_min_us=1100, throttle_max_us=1700
    )
    pid = TutorialPid(g)
    pid.reset(0.0)
    for i in range(1, 200):
        out = pid.update(sample(i * 0.02, 0.0, target=5.0))
    assert pid.integral == pytest.approx(0.5)
    assert out == pytest.approx(g.hover_base_us + 100 * 0.5)
    big = TutorialPid(TutorialPidGains(kp=1000, throttle_max_us=1700))
    big.reset(0.0)
    assert big.update(sample(0.02, 0.0, target=10.0)) == 1700
    assert big.update(sample(0.04, 20.0, target=10.0)) == big.gains.throttle_min_us


def test_reset_forgets_integral_and_derivative():
    pid = TutorialPid()
    pid.reset(0.0)
    for i in range(1, 50):
        pid.update(sample(i * 0.02, 0.5))
    pid.reset(10.0)
    assert pid.integral == 0.0
    # Right after a reset: no derivative kick from the old error.
    first = pid.update(sample(10.02, 1.9))
    g = pid.gains
    assert first == pytest.approx(g.hover_base_us + g.kp * 0.1 + g.ki * 0.1 * 0.02)


def test_repeated_time_does_not_divide_by_zero():
    pid = TutorialPid()
    pid.reset(0.0)
    a = pid.update(sample(0.02, 0.0))
    assert pid.update(sample(0.02, 0.0)) == pytest.approx(a)


def test_open_loop_follows_the_clock_only():
    g = OpenLoopGains(ramp_s=1.0, climb_us=1600, climb_s=2.0, hover_us=1520)
    ol = OpenLoopTakeoff(g)
    ol.reset(5.0)
    assert ol.update(sample(5.0, 0.0)) == pytest.approx(1000)
    assert ol.update(sample(5.5, 9.0)) == pytest.approx(1300)  # altitude ignored
    assert ol.update(sample(6.5, -3.0)) == pytest.approx(1600)
    assert ol.update(sample(8.5, 2.0)) == pytest.approx(1520)


@pytest.mark.parametrize(
    "bad",
    [
        dict(kp=-1.0),
        dict(integral_limit=-1.0),
        dict(throttle_min_us=1900),
        dict(hover_base_us=1950),
        dict(kd=float("nan")),
        dict(throttle_max_us=2500),
    ],
)
def test_bad_pid_gains_are_rejected(bad):
    with pytest.raises(ControllerConfigError):
        TutorialPidGains(**bad)


@pytest.mark.parametrize("bad", [dict(ramp_s=-1.0), dict(climb_us=900), dict(hover_us=2100)])
def test_bad_open_loop_gains_are_rejected(bad):
    with pytest.raises(ControllerConfigError):
        OpenLoopGains(**bad)
