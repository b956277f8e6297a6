"""The step response estimated from free flight (:mod:`bfsitl.replay.step_response`), against
systems whose step response is known: a pilot-like setpoint flown through first- and
second-order rate loops (with pure delay, gain and gyro noise), read back and compared with
the analytic rise time, overshoot, settling time and gain.

What would fail: a response one sample off or normalised wrongly (rise time, gain), windows
averaged so that noise or idle stick dominates (overshoot), NaN gaps bridged or crashing, an
idle stick read as a response, the ground or a crash read as the rate loop, an estimator that
cannot tell a fast quad from a slow one.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from scipy import signal

from bfsitl.errors import MetricsInputError
from bfsitl.replay.step_response import StepResponse, step_response

RATE_HZ = 1000.0
DURATION_S = 60.0


@functools.cache
def _pilot(rate_hz: float = RATE_HZ, seed: int = 1) -> np.ndarray:
    """A pilot's setpoint, deg/s: sticks held at random rates (or centred) for 0.1-0.8 s,
    plus slow wandering, smoothed at 30 Hz as the firmware smooths the sticks."""
    rng = np.random.default_rng(seed)
    n = int(DURATION_S * rate_hz)
    held = np.zeros(n)
    i = 0
    while i < n:
        length = int(rng.uniform(0.1, 0.8) * rate_hz)
        held[i : i + length] = rng.uniform(-300.0, 300.0) if rng.random() < 0.6 else 0.0
        i += length
    b, a = signal.butter(2, 3.0, fs=rate_hz)
    wander = signal.lfilter(b, a, rng.standard_normal(n))
    b, a = signal.butter(2, 30.0, fs=rate_hz)
    setpoint = signal.lfilter(b, a, held + wander * 60.0 / wander.std())
    setpoint.setflags(write=False)
    return setpoint


def _fly(
    setpoint: np.ndarray,
    num: list[float],
    den: list[float],
    delay_s: float = 0.0,
    rate_hz: float = RATE_HZ,
) -> np.ndarray:
    """The gyro of a linear rate loop ``num / den`` (continuous, s-domain) with a pure delay.
    Zero-order-hold discretisation: at the samples its step response is the continuous one."""
    b, a, _ = signal.cont2discrete((num, den), 1.0 / rate_hz, method="zoh")
    gyro = signal.lfilter(np.ravel(b), a, setpoint)
    shift = int(round(delay_s * rate_hz))
    return np.concatenate([np.zeros(shift), gyro[: len(gyro) - shift]])


def _noisy(gyro: np.ndarray, seed: int, rate_hz: float = RATE_HZ) -> np.ndarray:
    """Gyro noise (5 deg/s RMS, white) and a slow disturbance (5 deg/s RMS below 2 Hz, wind):
    about what a real 5-inch log leaves unexplained by its sticks."""
    rng = np.random.default_rng(seed)
    b, a = signal.butter(2, 2.0, fs=rate_hz)
    slow = signal.lfilter(b, a, rng.standard_normal(len(gyro)))
    return gyro + 5.0 * rng.standard_normal(len(gyro)) + slow * 5.0 / slow.std()


def _second_order(zeta: float, omega: float) -> tuple[float, float, float, float]:
    """Rise time (ms), overshoot (%), settling time (5 %, ms) and time to 50 % (ms) of
    ``omega^2 / (s^2 + 2 zeta omega s + omega^2)``, from its closed-form step response."""
    t = np.arange(0.0, 0.5, 1e-5)
    damped = omega * math.sqrt(1.0 - zeta**2)
    step = 1.0 - np.exp(-zeta * omega * t) * (
        np.cos(damped * t) + zeta / math.sqrt(1.0 - zeta**2) * np.sin(damped * t)
    )
    rise = t[np.argmax(step >= 0.9)] - t[np.argmax(step >= 0.1)]
    overshoot = 100.0 * math.exp(-math.pi * zeta / math.sqrt(1.0 - zeta**2))
    settling = t[np.flatnonzero(np.abs(step - 1.0) > 0.05)[-1]]
    return rise * 1e3, overshoot, settling * 1e3, t[np.argmax(step >= 0.5)] * 1e3


def _estimated(gyro: np.ndarray, setpoint: np.ndarray | None = None) -> StepResponse:
    result = step_response(_pilot() if setpoint is None else setpoint, gyro, RATE_HZ)
    assert result is not None
    return result


def test_a_first_order_lag_reads_its_rise_time_gain_and_no_overshoot() -> None:
    tau_s = 0.015
    result = _estimated(_fly(_pilot(), [1.0], [tau_s, 1.0]))
    assert result.rise_time_ms == pytest.approx(math.log(9.0) * tau_s * 1e3, rel=0.05)
    assert result.delay_ms == pytest.approx(math.log(2.0) * tau_s * 1e3, abs=1.0)
    assert result.overshoot_pct < 2.0
    assert result.steady_level == pytest.approx(1.0, abs=0.03)
    # 60 s, 1 s windows every 0.25 s, and the pilot moves the stick in every one of them.
    assert result.windows == 237
    assert result.time_s[0] == 0.0
    assert np.diff(result.time_s) == pytest.approx(1.0 / RATE_HZ)
    assert len(result.time_s) == len(result.response) == 500
    assert not result.response.flags.writeable


def test_a_second_order_loop_with_delay_reads_its_overshoot_and_settling() -> None:
    zeta, omega, delay_s = 0.45, 70.0, 0.003
    rise_ms, overshoot_pct, settling_ms, half_ms = _second_order(zeta, omega)
    result = _estimated(_fly(_pilot(), [omega**2], [1.0, 2 * zeta * omega, omega**2], delay_s))
    assert result.rise_time_ms == pytest.approx(rise_ms, rel=0.05)
    assert result.overshoot_pct == pytest.approx(overshoot_pct, abs=2.0)
    assert result.settling_time_ms == pytest.approx(settling_ms + delay_s * 1e3, rel=0.04)
    assert result.delay_ms == pytest.approx(half_ms + delay_s * 1e3, abs=1.5)
    assert result.steady_level == pytest.approx(1.0, abs=0.03)


@pytest.mark.parametrize("seed", [3, 4])
def test_gyro_noise_moves_the_figures_only_a_little(seed: int) -> None:
    zeta, omega = 0.45, 70.0
    rise_ms, overshoot_pct, _, _ = _second_order(zeta, omega)
    gyro = _fly(_pilot(), [omega**2], [1.0, 2 * zeta * omega, omega**2], 0.003)
    result = _estimated(_noisy(gyro, seed))
    assert result.rise_time_ms == pytest.approx(rise_ms, rel=0.1)
    assert result.overshoot_pct == pytest.approx(overshoot_pct, abs=3.0)
    tau_s = 0.015
    lag = _estimated(_noisy(_fly(_pilot(), [1.0], [tau_s, 1.0]), seed))
    assert lag.rise_time_ms == pytest.approx(math.log(9.0) * tau_s * 1e3, rel=0.1)
    assert lag.overshoot_pct < 3.0


def test_a_gain_below_one_is_the_steady_level_and_the_figures_are_relative_to_it() -> None:
    zeta, omega = 0.4, 90.0
    rise_ms, overshoot_pct, _, _ = _second_order(zeta, omega)
    result = _estimated(_fly(_pilot(), [0.8 * omega**2], [1.0, 2 * zeta * omega, omega**2]))
    assert result.steady_level == pytest.approx(0.8, abs=0.02)
    assert result.rise_time_ms == pytest.approx(rise_ms, rel=0.1)
    assert result.overshoot_pct == pytest.approx(overshoot_pct, abs=2.0)


def test_a_fast_quad_is_told_from_a_slow_one() -> None:
    fast = _estimated(_fly(_pilot(), [1.0], [0.010, 1.0], 0.002))
    slow = _estimated(_fly(_pilot(), [1.0], [0.025, 1.0], 0.002))
    # 2.5 times the time constant: 2.5 times the rise time (a 1 s window reads the slow
    # one's a little short, see the module docstring).
    assert 2.0 < slow.rise_time_ms / fast.rise_time_ms < 2.7
    damped = _estimated(_fly(_pilot(), [50.0**2], [1.0, 2 * 0.7 * 50.0, 50.0**2]))
    springy = _estimated(_fly(_pilot(), [50.0**2], [1.0, 2 * 0.3 * 50.0, 50.0**2]))
    assert damped.overshoot_pct < 8.0 < 30.0 < springy.overshoot_pct


def test_other_sample_rates_read_the_same_response() -> None:
    zeta, omega = 0.45, 70.0
    rise_ms, overshoot_pct, _, _ = _second_order(zeta, omega)
    for rate_hz in (500.0, 2000.0):
        setpoint = _pilot(rate_hz)
        gyro = _fly(setpoint, [omega**2], [1.0, 2 * zeta * omega, omega**2], 0.004, rate_hz)
        result = step_response(setpoint, gyro, rate_hz)
        assert result is not None
        assert result.rise_time_ms == pytest.approx(rise_ms, rel=0.06), rate_hz
        assert result.overshoot_pct == pytest.approx(overshoot_pct, abs=2.0), rate_hz
        assert len(result.response) == int(0.5 * rate_hz)


def test_an_idle_stick_gives_no_response() -> None:
    rng = np.random.default_rng(5)
    n = int(DURATION_S * RATE_HZ)
    # Hover corrections of a few deg/s, then a turn held at a steady 100 deg/s: neither moves
    # the stick by 20 deg/s within a window.
    hover = np.cumsum(rng.standard_normal(n)) * 0.02
    hover -= hover.mean()
    for setpoint in (hover, np.full(n, 100.0), np.zeros(n)):
        gyro = _noisy(_fly(setpoint, [1.0], [0.015, 1.0]), seed=6)
        assert step_response(setpoint, gyro, RATE_HZ) is None
    # Far from zero is not enough: the stick has to move (and here the gyro follows it well).
    turn = 100.0 + hover
    assert np.ptp(turn) < 20.0 < np.abs(turn).min()
    assert step_response(turn, _fly(turn, [1.0], [0.015, 1.0]), RATE_HZ) is None
    # Shorter than one window.
    assert step_response(_pilot()[:900], _pilot()[:900], RATE_HZ) is None


def test_windows_with_nan_are_skipped_not_bridged() -> None:
    tau_s = 0.015
    setpoint = _pilot().copy()
    gyro = _fly(_pilot(), [1.0], [tau_s, 1.0])
    gaps = [(5_000, 5_300), (20_000, 20_010), (41_500, 43_000)]
    for first, end in gaps[:2]:
        gyro[first:end] = np.nan
    setpoint[gaps[2][0] : gaps[2][1]] = np.nan
    result = _estimated(gyro, setpoint)
    starts = range(0, len(gyro) - 1000 + 1, 250)
    clean = [s for s in starts if all(end <= s or first >= s + 1000 for first, end in gaps)]
    assert result.windows == len(clean) < 237
    assert result.rise_time_ms == pytest.approx(math.log(9.0) * tau_s * 1e3, rel=0.05)
    everywhere = np.full(len(gyro), np.nan)
    assert step_response(setpoint, everywhere, RATE_HZ) is None


def test_the_ground_and_a_crash_are_left_out() -> None:
    zeta, omega = 0.45, 70.0
    rise_ms, overshoot_pct, _, _ = _second_order(zeta, omega)
    gyro = _fly(_pilot(), [omega**2], [1.0, 2 * zeta * omega, omega**2], 0.003)
    # On the ground for the first 3 s (the sticks move, the quad does not), and a tumble of
    # +-1500 deg/s for 1.5 s mid-flight, with the sticks still moving.
    gyro[:3000] = 0.0
    tumble_s = np.arange(1500) / RATE_HZ
    gyro[30_000:31_500] = 1500.0 * np.sin(2 * np.pi * 7.0 * tumble_s**1.5)
    result = _estimated(gyro)
    # 9 windows wholly on the ground, 3 wholly in the tumble; those partly in them may pass.
    assert result.windows <= 237 - 12
    assert result.rise_time_ms == pytest.approx(rise_ms, rel=0.05)
    assert result.overshoot_pct == pytest.approx(overshoot_pct, abs=2.0)
    assert result.steady_level == pytest.approx(1.0, abs=0.03)


def test_an_inverted_gyro_gives_no_figures() -> None:
    result = _estimated(-_fly(_pilot(), [1.0], [0.015, 1.0]))
    assert result.steady_level == pytest.approx(-1.0, abs=0.03)
    assert math.isnan(result.rise_time_ms)
    assert math.isnan(result.overshoot_pct)


def test_the_estimate_is_deterministic() -> None:
    gyro = _noisy(_fly(_pilot(), [1.0], [0.015, 1.0]), seed=7)
    first, second = _estimated(gyro), _estimated(gyro)
    assert np.array_equal(first.response, second.response)
    assert first.rise_time_ms == second.rise_time_ms


def test_series_that_cannot_be_read_are_refused() -> None:
    with pytest.raises(MetricsInputError, match="one length"):
        step_response(np.zeros(2000), np.zeros(1999), RATE_HZ)
    with pytest.raises(MetricsInputError, match="rate_hz"):
        step_response(np.zeros(2000), np.zeros(2000), 0.0)
    with pytest.raises(MetricsInputError, match="response_s"):
        step_response(np.zeros(2000), np.zeros(2000), RATE_HZ, response_s=2.0)
