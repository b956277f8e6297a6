"""Step-response metrics against signals whose answers are known in closed form."""

from __future__ import annotations

import math

import pytest

from bfsitl.control.metrics import step_response
from bfsitl.errors import BfsitlError, MetricsInputError

DT = 0.001


def _times(duration_s: float) -> list[float]:
    return [i * DT for i in range(int(duration_s / DT) + 1)]


def first_order(tau_s: float, target: float = 2.0, duration_s: float = 20.0):
    t = _times(duration_s)
    return t, [target * (1.0 - math.exp(-x / tau_s)) for x in t]


def second_order(zeta: float, wn: float, target: float = 2.0, duration_s: float = 30.0):
    wd = wn * math.sqrt(1 - zeta * zeta)
    phi = math.acos(zeta)
    t = _times(duration_s)
    return t, [
        target
        * (1 - math.exp(-zeta * wn * x) * math.sin(wd * x + phi) / math.sqrt(1 - zeta * zeta))
        for x in t
    ]


def test_first_order_rise_settle_and_no_overshoot():
    tau = 0.8
    t, y = first_order(tau)
    m = step_response(t, y, target_m=2.0, band_m=0.05)
    assert m.rise_time_s == pytest.approx(tau * math.log(9.0), abs=2e-3)
    assert m.overshoot_pct == 0.0
    # |2 e^(-t/tau)| = 0.05  ->  t = tau ln(40)
    assert m.settling_time_s == pytest.approx(tau * math.log(40.0), abs=2e-3)
    assert m.steady_state_rms_m < 1e-6
    assert m.settled


def test_second_order_overshoot_matches_the_formula():
    zeta, wn = 0.4, 3.0
    t, y = second_order(zeta, wn)
    m = step_response(t, y, target_m=2.0)
    expected = 100 * math.exp(-math.pi * zeta / math.sqrt(1 - zeta * zeta))
    assert m.overshoot_pct == pytest.approx(expected, rel=1e-3)
    assert m.peak_alt_m == pytest.approx(2.0 * (1 + expected / 100), rel=1e-4)


def test_settling_is_the_last_entry_into_the_band():
    # In the band at 1 s, out again at 3 s (a bump), back in for good at 4 s.
    t = _times(10.0)
    y = [2.0 if x >= 1.0 else 0.0 for x in t]
    y = [v + (0.2 if 3.0 <= x < 4.0 else 0.0) for x, v in zip(t, y, strict=True)]
    m = step_response(t, y, target_m=2.0, band_m=0.05)
    assert m.settling_time_s == pytest.approx(4.0, abs=2 * DT)


def test_never_settling_is_inf_and_never_rising_is_inf():
    t = _times(5.0)
    m = step_response(t, [2.2] * len(t), target_m=2.0, start_m=0.0)
    assert m.settling_time_s == math.inf and not m.settled
    m = step_response(t, [0.1] * len(t), target_m=2.0)
    assert m.rise_time_s == math.inf


def test_step_time_moves_the_origin_of_settling():
    tau = 0.5
    t, y = first_order(tau)
    shifted = [x + 100.0 for x in t]
    a = step_response(t, y, target_m=2.0)
    b = step_response(shifted, y, target_m=2.0)
    c = step_response(shifted, y, target_m=2.0, step_time_s=99.0)
    assert b.settling_time_s == pytest.approx(a.settling_time_s, abs=1e-9)
    assert c.settling_time_s == pytest.approx(a.settling_time_s + 1.0, abs=1e-9)


def test_downward_step_is_mirrored():
    t, y = second_order(0.5, 2.0, target=1.5)
    down = [3.0 - v for v in y]  # from 3.0 down to 1.5
    up = step_response(t, y, target_m=1.5, start_m=0.0)
    m = step_response(t, down, target_m=1.5, start_m=3.0)
    assert m.overshoot_pct == pytest.approx(up.overshoot_pct, rel=1e-6)
    assert m.rise_time_s == pytest.approx(up.rise_time_s, abs=2e-3)


def test_steady_state_rms_and_bias_over_the_window_only():
    t = _times(10.0)
    # 3 cm sine around 2.0 + 1 cm bias in the last 5 s, garbage before.
    y = [(0.0 if x < 5 else 2.01 + 0.03 * math.sin(2 * math.pi * x)) for x in t]
    m = step_response(t, y, target_m=2.0, steady_window_s=5.0)
    assert m.steady_state_mean_error_m == pytest.approx(0.01, abs=1e-3)
    assert m.steady_state_rms_m == pytest.approx(math.sqrt(0.01**2 + 0.03**2 / 2), rel=1e-2)


def test_max_attitude_from_roll_and_pitch():
    t, y = first_order(0.5)
    roll = [0.0] * len(t)
    pitch = [0.0] * len(t)
    roll[10], pitch[20] = -3.5, 2.0
    m = step_response(t, y, target_m=2.0, roll_deg=roll, pitch_deg=pitch)
    assert m.max_attitude_deg == 3.5
    assert math.isnan(step_response(t, y, target_m=2.0).max_attitude_deg)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        (dict(time_s=[0.0, 1.0], altitude_m=[0.0]), "samples"),
        (dict(time_s=[0.0], altitude_m=[0.0]), "at least 2"),
        (dict(time_s=[0.0, 0.0], altitude_m=[0.0, 1.0]), "strictly increasing"),
        (dict(time_s=[0.0, 1.0], altitude_m=[0.0, math.nan]), "finite"),
        (dict(time_s=[0.0, 1.0], altitude_m=[0.0, 1.0], target_m=0.0), "differ"),
        (dict(time_s=[0.0, 1.0], altitude_m=[0.0, 1.0], band_m=0.0), "band_m"),
        (dict(time_s=[0.0, 1.0], altitude_m=[0.0, 1.0], roll_deg=[1.0]), "roll_deg"),
    ],
)
def test_bad_input_is_rejected_clearly(kwargs, message):
    kwargs.setdefault("target_m", 2.0)
    with pytest.raises(MetricsInputError, match=message) as caught:
        step_response(**kwargs)
    assert isinstance(caught.value, BfsitlError) and isinstance(caught.value, ValueError)
