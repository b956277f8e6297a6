"""bfsitl's own vector environment as Stable-Baselines3 sees one: train on
:class:`~bfsitl.gym.vector.FlightVectorEnv` (pinned workers, numbers in shared memory)
instead of SB3's ``SubprocVecEnv`` (a pickled ``info`` per environment per step).

    envs = Sb3VectorEnv(gymnasium.make_vec("bfsitl/Hover-v0", num_envs=2, control_hz=50))
    model = PPO("MlpPolicy", envs)

With ``limits`` (a :class:`~bfsitl.gym.scaled.StickLimits`, the default) the policy sees what
:class:`~bfsitl.gym.scaled.ScaledEnv` shows it, computed here for all the environments at
once; ``limits=None`` passes the environments' own observations and four sticks.  What SB3
reads in the ``infos`` is here: ``terminal_observation`` and ``TimeLimit.truncated`` at the
end of an episode, and ``episode`` (return ``r``, length ``l``, wall seconds ``t``, as SB3's
``Monitor`` writes them), so its episode statistics and callbacks work without a ``Monitor``;
the ended episode's whole info rides in ``final_info``.  Needs the ``learn`` extra.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from bfsitl.errors import EnvironmentConfigError, ExtraMissingError
from bfsitl.gym.baseline import hover_stick
from bfsitl.gym.observation import OBSERVATION_SIZE
from bfsitl.gym.scaled import DEFAULT_LIMITS, SCALED_LIMIT, StickLimits, scale_observation
from bfsitl.gym.vector import FlightVectorEnv

try:
    from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvStepReturn
except ImportError as exc:  # pragma: no cover - depends on the installation
    raise ExtraMissingError(
        "bfsitl.gym.sb3_vector needs Stable-Baselines3: pip install torch==2.13.0 "
        "'bfsitl[learn]' (torch first: the CPU build)"
    ) from exc


class Sb3VectorEnv(VecEnv):  # type: ignore[misc]  # SB3 is untyped for mypy here
    """``envs`` (a :class:`~bfsitl.gym.vector.FlightVectorEnv`) for SB3 (module docstring)."""

    def __init__(self, envs: FlightVectorEnv, limits: StickLimits | None = DEFAULT_LIMITS) -> None:
        if not isinstance(envs, FlightVectorEnv):
            raise EnvironmentConfigError(
                f"Sb3VectorEnv takes a FlightVectorEnv (gymnasium.make_vec('bfsitl/Hover-v0', "
                f"num_envs=N)), not {type(envs).__name__}"
            )
        self.envs = envs
        self.limits = limits
        self.hover_throttle = hover_stick(envs.world.quad)
        if limits is None:
            observation_space: spaces.Box = envs.single_observation_space  # type: ignore[assignment]
            action_space: spaces.Box = envs.single_action_space  # type: ignore[assignment]
        else:
            observation_space = spaces.Box(
                -SCALED_LIMIT, SCALED_LIMIT, shape=(OBSERVATION_SIZE,), dtype=np.float32
            )
            action_space = spaces.Box(-1.0, 1.0, shape=(limits.action_size,), dtype=np.float32)
        super().__init__(envs.num_envs, observation_space, action_space)
        self._actions: np.ndarray | None = None
        self._returns = np.zeros(envs.num_envs)
        self._lengths = np.zeros(envs.num_envs, dtype=np.int64)
        self._started = time.monotonic()

    def _observations(self, observations: np.ndarray) -> np.ndarray:
        return observations if self.limits is None else scale_observation(observations)

    # -- SB3's VecEnv ------------------------------------------------------------------------
    def reset(self) -> np.ndarray:
        seeds = None if all(seed is None for seed in self._seeds) else list(self._seeds)
        options = self._options[0] or None
        observations, info = self.envs.reset(seed=seeds, options=options)
        self._reset_seeds()
        self._reset_options()
        self._returns[:] = 0.0
        self._lengths[:] = 0
        self.reset_infos = [_one(info, index) for index in range(self.num_envs)]
        return self._observations(observations)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions, dtype=np.float32)

    def step_wait(self) -> VecEnvStepReturn:
        actions, self._actions = self._actions, None
        if actions is None:
            raise EnvironmentConfigError("step_wait() without step_async(): call step()")
        limits = self.limits
        sticks = actions if limits is None else limits.sticks(actions, self.hover_throttle)
        observations, rewards, terminated, truncated, info = self.envs.step(sticks)
        self._returns += rewards
        self._lengths += 1
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for index in np.flatnonzero(dones).tolist():
            final_info = info["final_info"]
            infos[index] = {
                "terminal_observation": self._observations(info["final_obs"][index]),
                "TimeLimit.truncated": bool(truncated[index] and not terminated[index]),
                "episode": {
                    "r": round(float(self._returns[index]), 6),
                    "l": int(self._lengths[index]),
                    "t": round(time.monotonic() - self._started, 6),
                },
                "final_info": _one(final_info, index),
            }
            self._returns[index] = 0.0
            self._lengths[index] = 0
        return self._observations(observations), rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.envs.close()

    def get_images(self) -> Sequence[np.ndarray | None]:
        frames = self.envs.render()
        return list(frames) if frames is not None else [None] * self.num_envs

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        # SB3 asks for the render mode (all environments share the vector's); nothing else
        # of an environment in a worker process is reachable from here.
        if attr_name == "render_mode":
            return [self.envs.render_mode for _ in self._get_indices(indices)]
        raise AttributeError(
            f"{attr_name}: the environments live in worker processes; Sb3VectorEnv gives "
            f"only render_mode"
        )

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        raise EnvironmentConfigError(
            f"set_attr({attr_name!r}): the environments live in worker processes; give the "
            f"option when the vector environment is made"
        )

    def env_method(
        self, method_name: str, *method_args: Any, indices: Any = None, **method_kwargs: Any
    ) -> list[Any]:
        raise EnvironmentConfigError(
            f"env_method({method_name!r}): the environments live in worker processes"
        )

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        # No environment is wrapped (this class writes Monitor's episode statistics).
        return [False for _ in self._get_indices(indices)]


def _one(info: dict[str, Any], index: int) -> dict[str, Any]:
    """Environment ``index``'s part of a batched Gymnasium info (nested dicts too; the
    ``_key`` masks kept out)."""
    return {
        key: _one(value, index) if isinstance(value, dict) else value[index]
        for key, value in info.items()
        if not key.startswith("_") and (f"_{key}" not in info or info[f"_{key}"][index])
    }
