"""Wind: a constant air velocity plus first-order Gauss-Markov gusts per NED axis.

:class:`Wind` is the description (what a user, a scenario's ``[wind]`` or a ``wind`` fault
gives); the physics (``bfsitl/kernel/physics.c``) draws its gusts from the run's seed, so a run
repeats, and acts on the vehicle through body drag and rotor inflow.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError
from bfsitl.physics.params import Vec3

#: The one range every way of giving a wind accepts: ``bfsitl fly --wind/--gusts``, a scenario's
#: ``[wind]`` table and the ``wind`` fault all check against these (through :class:`Wind`).
MAX_WIND_COMPONENT_M_S = 50.0
MAX_GUST_STD_M_S = 20.0
MIN_GUST_TIME_CONSTANT_S = 0.1
MAX_GUST_TIME_CONSTANT_S = 60.0


@dataclass(frozen=True, slots=True)
class Wind:
    """Air velocity in the world: a constant part plus a gust (first-order Gauss-Markov).

    The gust of each NED axis is an exponentially correlated random process with standard
    deviation ``gust_std_m_s`` and correlation time ``gust_time_constant_s``, drawn from the
    simulator's seed, so a run is repeatable.  Wind acts through body drag and rotor inflow.

    Attributes:
        velocity_ned_m_s: The constant part: the air's velocity north, east and down, metres
            per second (each within +-50).
        gust_std_m_s: The gusts' standard deviation on each axis, metres per second (0 to
            20; 0 is no gusts).
        gust_time_constant_s: How long a gust lasts: the correlation time, seconds (0.1 to
            60).

    Raises:
        SimInputError: A value outside its range or not finite.
    """

    velocity_ned_m_s: Vec3 = (0.0, 0.0, 0.0)
    gust_std_m_s: float = 0.0
    gust_time_constant_s: float = 2.0

    def __post_init__(self) -> None:
        if len(self.velocity_ned_m_s) != 3 or not all(
            math.isfinite(v) and abs(v) <= MAX_WIND_COMPONENT_M_S for v in self.velocity_ned_m_s
        ):
            raise SimInputError(
                f"Wind: velocity_ned_m_s must be 3 numbers within "
                f"+-{MAX_WIND_COMPONENT_M_S:g} m/s, got {self.velocity_ned_m_s!r}"
            )
        if not (math.isfinite(self.gust_std_m_s) and 0 <= self.gust_std_m_s <= MAX_GUST_STD_M_S):
            raise SimInputError(
                f"Wind: gust_std_m_s must be in 0..{MAX_GUST_STD_M_S:g} m/s, "
                f"got {self.gust_std_m_s}"
            )
        if not (
            math.isfinite(self.gust_time_constant_s)
            and MIN_GUST_TIME_CONSTANT_S <= self.gust_time_constant_s <= MAX_GUST_TIME_CONSTANT_S
        ):
            raise SimInputError(
                f"Wind: gust_time_constant_s must be in {MIN_GUST_TIME_CONSTANT_S:g}.."
                f"{MAX_GUST_TIME_CONSTANT_S:g} s, got {self.gust_time_constant_s}"
            )

    @classmethod
    def from_direction(
        cls, speed_m_s: float, from_deg: float = 0.0, gust_std_m_s: float = 0.0
    ) -> Wind:
        """A horizontal wind blowing FROM a direction (the meteorological convention).

        Args:
            speed_m_s: The wind's speed, metres per second.
            from_deg: Where it blows from, degrees clockwise from north: 0 is from the north
                (the air moves south), 90 from the east.
            gust_std_m_s: The gusts' standard deviation on each axis, metres per second.

        Returns:
            The wind, with the default gust time constant.

        Raises:
            SimInputError: A negative speed, or a value that is not finite.
        """
        if not (math.isfinite(speed_m_s) and speed_m_s >= 0):
            raise SimInputError(f"Wind: speed must be >= 0 m/s, got {speed_m_s}")
        if not math.isfinite(from_deg):
            raise SimInputError(f"Wind: direction must be finite, got {from_deg}")
        heading = math.radians(from_deg)
        return cls(
            (-speed_m_s * math.cos(heading), -speed_m_s * math.sin(heading), 0.0), gust_std_m_s
        )
