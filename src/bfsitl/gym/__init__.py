"""Learn to fly through the real firmware: Gymnasium environments on lockstep builds.

    import gymnasium
    import bfsitl.gym  # registers the environments
    from bfsitl import SitlLaunch, Wind, World

    env = gymnasium.make("bfsitl/Hover-v0", sitl=SitlLaunch(firmware="4.6.0-gps-lockstep"),
                         world=World(wind=Wind.from_direction(3.0, 90.0)), control_hz=100)
    observation, info = env.reset(seed=1)
    observation, reward, terminated, truncated, info = env.step(env.action_space.sample())

``bfsitl/Hover-v0`` reaches and holds a point, ``bfsitl/Waypoints-v0`` flies through points
in turn (the next one in the observation), ``bfsitl/Recover-v0`` is thrown, tumbling with its
rotors stopped, and must recover and hold (``throw``: :class:`~bfsitl.gym.throws.Throw`).
Options of all, the session's groups
(:class:`~bfsitl.mission.session.SessionConfig`) where they mean the same: ``sitl``
(:class:`~bfsitl.mission.session.SitlLaunch`: a ``--lockstep`` build and the run directory),
``timing`` (:class:`~bfsitl.backend.options.Timing`: the lockstep exchange and spinning) and
``world`` (:class:`~bfsitl.backend.options.World`: wind, quad, sensors, heading); and the
environment's own: ``control_hz``, ``mode`` (``"angle"`` or ``"acro"``), ``observation``
(``"fc"``: what the FC reports; ``"truth"``: the simulation), ``disturbances`` (a hook called
before every step with the flight's disturbance surface), ``start`` (``"air"`` or
``"ground"``), ``start_alt_m``, ``latency`` (:class:`~bfsitl.gym.latency.Latency`: the
observation late by some control steps, drawn per episode), ``rc_frame_per_step`` (one
receiver frame per step, so that the FC smooths the sticks as outside the lockstep),
``random_wind`` (:class:`~bfsitl.gym.random_wind.RandomWind`: a wind drawn per episode),
``random_vehicle`` (:class:`~bfsitl.gym.random_vehicle.RandomVehicle`: a quad drawn per
episode), ``pin_core``, ``warm_resets``, ``render_mode`` (``"rgb_array"``:
:mod:`~bfsitl.gym.render`).  Needs the ``gym`` extra:
``pip install 'bfsitl[gym]'``.

An episode is truncated after ``max_episode_steps`` steps, Gymnasium's own limit, registered
with each id (1000 for Hover, 2000 for Waypoints: 10 s and 20 s at the default 100 Hz) and
changed the Gymnasium way, ``gymnasium.make(id, max_episode_steps=N)`` (also at another
``control_hz``: the limit counts steps, not seconds).  An environment made directly
(``HoverEnv(max_episode_steps=N)``) counts the same option itself.

Many at once: ``gymnasium.make_vec(id, num_envs=N)`` gives
:class:`~bfsitl.gym.vector.FlightVectorEnv` (a worker per environment, each pinned to a core
with its SITL, the numbers in shared memory); Gymnasium's own ``AsyncVectorEnv`` works too,
at a higher cost per step.  On a Ray cluster: :class:`~bfsitl.gym.ray_vector.RayVectorEnv`
(one Ray actor per environment; the firmware travels to the nodes).

For a learner: :class:`~bfsitl.gym.scaled.ScaledEnv` shows an environment with observations
scaled to about one and sticks limited to what a hover needs (what made the hover learn in
minutes), and :class:`~bfsitl.gym.sb3_vector.Sb3VectorEnv` hands ``FlightVectorEnv`` to
Stable-Baselines3 with the same scaling (``examples/train_hover.py``).
"""

from __future__ import annotations

from bfsitl.errors import ExtraMissingError

try:
    from gymnasium.envs.registration import register, registry
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ExtraMissingError("bfsitl.gym needs Gymnasium: pip install 'bfsitl[gym]'") from exc

from bfsitl.gym.env import (
    HOVER_MAX_EPISODE_STEPS,
    RECOVER_MAX_EPISODE_STEPS,
    WAYPOINTS_MAX_EPISODE_STEPS,
    FlightEnv,
    HoverEnv,
    RecoverEnv,
    WaypointsEnv,
)
from bfsitl.gym.latency import Latency
from bfsitl.gym.random_vehicle import RandomVehicle
from bfsitl.gym.random_wind import RandomWind
from bfsitl.gym.throws import Throw

ENVIRONMENTS = {
    "bfsitl/Hover-v0": "bfsitl.gym.env:HoverEnv",
    "bfsitl/Waypoints-v0": "bfsitl.gym.env:WaypointsEnv",
    "bfsitl/Recover-v0": "bfsitl.gym.env:RecoverEnv",
}
#: What ``gymnasium.make_vec(id, num_envs=N)`` makes (Gymnasium takes a registered vector
#: entry point first): N environments in pinned workers, sharing memory (bfsitl.gym.vector);
#: ``vectorization_mode="async"`` or ``"sync"`` asks for Gymnasium's own.
VECTOR_ENVIRONMENTS = {
    "bfsitl/Hover-v0": "bfsitl.gym.vector:HoverVectorEnv",
    "bfsitl/Waypoints-v0": "bfsitl.gym.vector:WaypointsVectorEnv",
    "bfsitl/Recover-v0": "bfsitl.gym.vector:RecoverVectorEnv",
}
#: Gymnasium's TimeLimit ends each episode after this many steps (``make_vec`` passes it to
#: the vector environments, whose workers count it).
MAX_EPISODE_STEPS = {
    "bfsitl/Hover-v0": HOVER_MAX_EPISODE_STEPS,
    "bfsitl/Waypoints-v0": WAYPOINTS_MAX_EPISODE_STEPS,
    "bfsitl/Recover-v0": RECOVER_MAX_EPISODE_STEPS,
}

for _id, _entry_point in ENVIRONMENTS.items():
    if _id not in registry:
        register(
            id=_id,
            entry_point=_entry_point,
            vector_entry_point=VECTOR_ENVIRONMENTS[_id],
            max_episode_steps=MAX_EPISODE_STEPS[_id],
        )

__all__ = [
    "ENVIRONMENTS",
    "MAX_EPISODE_STEPS",
    "VECTOR_ENVIRONMENTS",
    "FlightEnv",
    "HoverEnv",
    "Latency",
    "RandomVehicle",
    "RandomWind",
    "RecoverEnv",
    "Throw",
    "WaypointsEnv",
]
