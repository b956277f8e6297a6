"""ANGLE mode's stick -> angle curve (the firmware's Actual rates) and its inverse."""

from __future__ import annotations

import random

import pytest

from bfsitl.control.angle_sticks import ActualRates, AngleStickMap
from bfsitl.errors import UnsupportedFirmwareError
from bfsitl.protocol import messages as msg

DEFAULT = ActualRates(rc_rate=7, rate=67, expo=0)  # 4.6.0 and master controlrate_profile.c


def test_the_default_curve_is_the_firmwares():
    # applyActualRates: x * 70 + 600 * x|x|; full stick 670 deg/s.
    assert DEFAULT.setpoint(1.0) == pytest.approx(670.0)
    assert DEFAULT.setpoint(0.3) == pytest.approx(0.3 * 70 + 600 * 0.09)
    assert DEFAULT.setpoint(-0.3) == pytest.approx(-DEFAULT.setpoint(0.3))
    # What made a linear assumption three times too weak: a third of the stick is 6.7 deg.
    angles = AngleStickMap(DEFAULT, DEFAULT, 60.0)
    assert angles.angle_deg("pitch", 1500 + 0.3 * 500) == pytest.approx(6.72, abs=0.01)


@pytest.mark.parametrize("rates", [DEFAULT, ActualRates(10, 50, 40), ActualRates(67, 67, 0)])
@pytest.mark.parametrize("angle", [-40.0, -7.5, -0.2, 0.0, 3.0, 12.0, 59.0])
def test_the_inverse_gives_the_stick_that_holds_the_angle(rates, angle):
    angles = AngleStickMap(rates, rates, 60.0)
    for axis in ("roll", "pitch"):
        stick = angles.stick_us(axis, angle)
        assert 1000.0 <= stick <= 2000.0
        assert angles.angle_deg(axis, stick) == pytest.approx(angle, abs=1e-6)


def test_beyond_the_limit_is_full_stick_and_linear_is_a_line():
    angles = AngleStickMap.linear(60.0)
    assert angles.stick_us("roll", 90.0) == pytest.approx(2000.0)
    assert angles.stick_us("roll", -15.0) == pytest.approx(1375.0)


def test_made_from_the_fcs_replies_and_other_rate_types_are_refused():
    tuning = msg.RcTuning(7, 0, 67, 68, 67, 0, 7, 8, 5, msg.RcTuning.ACTUAL)
    angles = AngleStickMap.from_replies(tuning, msg.PidAdvanced(55))
    assert angles.angle_limit_deg == 55.0
    assert (angles.pitch.rc_rate, angles.pitch.rate, angles.pitch.expo) == (8, 68, 5)
    with pytest.raises(UnsupportedFirmwareError, match="rates_type = ACTUAL"):
        AngleStickMap.from_replies(
            msg.RcTuning(7, 0, 67, 67, 67, 0, 7, 7, 0, 0), msg.PidAdvanced(60)
        )


def test_the_replies_decode_at_the_firmwares_offsets():
    # As 4.6.0 and master answered, with distinct rates put in.
    payload = bytes(
        [7, 1, 67, 68, 69, 0, 50, 0, 0, 0, 2, 9, 8, 3, 0, 100, 206, 7, 206, 7, 206, 7, 3, 50]
    )
    tuning = msg.RcTuning.decode(payload)
    assert (
        tuning.roll_rc_rate,
        tuning.roll_expo,
        tuning.roll_rate,
        tuning.pitch_rate,
        tuning.yaw_rate,
        tuning.yaw_expo,
        tuning.yaw_rc_rate,
        tuning.pitch_rc_rate,
        tuning.pitch_expo,
        tuning.rates_type,
    ) == (7, 1, 67, 68, 69, 2, 9, 8, 3, 3)
    advanced = bytes(17) + bytes([60, 0, 0, 0, 80]) + bytes(39)  # the SITLs' first bytes
    assert msg.PidAdvanced.decode(advanced).angle_limit_deg == 60


def bisect_share(rates: ActualRates, rate_deg_s: float) -> float:
    """The inversion as defined: 40 halvings of share() (what deflection_for once did)."""
    full = rates.setpoint(1.0)
    if full <= 0:
        return 0.0
    wanted = max(-1.0, min(1.0, rate_deg_s / full))
    sign = 1.0 if wanted >= 0 else -1.0
    low, high = 0.0, 1.0
    for _ in range(40):
        mid = 0.5 * (low + high)
        if rates.share(mid) < abs(wanted):
            low = mid
        else:
            high = mid
    return sign * 0.5 * (low + high)


@pytest.mark.parametrize(
    "curve", [(7, 67, 0), (100, 67, 0), (1, 200, 50), (20, 80, 30), (12, 50, 100), (0, 0, 0)]
)
def test_the_inversion_agrees_with_halving_share_and_inverts_the_curve(
    curve: tuple[int, int, int],
) -> None:
    """Newton's steps land where 40 halvings of share() do (within the halvings' own width,
    2^-40), and the curve at that stick gives the rate asked for: a microsecond of stick is
    2e-3 of the range, nine orders of magnitude above the difference."""
    rates = ActualRates(*curve)
    rng = random.Random(sum(curve))
    full = rates.setpoint(1.0)
    for rate in [0.0, -0.0, 670.0, -670.0, 1e-9] + [rng.uniform(-900, 900) for _ in range(2000)]:
        stick = rates.deflection_for(rate)
        assert stick == pytest.approx(bisect_share(rates, rate), abs=2e-12)
        if full > 0:
            wanted = max(-full, min(full, rate))
            assert rates.setpoint(stick) == pytest.approx(wanted, abs=1e-9 * full)
