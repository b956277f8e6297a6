"""A wind drawn anew for every episode, so that a policy learns to fly in any of them.

``RandomWind(max_speed_m_s=3.0, max_gust_m_s=1.5)`` gives each episode a horizontal wind of
a speed drawn uniformly from 0 to ``max_speed_m_s``, from a direction drawn uniformly round
the compass, gusting with a standard deviation drawn uniformly from 0 to ``max_gust_m_s``,
all from the episode's generator (the same seed, the same winds).  The environment turns it
on when the policy gets the sticks (after the take-off, which flies in the world's own wind,
or at the hand's release or throw), so a start is never disturbed by it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bfsitl.errors import EnvironmentConfigError
from bfsitl.physics.wind import Wind

#: The strongest wind worth drawing for a quad the size of those bfsitl flies.
MAX_RANDOM_WIND_M_S = 15.0


@dataclass(frozen=True)
class RandomWind:
    """The range each episode's wind is drawn from (module docstring)."""

    max_speed_m_s: float = 3.0
    max_gust_m_s: float = 1.5

    def __post_init__(self) -> None:
        for name in ("max_speed_m_s", "max_gust_m_s"):
            value = getattr(self, name)
            if not 0.0 <= value <= MAX_RANDOM_WIND_M_S:
                raise EnvironmentConfigError(
                    f"RandomWind.{name} {value} is outside 0..{MAX_RANDOM_WIND_M_S:g} m/s"
                )

    def draw(self, rng: np.random.Generator) -> Wind:
        speed_m_s = float(rng.uniform(0.0, self.max_speed_m_s))
        from_deg = float(rng.uniform(0.0, 360.0))
        gust_m_s = float(rng.uniform(0.0, self.max_gust_m_s))
        return Wind.from_direction(speed_m_s, from_deg, gust_m_s)
