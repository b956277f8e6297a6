"""Late observations, as a policy meets them outside the lockstep.

In the lockstep environment the policy reads the FC the instant its step ends, and its sticks
reach the FC at the RC link's next frame (250 Hz unless the environment sends one per step,
``rc_frame_per_step``).  Outside it they do not: a board's
receiver sends its frames at its own rate, which the FC smooths accordingly, its serial link
adds its delays, and the FC's altitude lags the truth longer (155-165 ms on the stock SITL
reached as a board, against 115-130 ms in lockstep, docs/gym.md); a real GPS and barometer
add their own.  A policy trained
without any of it is brittle: one control step (20 ms) of delay took the shipped hover
policy's error from 7 to 24 cm.

:class:`Latency` says how late the observation may be, in whole control steps, drawn anew
for each episode (so a policy learns to fly with any delay in the range); the environment
hands the policy the observation of that many steps ago.  The height and climb slots can be
given more on top, for the barometer.  For a time-invariant plant a late observation and a
late stick are one and the same delay around the loop.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from bfsitl.errors import EnvironmentConfigError

#: The observation slots of the height (target minus altitude) and of the climb rate.
ALTITUDE_SLOTS = (2, 5)
#: Longer than any delay worth training with: 50 steps is a second at 50 Hz.
MAX_DELAY_STEPS = 50

StepRange = tuple[int, int]


@dataclass(frozen=True)
class Latency:
    """How many control steps late the policy's observation is, each drawn per episode
    uniformly from its inclusive range: ``steps`` for every slot, ``altitude_steps`` on top
    for the height and climb slots.  ``Latency()`` is none."""

    steps: StepRange = (0, 0)
    altitude_steps: StepRange = (0, 0)

    def __post_init__(self) -> None:
        for name in ("steps", "altitude_steps"):
            low, high = getattr(self, name)
            if not (
                isinstance(low, int)
                and isinstance(high, int)
                and 0 <= low <= high <= MAX_DELAY_STEPS
            ):
                raise EnvironmentConfigError(
                    f"latency {name}={(low, high)}: a range of whole control steps, "
                    f"0 <= low <= high <= {MAX_DELAY_STEPS}"
                )

    @property
    def none(self) -> bool:
        return self.steps == (0, 0) and self.altitude_steps == (0, 0)


NO_LATENCY = Latency()


class DelayLine:
    """The observations of the last steps, handed out as late as the episode's draw says."""

    def __init__(self, latency: Latency) -> None:
        self.latency = latency
        self._history: deque[np.ndarray] = deque(maxlen=2 * MAX_DELAY_STEPS + 1)
        #: This episode's delays, steps: (every slot, the altitude slots' total).
        self.delays: tuple[int, int] = (0, 0)

    def restart(self, observation: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A new episode: draw its delays; before it, the first observation stands in for
        every earlier one."""
        steps = _draw(self.latency.steps, rng)
        self.delays = (steps, steps + _draw(self.latency.altitude_steps, rng))
        self._history.clear()
        self._history.append(observation)
        return observation.copy()

    def push(self, observation: np.ndarray) -> np.ndarray:
        """This step's observation in; the one the policy is given out."""
        history = self._history
        history.append(observation)
        every, altitude = self.delays
        late = history[max(0, len(history) - 1 - every)].copy()
        if altitude != every:
            older = history[max(0, len(history) - 1 - altitude)]
            late[list(ALTITUDE_SLOTS)] = older[list(ALTITUDE_SLOTS)]
        return late


def _draw(step_range: StepRange, rng: np.random.Generator) -> int:
    low, high = step_range
    return low if low == high else int(rng.integers(low, high + 1))
