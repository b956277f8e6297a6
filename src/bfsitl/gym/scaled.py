"""The environment as a learner sees it best: observations about one in size, and sticks with
the authority a hover needs, centred on the vehicle's own hover throttle.

    env = ScaledEnv(HoverEnv(...))                 # 3 actions: roll, pitch, throttle
    env = ScaledEnv(HoverEnv(...), StickLimits(yaw_stick=0.3))   # 4: yaw too

Why it matters (measured with ``examples/train_hover.py``, the table in ``docs/gym.md``): the
raw environment's action space is the sticks' whole travel, so a policy's first random actions
ask for 45 degree tilts and full or no throttle and every early episode is a crash within a
second; its observation mixes metres, radians and a 9.81 m/s^2 specific force.  Here an
action of -1..1 asks for at most ``tilt_stick`` of roll and pitch stick and ``throttle_span``
of throttle either side of the hover point (:func:`~bfsitl.gym.baseline.hover_stick`, by the
vehicle's own hover throttle), yaw is held unless ``yaw_stick`` allows it, and every
observation slot is divided by a fixed scale (not a running normalisation: the policy's input
means the same thing at every step of training, and an exported policy needs no statistics
beside it).

Both maps are plain functions (:func:`scale_observation`, :meth:`StickLimits.sticks`), so a
policy trained here flies anywhere the same numbers are computed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from bfsitl.errors import EnvironmentConfigError
from bfsitl.gym.baseline import hover_stick
from bfsitl.gym.observation import OBSERVATION_SIZE

#: Subtracted from each observation slot (observation.py's layout) before it is scaled: the
#: specific force's 1 g on z and the motors' middle.
OBSERVATION_OFFSET = np.array([0.0] * 15 + [9.81] + [0.5] * 4 + [0.0] * 3, dtype=np.float32)
#: What each slot is divided by: 2 m, 2 m/s, 0.5 rad, 1, 5 rad/s, 10 m/s^2, 1, 2 m (the next
#: leg); a hovering quad's observation is then within about one of zero.
OBSERVATION_SCALE = np.array(
    [2.0] * 3 + [2.0] * 3 + [0.5] * 2 + [1.0] * 2 + [5.0] * 3 + [10.0] * 3 + [1.0] * 4 + [2.0] * 3,
    dtype=np.float32,
)
#: A scaled slot is clipped to this: one wild reading does not swamp the rest.
SCALED_LIMIT = 10.0


def scale_observation(observation: np.ndarray) -> np.ndarray:
    """``observation`` (the slots of :mod:`~bfsitl.gym.observation`) scaled about zero."""
    scaled = (np.asarray(observation, dtype=np.float32) - OBSERVATION_OFFSET) / OBSERVATION_SCALE
    return np.clip(scaled, -SCALED_LIMIT, SCALED_LIMIT).astype(np.float32)


@dataclass(frozen=True)
class StickLimits:
    """How far a scaled action may move each stick (fractions of the half travel)."""

    #: Roll and pitch: 0.4 of the half travel asks for 0.4 of the FC's ``angle_limit`` in
    #: ANGLE mode (the hand-written policy's own limit).
    tilt_stick: float = 0.4
    #: Throttle either side of the hover point.
    throttle_span: float = 0.4
    #: Yaw: 0 holds the stick centred and leaves it out of the action.
    yaw_stick: float = 0.0

    def __post_init__(self) -> None:
        for name in ("tilt_stick", "throttle_span", "yaw_stick"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise EnvironmentConfigError(f"StickLimits.{name} {value} is outside 0..1")
        if self.tilt_stick == 0.0 or self.throttle_span == 0.0:
            raise EnvironmentConfigError(
                "StickLimits: tilt_stick and throttle_span must be above 0, or the policy "
                "cannot fly"
            )

    @property
    def action_size(self) -> int:
        return 4 if self.yaw_stick > 0.0 else 3

    def sticks(self, action: np.ndarray, hover_throttle: float) -> np.ndarray:
        """The environment's action (roll, pitch, throttle, yaw in -1..1) for a scaled one;
        for a batch (one row each) too."""
        values = np.clip(np.asarray(action, dtype=np.float32), -1.0, 1.0)
        if values.ndim not in (1, 2) or values.shape[-1] != self.action_size:
            raise EnvironmentConfigError(
                f"a scaled action is {self.action_size} numbers (roll, pitch, throttle"
                f"{', yaw' if self.action_size == 4 else ''}), got shape {values.shape}"
            )
        sticks = np.zeros((*values.shape[:-1], 4), dtype=np.float32)
        sticks[..., :2] = values[..., :2] * self.tilt_stick
        sticks[..., 2] = np.clip(hover_throttle + values[..., 2] * self.throttle_span, -1.0, 1.0)
        if self.action_size == 4:
            sticks[..., 3] = values[..., 3] * self.yaw_stick
        return sticks


#: What a hover needs (the limits measured in docs/gym.md).
DEFAULT_LIMITS = StickLimits()


class ScaledEnv(gymnasium.Wrapper[np.ndarray, np.ndarray, np.ndarray, np.ndarray]):
    """A bfsitl environment with scaled observations and limited sticks (module docstring).
    The hover point is the wrapped environment's vehicle's (``world.quad``)."""

    def __init__(self, env: gymnasium.Env[Any, Any], limits: StickLimits = DEFAULT_LIMITS) -> None:
        super().__init__(env)
        world = getattr(env.unwrapped, "world", None)
        if world is None:
            raise EnvironmentConfigError(
                "ScaledEnv wraps a bfsitl environment (bfsitl/Hover-v0, bfsitl/Waypoints-v0)"
            )
        self.limits = limits
        #: The throttle stick about which this vehicle hovers (-1..1).
        self.hover_throttle = hover_stick(world.quad)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(limits.action_size,), dtype=np.float32)
        self.observation_space = spaces.Box(
            -SCALED_LIMIT, SCALED_LIMIT, shape=(OBSERVATION_SIZE,), dtype=np.float32
        )

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        observation, info = self.env.reset(seed=seed, options=options)
        return scale_observation(observation), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        sticks = self.limits.sticks(action, self.hover_throttle)
        observation, reward, terminated, truncated, info = self.env.step(sticks)
        return scale_observation(observation), float(reward), terminated, truncated, info
