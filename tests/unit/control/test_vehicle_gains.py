"""The controllers' defaults carried over to another quad: unchanged on IRIS, and on a light
5-inch they fly the take-off that the IRIS defaults botch."""

from __future__ import annotations

import dataclasses

import pytest
from support.altitude_plant import AltitudePlant

from bfsitl.backend.options import DEFAULT_ACCEL_NOISE_M_S2, DEFAULT_BARO_NOISE_PA
from bfsitl.control import GAINS, LandingGains, make_controller, make_landing
from bfsitl.control.metrics import step_response
from bfsitl.control.vehicle_gains import vehicle_gains
from bfsitl.mission.plan import MissionPlan
from bfsitl.physics import IRIS
from bfsitl.vehicles import hover_throttle_us, load_vehicle, stick_per_acceleration_us

FIVE_INCH = load_vehicle("5inch-freestyle")


@pytest.mark.parametrize("gains_type", [*GAINS.values(), LandingGains])
def test_on_iris_nothing_changes(gains_type: type) -> None:
    assert vehicle_gains(gains_type, IRIS) == {}


def test_on_iris_the_controllers_are_made_as_before() -> None:
    for name in GAINS:
        assert make_controller(name, quad=IRIS).gains == make_controller(name).gains  # type: ignore[attr-defined]
    assert make_landing(IRIS).gains == make_landing().gains


def test_on_a_5_inch_the_levels_sit_about_its_hover_and_the_feedforward_is_its_own() -> None:
    gains = make_controller("fused", quad=FIVE_INCH).gains  # type: ignore[attr-defined]
    hover_us = hover_throttle_us(FIVE_INCH)
    assert gains.hover_min_us < gains.hover_guess_us < hover_us < gains.hover_max_us
    # The spool starts as far below the hover, in thrust, as IRIS's 1480 below its 1545.
    assert (hover_us - gains.hover_guess_us) / (hover_us - 1000) == pytest.approx(65 / 545)
    assert gains.accel_ff_us == pytest.approx(
        28.0 * stick_per_acceleration_us(FIVE_INCH) / stick_per_acceleration_us(IRIS)
    )
    # A --gain given by the user wins over the carried-over default.
    mine = make_controller("fused", {"hover_guess_us": 1150}, quad=FIVE_INCH)
    assert mine.gains.hover_guess_us == 1150  # type: ignore[attr-defined]
    assert dataclasses.asdict(make_landing(FIVE_INCH).gains)["hover_max_us"] < 1545


def _take_off(controller: object) -> tuple[float, float]:
    plant = AltitudePlant(
        quad=FIVE_INCH,
        baro_noise_pa=DEFAULT_BARO_NOISE_PA,
        accel_noise_m_s2=DEFAULT_ACCEL_NOISE_M_S2,
    )
    trace = plant.fly(
        controller,  # type: ignore[arg-type]
        target_alt_m=2.0,
        duration_s=10.0,
        ground_s=MissionPlan().ground_s,
    )
    metrics = step_response(trace.time_s, trace.true_alt_m, target_m=2.0)
    return metrics.overshoot_pct, max(trace.true_alt_m)


def test_the_carried_over_defaults_fly_a_5_inch_take_off_the_iris_defaults_overshoot() -> None:
    carried_overshoot_pct, carried_peak_m = _take_off(make_controller("fused", quad=FIVE_INCH))
    iris_overshoot_pct, iris_peak_m = _take_off(make_controller("fused"))
    assert carried_overshoot_pct < 5.0 and carried_peak_m < 2.1
    # IRIS's spool starts at 1480 us, far above a 5-inch's hover: it leaps.
    assert iris_peak_m > carried_peak_m + 0.3
