"""A quad drawn anew for every episode, so that a policy learns to fly more than one.

``RandomVehicle.named("iris", "5inch-freestyle", "7inch-longrange")`` gives each episode one
of those vehicles (:func:`bfsitl.vehicles.load_vehicle`: a shipped name or a profile file),
drawn uniformly from the episode's generator (the same seed, the same quads), and may scale
each one's mass and motor thrust by factors drawn uniformly within ``mass_spread`` and
``thrust_spread`` (0.1: 0.9 to 1.1 times), for the quads between the profiles.

The firmware is the same for all of them (one provisioned EEPROM, stock settings), as one
flight controller moved from frame to frame would be: a warm reset swaps the quad in the
physics (:meth:`~bfsitl.physics.multirotor.Simulator.set_vehicle`) while the hand holds it,
and a cold one boots the firmware with it.  The environment's ``world.quad`` stays what the
observation's scales and an exported policy's throttle centre are reckoned from; the episode's
own quad is in ``info["vehicle"]``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from bfsitl.errors import EnvironmentConfigError
from bfsitl.physics.params import QuadParams
from bfsitl.vehicles import load_vehicle

#: The widest spread worth drawing: beyond it a profile of its own says more.
MAX_SPREAD = 0.5


@dataclass(frozen=True)
class RandomVehicle:
    """The vehicles each episode's quad is drawn from, and the spread about each (module
    docstring)."""

    quads: tuple[QuadParams, ...]
    mass_spread: float = 0.0
    thrust_spread: float = 0.0

    def __post_init__(self) -> None:
        if not self.quads or not all(isinstance(quad, QuadParams) for quad in self.quads):
            raise EnvironmentConfigError(
                "RandomVehicle.quads must be one or more vehicles' physics "
                "(RandomVehicle.named('iris', '5inch-freestyle') loads them by name)"
            )
        for name in ("mass_spread", "thrust_spread"):
            value = getattr(self, name)
            if not 0.0 <= value <= MAX_SPREAD:
                raise EnvironmentConfigError(
                    f"RandomVehicle.{name} {value} is outside 0..{MAX_SPREAD:g} "
                    f"(a share either side of the profile's own)"
                )

    @classmethod
    def named(
        cls, *names: str | Path, mass_spread: float = 0.0, thrust_spread: float = 0.0
    ) -> RandomVehicle:
        """The vehicles by name (``bfsitl vehicles``) or profile file.

        Raises:
            VehicleProfileError: A name that is neither a vehicle nor a readable profile.
        """
        quads = tuple(load_vehicle(name) for name in names)
        return cls(quads, mass_spread=mass_spread, thrust_spread=thrust_spread)

    def draw(self, rng: np.random.Generator) -> QuadParams:
        """One episode's quad: a profile, then its mass and thrust scaled within the spreads
        (always three draws, so a spread changes no other episode's profile)."""
        quad = self.quads[int(rng.integers(len(self.quads)))]
        mass_k = float(rng.uniform(1.0 - self.mass_spread, 1.0 + self.mass_spread))
        thrust_k = float(rng.uniform(1.0 - self.thrust_spread, 1.0 + self.thrust_spread))
        if mass_k == 1.0 and thrust_k == 1.0:
            return quad
        return replace(
            quad,
            name=f"{quad.name} (mass x{mass_k:.2f}, thrust x{thrust_k:.2f})",
            mass_kg=quad.mass_kg * mass_k,
            # The inertia goes with the mass (the same frame, heavier or lighter throughout).
            inertia_kg_m2=(
                quad.inertia_kg_m2[0] * mass_k,
                quad.inertia_kg_m2[1] * mass_k,
                quad.inertia_kg_m2[2] * mass_k,
            ),
            thrust_coefficient_n_per_rad2_s2=quad.thrust_coefficient_n_per_rad2_s2 * thrust_k,
        )
