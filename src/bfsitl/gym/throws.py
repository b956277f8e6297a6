"""Throws: how ``bfsitl/Recover-v0`` starts an episode, drawn per episode from a seed.

A hand holds the armed quad at ``height_m`` above where it armed while the FC settles, then
lets it go tumbling: tilted by up to ``max_tilt_deg`` (180 is upside down) about a horizontal
axis of random direction, at a random heading, moving at up to ``max_speed_m_s`` in a random
direction and spinning at up to ``max_rate_deg_s`` about a random axis, **its rotors
stopped**.  From that instant the policy has the sticks; the FC spins the motors up as they
ask.  Every magnitude is drawn uniformly between zero and its limit, every direction
uniformly over the sphere (over the circle for the tilt axis and the heading), so the same
seed throws the same way every time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bfsitl.errors import EnvironmentConfigError
from bfsitl.physics.frames import quat_from_axis_angle, quat_multiply
from bfsitl.physics.params import Quat, Vec3

#: The highest throw the environment's bounds leave room above (tasks.MAX_ALT_M is 20 m).
MAX_THROW_HEIGHT_M = 15.0


@dataclass(frozen=True)
class Throw:
    """The range each throw is drawn from (module docstring)."""

    #: Where the hand lets go, above the point the quad armed at; also the height to hold.
    height_m: float = 10.0
    max_tilt_deg: float = 180.0
    max_speed_m_s: float = 3.0
    max_rate_deg_s: float = 360.0

    def __post_init__(self) -> None:
        limits = {
            "height_m": (2.0, MAX_THROW_HEIGHT_M),
            "max_tilt_deg": (0.0, 180.0),
            "max_speed_m_s": (0.0, 10.0),
            "max_rate_deg_s": (0.0, 1440.0),
        }
        for name, (low, high) in limits.items():
            value = getattr(self, name)
            if not low <= value <= high:
                raise EnvironmentConfigError(f"Throw.{name} {value} is outside {low:g}..{high:g}")

    def draw(self, rng: np.random.Generator) -> ThrownState:
        """One throw from this range."""
        heading_rad = float(rng.uniform(-math.pi, math.pi))
        tilt_axis_rad = float(rng.uniform(-math.pi, math.pi))
        tilt_deg = float(rng.uniform(0.0, self.max_tilt_deg))
        speed_m_s = float(rng.uniform(0.0, self.max_speed_m_s))
        rate_deg_s = float(rng.uniform(0.0, self.max_rate_deg_s))
        velocity = _unit(rng) * speed_m_s
        rates = _unit(rng) * math.radians(rate_deg_s)
        # The heading first (about down), then the tilt about a horizontal axis of the world:
        # the body's z then leans tilt_deg from down whatever the heading.
        heading = quat_from_axis_angle((0.0, 0.0, 1.0), heading_rad)
        axis = (math.cos(tilt_axis_rad), math.sin(tilt_axis_rad), 0.0)
        attitude = quat_multiply(quat_from_axis_angle(axis, math.radians(tilt_deg)), heading)
        return ThrownState(
            quaternion_wxyz=attitude,
            velocity_ned_m_s=_vec3(velocity),
            angular_velocity_frd_rad_s=_vec3(rates),
            tilt_deg=tilt_deg,
            speed_m_s=speed_m_s,
            rate_deg_s=rate_deg_s,
        )


@dataclass(frozen=True)
class ThrownState:
    """One throw: the state the hand lets the quad go in (its rotors stopped), and the
    magnitudes it was drawn with."""

    quaternion_wxyz: Quat  # body FRD to world NED
    velocity_ned_m_s: Vec3
    angular_velocity_frd_rad_s: Vec3
    tilt_deg: float
    speed_m_s: float
    rate_deg_s: float

    def as_dict(self) -> dict[str, float]:
        return {
            "tilt_deg": self.tilt_deg,
            "speed_m_s": self.speed_m_s,
            "rate_deg_s": self.rate_deg_s,
        }


def _unit(rng: np.random.Generator) -> np.ndarray:
    """A direction uniform over the sphere (a normal draw made unit length)."""
    while True:
        vector = rng.normal(size=3)
        norm = float(np.linalg.norm(vector))
        if norm > 1e-9:
            return vector / norm


def _vec3(values: np.ndarray) -> Vec3:
    x, y, z = (float(v) for v in values)
    return (x, y, z)
