"""The late observation a policy is trained with (bfsitl.gym.latency): the delays drawn per
episode from their ranges, the observation of that many steps ago handed out, the height and
climb slots later again, the first observation standing in for what came before it, and
nothing drawn (the environment's random numbers untouched) when there is no latency."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from bfsitl.errors import EnvironmentConfigError  # noqa: E402
from bfsitl.gym.latency import ALTITUDE_SLOTS, NO_LATENCY, DelayLine, Latency  # noqa: E402
from bfsitl.gym.observation import OBSERVATION_SIZE  # noqa: E402


def numbered(step: int) -> np.ndarray:
    """An observation whose every slot says which step it came from."""
    return np.full(OBSERVATION_SIZE, float(step), dtype=np.float32)


def test_the_observation_is_handed_out_as_many_steps_late_as_drawn() -> None:
    line = DelayLine(Latency(steps=(2, 2)))
    assert line.restart(numbered(0), np.random.default_rng(0))[0] == 0.0
    given = [line.push(numbered(step))[0] for step in range(1, 8)]
    # Before the episode's first observation there is none: it stands in.
    assert given == [0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0]


def test_the_height_and_climb_slots_are_later_again() -> None:
    line = DelayLine(Latency(steps=(1, 1), altitude_steps=(3, 3)))
    line.restart(numbered(0), np.random.default_rng(0))
    for step in range(1, 10):
        out = line.push(numbered(step))
    assert line.delays == (1, 4)
    others = [i for i in range(OBSERVATION_SIZE) if i not in ALTITUDE_SLOTS]
    assert set(out[others]) == {8.0} and set(out[list(ALTITUDE_SLOTS)]) == {5.0}


def test_each_episode_draws_its_delays_from_the_ranges_with_the_environments_rng() -> None:
    line = DelayLine(Latency(steps=(0, 2), altitude_steps=(0, 8)))
    rng = np.random.default_rng(7)
    drawn = set()
    for _ in range(200):
        line.restart(numbered(0), rng)
        every, altitude = line.delays
        assert 0 <= every <= 2 and every <= altitude <= every + 8
        drawn.add(line.delays)
    assert {every for every, _ in drawn} == {0, 1, 2}
    again = DelayLine(Latency(steps=(0, 2), altitude_steps=(0, 8)))
    same_seed = np.random.default_rng(7)
    again.restart(numbered(0), same_seed)
    first = DelayLine(Latency(steps=(0, 2), altitude_steps=(0, 8)))
    first.restart(numbered(0), np.random.default_rng(7))
    assert again.delays == first.delays  # seeded: the same draws


def test_no_latency_hands_out_each_observation_and_draws_nothing() -> None:
    line = DelayLine(NO_LATENCY)
    rng = np.random.default_rng(3)
    state = rng.bit_generator.state
    line.restart(numbered(0), rng)
    assert rng.bit_generator.state == state
    assert [line.push(numbered(s))[0] for s in (1, 2, 3)] == [1.0, 2.0, 3.0]
    assert NO_LATENCY.none and not Latency(steps=(0, 1)).none


def test_what_is_handed_out_is_a_copy() -> None:
    line = DelayLine(Latency(steps=(1, 1)))
    line.restart(numbered(0), np.random.default_rng(0))
    out = line.push(numbered(1))
    out[:] = 99.0
    assert line.push(numbered(2))[0] == 1.0


@pytest.mark.parametrize(
    "latency",
    [
        {"steps": (2, 1)},
        {"steps": (-1, 0)},
        {"altitude_steps": (0, 51)},
        {"steps": (0.5, 1)},
    ],
)
def test_a_range_that_is_not_whole_steps_in_order_is_refused(latency: dict) -> None:
    with pytest.raises(EnvironmentConfigError, match="whole control steps"):
        Latency(**latency)
