"""The fit against flights whose physics is known: the shipped profiles flown by the embedded
physics (tests/support/synthetic_flight.py), fitted back, replayed, and broken on purpose.

What would fail: a regressor one step off in time (the spin-up reaction was, and biased the
yaw by 8 %), a wrong sign or motor order in the mixer's signs, a motor model that is not the
physics', a replay that compares the wrong frames, a profile that does not carry the fitted
figures into the physics.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from support.synthetic_flight import synthetic_flight

from bfsitl.errors import FitError
from bfsitl.fit.fitted_profile import effectiveness_of, fitted_spec, spec_beta
from bfsitl.fit.log_data import FlightData
from bfsitl.fit.noise_floor import noise_floor
from bfsitl.fit.replay import hold_score, replay, score
from bfsitl.fit.rotation import fit_rotation
from bfsitl.fit.thrust import fit_thrust, hover_command
from bfsitl.fit.windows import train_and_test
from bfsitl.physics.params import IRIS
from bfsitl.vehicles import VehicleSpec, quad_params, read_profile, shipped_profiles, write_profile

PROFILES = ("5inch-freestyle", "3inch-cinewhoop")


@pytest.fixture(scope="module", params=PROFILES)
def flown(request: pytest.FixtureRequest) -> tuple[VehicleSpec, FlightData]:
    spec = shipped_profiles()[request.param]
    return spec, synthetic_flight(quad_params(spec))


def test_a_known_quad_is_fitted_back_within_five_percent(
    flown: tuple[VehicleSpec, FlightData],
) -> None:
    spec, data = flown
    train, _ = train_and_test(data)
    rotation = fit_rotation(data, train, spec_beta(spec))
    thrust = fit_thrust(data, rotation.time_constant_s, spec_beta(spec))
    assert rotation.time_constant_s * 1000 == pytest.approx(spec.motor_time_constant_ms, rel=0.05)
    for axis, truth in enumerate(effectiveness_of(spec)):
        assert rotation.axis(axis).effectiveness.value == pytest.approx(truth, rel=0.05), axis
    assert thrust.thrust_to_weight.value == pytest.approx(spec.thrust_to_weight, rel=0.05)
    assert not rotation.props_out
    # The rigid body's own coupling on yaw is (I_xx - I_yy) / I_zz.
    ixx, iyy, izz = spec.inertia_kg_m2
    assert rotation.yaw.coupling == pytest.approx((ixx - iyy) / izz, abs=0.02)
    assert hover_command(data) == pytest.approx(quad_params(spec).hover_command, abs=0.02)


def test_the_fitted_profile_carries_the_figures_into_the_physics(
    flown: tuple[VehicleSpec, FlightData], tmp_path: Path
) -> None:
    spec, data = flown
    train, test = train_and_test(data)
    rotation = fit_rotation(data, train, spec_beta(spec))
    thrust = fit_thrust(data, rotation.time_constant_s, spec_beta(spec))
    fitted = fitted_spec(
        spec, name="mine", mass_g=spec.mass_g, label="synthetic", rotation=rotation, thrust=thrust
    )
    path = tmp_path / "mine.toml"
    write_profile(fitted, path)
    assert read_profile(path) == fitted
    assert spec_beta(fitted) == pytest.approx(spec_beta(spec), rel=1e-3)
    for axis, value in enumerate(effectiveness_of(fitted)):
        assert value == pytest.approx(rotation.axis(axis).effectiveness.value, rel=1e-3)
    assert "stated by the user" in fitted.sources["mass_g"]
    assert "fitted from synthetic" in fitted.sources["inertia_kg_m2"]
    # The fitted quad replays what the fit never saw about as well as the true one.
    fitted_score = score(replay(data, test, quad_params(fitted)), data.dt_s)
    true_score = score(replay(data, test, quad_params(spec)), data.dt_s)
    for axis in range(3):
        assert fitted_score.rates[axis] < true_score.rates[axis] + 0.05


def test_the_replay_tells_the_right_quad_from_a_wrong_one(
    flown: tuple[VehicleSpec, FlightData],
) -> None:
    spec, data = flown
    _, test = train_and_test(data)
    right = score(replay(data, test, quad_params(spec)), data.dt_s)
    wrong = score(replay(data, test, IRIS), data.dt_s)
    held = hold_score(data, test)
    for axis in range(3):
        # The true quad replays within a few hundredths: a replay one frame off in its start
        # or its comparison scores 0.05-0.07 here.
        assert right.rates[axis] < 0.035, (axis, right)
        assert wrong.rates[axis] > 3 * right.rates[axis], (axis, wrong, right)
    assert held.rates[0] > 0.5 and held.rates[1] > 0.5


def _broken(data: FlightData, **changes: np.ndarray) -> FlightData:
    return dataclasses.replace(data, **changes)


def test_a_pitch_sign_read_the_wrong_way_is_refused(
    flown: tuple[VehicleSpec, FlightData],
) -> None:
    spec, data = flown
    flipped = data.gyro_frd_rad_s * np.array([[1.0], [-1.0], [1.0]])
    train, _ = train_and_test(data)
    with pytest.raises(FitError, match="the pitch rates do not follow the motors"):
        fit_rotation(_broken(data, gyro_frd_rad_s=flipped), train, spec_beta(spec))


def test_motors_in_the_wrong_order_do_not_fit(flown: tuple[VehicleSpec, FlightData]) -> None:
    spec, data = flown
    train, _ = train_and_test(data)
    swapped = data.motors[[1, 0, 2, 3]]  # M1 and M2 exchanged: pitch and yaw turn round
    with pytest.raises(FitError, match="rates do not follow the motors|hardly follow"):
        fit_rotation(_broken(data, motors=swapped), train, spec_beta(spec))


def test_a_yaw_the_other_way_round_reads_as_props_out(
    flown: tuple[VehicleSpec, FlightData],
) -> None:
    spec, data = flown
    flipped = data.gyro_frd_rad_s * np.array([[1.0], [1.0], [-1.0]])
    train, _ = train_and_test(data)
    rotation = fit_rotation(_broken(data, gyro_frd_rad_s=flipped), train, spec_beta(spec))
    assert rotation.props_out


def test_too_little_flight_is_one_clear_line(flown: tuple[VehicleSpec, FlightData]) -> None:
    spec, data = flown
    short = data.usable.copy()
    short[int(4.0 / data.dt_s) :] = False
    train, _ = train_and_test(_broken(data, usable=short))
    with pytest.raises(FitError) as caught:
        fit_rotation(_broken(data, usable=short), train, spec_beta(spec))
    assert "windows of usable flight" in str(caught.value) and "\n" not in str(caught.value)


def test_the_noise_floor_reads_the_noise_that_was_added(
    flown: tuple[VehicleSpec, FlightData],
) -> None:
    _, data = flown
    quiet = noise_floor(data)
    assert max(quiet.gyro_deg_s) < 0.2 and quiet.calm_s > 1.0 and quiet.above_hz == 100.0
    rng = np.random.default_rng(7)
    # White noise of 1 deg/s: 80 % of its power lies above 100 Hz at a 1 kHz log.
    noisy_gyro = data.gyro_frd_rad_s + np.radians(rng.normal(0.0, 1.0, data.gyro_frd_rad_s.shape))
    noisy = noise_floor(_broken(data, gyro_frd_rad_s=noisy_gyro))
    for axis in range(3):
        assert noisy.gyro_deg_s[axis] == pytest.approx(0.89, abs=0.08), noisy
