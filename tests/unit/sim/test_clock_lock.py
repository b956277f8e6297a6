"""The rate-frozen timestamp scheme (sitl.c's simRate estimator,
docs/firmware-facts.md#sim-clock)."""

from __future__ import annotations

import pytest

from bfsitl.sim.clock_lock import (
    BASE_TIMESTAMP_S,
    ESTIMATOR_WINDOW_S,
    FROZEN_STEP_S,
    FrozenRateStamps,
)


def test_regular_steps_are_exact_and_outside_the_estimator_window():
    stamps = FrozenRateStamps()
    values = [stamps.next() for _ in range(10_000)]
    deltas = {b - a for a, b in zip(values, values[1:], strict=False)}
    # 0.0625 is exact in binary: no delta ever drifts into the (0, 20 ms) window.
    assert deltas == {FROZEN_STEP_S}
    assert FROZEN_STEP_S > ESTIMATOR_WINDOW_S
    assert values[0] == BASE_TIMESTAMP_S + FROZEN_STEP_S


def test_why_not_exactly_20_ms():
    # The estimator needs Δ < 0.02; 0.02 steps accumulate float error and dip below it.
    t, deltas = 1024.0, []
    for _ in range(1000):
        deltas.append((t + 0.02) - t)
        t += 0.02
    assert min(deltas) < ESTIMATOR_WINDOW_S


@pytest.mark.parametrize("speed", [0.25, 0.5, 0.75, 1.5])
def test_calibration_pair_asks_for_the_speed_within_the_window(speed):
    stamps = FrozenRateStamps(speed)
    first = stamps.primer()
    wall_s = stamps.calibration_wall_s()
    second = stamps.calibration_second(first, wall_s)
    assert 0 < second - first < ESTIMATOR_WINDOW_S
    assert (second - first) / wall_s == pytest.approx(speed)
    assert stamps.next() - second == FROZEN_STEP_S


def test_late_second_packet_is_clamped_inside_the_window():
    stamps = FrozenRateStamps(1.5)
    first = stamps.primer()
    second = stamps.calibration_second(first, wall_elapsed_s=0.1)  # far too late
    assert 0 < second - first < ESTIMATOR_WINDOW_S


def test_speed_one_needs_no_calibration_and_bad_speeds_are_refused():
    assert not FrozenRateStamps(1.0).needs_calibration
    assert FrozenRateStamps(0.5).needs_calibration
    with pytest.raises(ValueError):
        FrozenRateStamps(0.0)
