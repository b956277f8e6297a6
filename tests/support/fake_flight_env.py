"""A stand-in for bfsitl.gym's environments, without a SITL: the observation counts steps,
the reward is the action's first stick, an episode ends after ``max_episode_steps`` steps, and an
action of NaN raises, so a vector environment's plumbing can be tested in milliseconds."""

from __future__ import annotations

import os
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from bfsitl.backend.options import Timing
from bfsitl.gym.observation import OBSERVATION_SIZE, observation_space


class FakeFlightEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    def __init__(
        self,
        *,
        max_episode_steps: int = 3,
        marker: float = 0.0,
        pin_core: bool = False,
        timing: Timing | None = None,
    ) -> None:
        options = {"pin_core": pin_core, "spin": timing is not None and bool(timing.lockstep_spin)}
        self.max_episode_steps = max_episode_steps
        self.marker = marker
        self.options = options
        self.observation_space = observation_space()
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)
        self.steps = 0
        self.episode = 0
        self.seed_seen: int | None = None

    def _observation(self) -> np.ndarray:
        observation = np.zeros(OBSERVATION_SIZE, dtype=np.float32)
        observation[0] = self.steps
        observation[1] = self.episode
        observation[2] = self.marker
        observation[3] = -1.0 if self.seed_seen is None else self.seed_seen
        # What the vector environment asked of the real one: a core of its own, no spin.
        observation[4] = float(bool(self.options.get("pin_core")))
        observation[5] = float(bool(self.options.get("spin")))
        return observation

    def _info(self, ended_because: str | None = None) -> dict[str, Any]:
        return {
            "time_s": self.steps * 0.01,
            "target": (1.0, 2.0, 3.0),
            "waypoint": 0,
            "distance_m": 0.5 + self.steps,
            "armed": True,
            "failsafe": False,
            "truth": {
                "north_m": 0.1,
                "east_m": 0.2,
                "alt_m": 1.5 + self.steps,
                "v_north_m_s": 0.0,
                "v_east_m_s": 0.0,
                "v_up_m_s": -0.5,
            },
            "flight_modes": ("ANGLE",),
            "ended_because": ended_because,
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        self.seed_seen = seed
        self.steps = 0
        self.episode += 1
        return self._observation(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if np.isnan(action).any():
            raise ValueError("a stick of NaN")
        if action[1] > 0.9:
            os._exit(3)  # a worker that dies without a word
        self.steps += 1
        terminated = action[2] < -0.9
        truncated = not terminated and self.steps >= self.max_episode_steps
        why = "crashed: asked to" if terminated else None
        return self._observation(), float(action[0]), terminated, truncated, self._info(why)
