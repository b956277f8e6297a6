"""Landing: descends on the rig, recognises the ground, cuts the throttle; no false touchdown."""

from __future__ import annotations

import pytest
from support.altitude_plant import AltitudePlant

from bfsitl.control.base import AltitudeInput
from bfsitl.control.cascade import CascadedAltitudeController
from bfsitl.control.landing import LandingController, LandingGains
from bfsitl.errors import ControllerConfigError


def hover_then_land(hand_over: bool):
    plant = AltitudePlant()
    flying = CascadedAltitudeController()
    plant.fly(flying, target_alt_m=2.0, duration_s=10.0, phase="hold")
    landing = LandingController(hover_from=flying if hand_over else None)
    plant.fly(
        landing, target_alt_m=0.0, duration_s=25.0, phase="land", until=lambda: landing.touched_down
    )
    return plant, landing, plant.trace.select("land")


@pytest.mark.parametrize("hand_over", [True, False])
def test_lands_gently_and_cuts_the_throttle(hand_over):
    plant, landing, trace = hover_then_land(hand_over)
    assert landing.touched_down
    assert plant.sim.on_ground
    # Slow near the ground: the skids meet it well below the mission's 2.5 m/s crash limit.
    contact = next(i for i, g in enumerate(trace.on_ground) if g)
    assert trace.true_climb_m_s[contact] > -0.6
    # Recognised soon after contact, and the throttle is then at minimum, for good.
    assert trace.time_s[-1] - trace.time_s[contact] < 3.0
    assert all(
        landing.update(AltitudeInput(trace.time_s[-1] + 0.02 * i, 0.0, 0.0, 0.0)) == 1000
        for i in range(1, 20)
    )


def test_handing_over_the_hover_estimate_avoids_the_initial_dip():
    _, _, with_hint = hover_then_land(True)
    _, _, without = hover_then_land(False)
    assert min(with_hint.true_climb_m_s) > min(without.true_climb_m_s)


def test_descent_slows_near_the_ground():
    landing = LandingController()
    g = landing.gains
    assert landing.descent_rate_m_s(5.0) == pytest.approx(g.descent_m_s)
    assert landing.descent_rate_m_s(0.1) == pytest.approx(g.slow_descent_m_s)
    assert g.slow_descent_m_s < landing.descent_rate_m_s(g.slow_below_m + 0.3) < g.descent_m_s


def test_no_touchdown_while_still_in_the_air():
    """Hovering at 1 m (the reading steady, the vehicle not descending yet) is not the ground."""
    landing = LandingController()
    landing.set_hover_estimate(1540.0)
    landing.reset(0.0)
    for i in range(1, 100):  # 2 s: the integrator moves, but not by the wind-up threshold
        landing.update(AltitudeInput(0.02 * i, 1.0, 0.0, 0.0))
    assert not landing.touched_down


def test_touchdown_from_integrator_wind_up_anywhere():
    """On a roof (the FC reads 0.8 m), commanded down but not moving: the integrator winds
    down until only the ground can explain it."""
    landing = LandingController()
    landing.set_hover_estimate(1540.0)
    landing.reset(0.0)
    outs = [landing.update(AltitudeInput(0.02 * i, 0.8, 0.0, 0.0)) for i in range(1, 1500)]
    assert landing.touched_down and outs[-1] == 1000


def test_reset_clears_the_touchdown():
    landing = LandingController()
    landing.reset(0.0)
    for i in range(1, 200):
        landing.update(AltitudeInput(0.02 * i, 0.0, 0.0, 0.0))
    assert landing.touched_down
    landing.reset(10.0)
    assert not landing.touched_down


@pytest.mark.parametrize(
    "bad",
    [
        dict(slow_descent_m_s=1.0, descent_m_s=0.5),
        dict(touchdown_hold_s=0.0),
        dict(hover_guess_us=1900.0),
        dict(rate_kp=-1.0),
    ],
)
def test_bad_gains_are_rejected(bad):
    with pytest.raises(ControllerConfigError):
        LandingGains(**bad)


def test_a_non_finite_hover_estimate_is_rejected():
    with pytest.raises(ControllerConfigError):
        LandingController().set_hover_estimate(float("nan"))
