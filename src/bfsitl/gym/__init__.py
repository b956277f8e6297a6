"""Learn to fly through the real firmware: Gymnasium environments on lockstep builds.

    import gymnasium
    import bfsitl.gym  # registers the environments

    env = gymnasium.make("bfsitl/Hover-v0", firmware="4.6.0-gps-lockstep", control_hz=100)
    observation, info = env.reset(seed=1)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

``bfsitl/Hover-v0`` reaches and holds a point, ``bfsitl/Waypoints-v0`` flies through points
in turn (the next one in the observation).  Options of both: ``firmware`` (a ``--lockstep``
build), ``control_hz``, ``mode`` (``"angle"`` or ``"acro"``), ``observation`` (``"fc"``: what
the FC reports; ``"truth"``: the simulation), ``wind``, ``wind_from_deg``, ``gusts``,
``disturbances`` (a hook called before every step with the flight's disturbance surface),
``episode_s``, ``start`` (``"air"`` or ``"ground"``), ``start_alt_m``.  Needs the ``gym``
extra: ``pip install 'bfsitl[gym]'``.

Many at once: ``gymnasium.make_vec(id, num_envs=N)`` gives
:class:`~bfsitl.gym.vector.FlightVectorEnv` (a worker per environment, each pinned to a core
with its SITL, the numbers in shared memory); Gymnasium's own ``AsyncVectorEnv`` works too,
at a higher cost per step.  On a Ray cluster: :class:`~bfsitl.gym.ray_vector.RayVectorEnv`
(one Ray actor per environment; the firmware travels to the nodes).
"""

from __future__ import annotations

from bfsitl.errors import ExtraMissingError

try:
    from gymnasium.envs.registration import register, registry
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ExtraMissingError(
        "bfsitl.gym needs Gymnasium: pip install 'bfsitl[gym]'") from exc

from bfsitl.gym.env import FlightEnv, HoverEnv, WaypointsEnv

ENVIRONMENTS = {"bfsitl/Hover-v0": "bfsitl.gym.env:HoverEnv",
                "bfsitl/Waypoints-v0": "bfsitl.gym.env:WaypointsEnv"}
#: What ``gymnasium.make_vec(id, num_envs=N)`` makes (Gymnasium takes a registered vector
#: entry point first): N environments in pinned workers, sharing memory (bfsitl.gym.vector);
#: ``vectorization_mode="async"`` or ``"sync"`` asks for Gymnasium's own.
VECTOR_ENVIRONMENTS = {"bfsitl/Hover-v0": "bfsitl.gym.vector:HoverVectorEnv",
                       "bfsitl/Waypoints-v0": "bfsitl.gym.vector:WaypointsVectorEnv"}

for _id, _entry_point in ENVIRONMENTS.items():
    if _id not in registry:
        register(id=_id, entry_point=_entry_point,
                 vector_entry_point=VECTOR_ENVIRONMENTS[_id])

__all__ = ["ENVIRONMENTS", "VECTOR_ENVIRONMENTS", "FlightEnv", "HoverEnv", "WaypointsEnv"]
