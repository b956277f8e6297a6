"""A quad drawn per episode: every profile drawn, the spreads inside their range, the same
for a seed, and the physics' swap flies the new quad exactly as a fresh one."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from support.fake_builds import fake_lockstep_build  # noqa: E402

from bfsitl.errors import EnvironmentConfigError, VehicleProfileError  # noqa: E402
from bfsitl.gym.env import HoverEnv  # noqa: E402
from bfsitl.gym.random_vehicle import RandomVehicle  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402
from bfsitl.physics import IRIS, Simulator  # noqa: E402
from bfsitl.vehicles import load_vehicle  # noqa: E402

FIVE_INCH = load_vehicle("5inch-freestyle")


def test_every_profile_is_drawn_and_the_same_seed_draws_the_same_quad() -> None:
    many = RandomVehicle.named("iris", "5inch-freestyle", "7inch-longrange")
    names = {many.draw(np.random.default_rng(seed)).name for seed in range(60)}
    assert names == {"iris", "5inch-freestyle", "7inch-longrange"}
    rng = np.random.default_rng
    assert many.draw(rng(3)) == many.draw(rng(3))
    # No spread: the profile itself, unchanged.
    assert RandomVehicle((FIVE_INCH,)).draw(rng(0)) is FIVE_INCH


def test_the_spreads_scale_mass_inertia_and_thrust_within_their_range() -> None:
    spread = RandomVehicle((FIVE_INCH,), mass_spread=0.2, thrust_spread=0.1)
    quads = [spread.draw(np.random.default_rng(seed)) for seed in range(300)]
    mass_k = [q.mass_kg / FIVE_INCH.mass_kg for q in quads]
    thrust_k = [
        q.thrust_coefficient_n_per_rad2_s2 / FIVE_INCH.thrust_coefficient_n_per_rad2_s2
        for q in quads
    ]
    assert 0.8 <= min(mass_k) < 0.82 and 1.18 < max(mass_k) <= 1.2
    assert 0.9 <= min(thrust_k) < 0.91 and 1.09 < max(thrust_k) <= 1.1
    for quad, k in zip(quads, mass_k, strict=True):
        assert quad.inertia_kg_m2 == pytest.approx([j * k for j in FIVE_INCH.inertia_kg_m2])
        assert quad.name.startswith("5inch-freestyle (mass x")
    # The mass and the thrust are drawn apart: not one factor for both.
    assert np.corrcoef(mass_k, thrust_k)[0, 1] < 0.3


def test_a_swapped_vehicle_flies_exactly_as_a_fresh_simulator_of_it() -> None:
    start = {"position_ned_m": (0.0, 0.0, -20.0), "roll_deg": 10.0, "pitch_deg": -5.0}
    motors = (0.45, 0.5, 0.55, 0.5)
    swapped = Simulator(IRIS)
    for _ in range(100):
        swapped.step(motors, 0.001)
    swapped.set_vehicle(FIVE_INCH)
    swapped.reset(**start)  # type: ignore[arg-type]
    fresh = Simulator(FIVE_INCH)
    fresh.reset(**start)  # type: ignore[arg-type]
    iris = Simulator(IRIS)
    iris.reset(**start)  # type: ignore[arg-type]
    for sim in (swapped, fresh, iris):
        for _ in range(500):
            sim.step(motors, 0.001)
    assert swapped.params is FIVE_INCH
    for field in ("position_ned_m", "quaternion_wxyz", "angular_velocity_frd_rad_s"):
        assert getattr(swapped.state, field) == getattr(fresh.state, field)
        # The swap is what made the difference: IRIS flies the same half second otherwise.
        assert getattr(iris.state, field) != getattr(fresh.state, field)
    # The sensors read the new quad too (its specific force, not a cached reading).
    assert swapped.specific_force_frd_m_s2 == fresh.specific_force_frd_m_s2


def test_bad_random_vehicles_are_refused_with_what_they_take(tmp_path: Path) -> None:
    with pytest.raises(EnvironmentConfigError, match="one or more vehicles"):
        RandomVehicle(())
    with pytest.raises(EnvironmentConfigError, match="one or more vehicles"):
        RandomVehicle(("iris",))  # type: ignore[arg-type]
    with pytest.raises(EnvironmentConfigError, match=r"mass_spread 0.6 is outside 0..0.5"):
        RandomVehicle((IRIS,), mass_spread=0.6)
    with pytest.raises(VehicleProfileError):
        RandomVehicle.named("iris", "no-such-quad")
    sitl = SitlLaunch(firmware=fake_lockstep_build(tmp_path))
    with pytest.raises(EnvironmentConfigError, match="random_vehicle must be a RandomVehicle"):
        HoverEnv(sitl=sitl, random_vehicle="iris")
    env = HoverEnv(sitl=sitl, random_vehicle=RandomVehicle((IRIS, FIVE_INCH)))
    try:
        assert env.random_vehicle == RandomVehicle((IRIS, FIVE_INCH))
        assert dataclasses.replace(env.world).quad is IRIS  # the world's quad stays
    finally:
        env.close()
