"""The RC link's frames at its own rate: which datagrams carry the trailer.  The bridge at a
rate is tested in test_lockstep.py (real UDP sockets, a fake FC), the compiled loop's same
choice in tests/unit/kernel/test_lockstep_loop.py."""

from __future__ import annotations

import itertools
import math

import pytest

from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ, RcFrameClock, check_rc_rate


def frames_of(clock: RcFrameClock, stamps_s: list[float]) -> list[float]:
    return [stamp for stamp in stamps_s if clock.due(stamp)]


def test_at_250_hz_a_frame_goes_in_every_fourth_millisecond() -> None:
    clock = RcFrameClock.at_rate(250.0)
    stamps = [0.001 * step for step in range(20)]  # sums of steps, as the simulator's time
    assert frames_of(clock, stamps) == pytest.approx([0.0, 0.004, 0.008, 0.012, 0.016])
    assert clock.sent == 5


def test_a_rate_that_is_not_a_whole_number_of_steps_takes_the_first_step_at_or_after() -> None:
    clock = RcFrameClock.at_rate(150.0)  # 6.67 ms
    stamps = [0.001 * step for step in range(30)]
    assert frames_of(clock, stamps) == pytest.approx([0.0, 0.007, 0.014, 0.020, 0.027])


def test_a_time_summed_from_steps_still_meets_its_grid_point() -> None:
    clock, time_s, taken = RcFrameClock.at_rate(250.0), 0.0, []
    for _ in range(4001):
        if clock.due(time_s):
            taken.append(time_s)
        time_s += 0.001  # 0.001 is not exact in binary: the sum drifts below the grid
    assert len(taken) == 1001
    assert all(math.isclose(b - a, 0.004, abs_tol=1e-9) for a, b in itertools.pairwise(taken))


def test_the_same_stamp_again_is_a_resend_and_carries_the_frame_again() -> None:
    clock = RcFrameClock.at_rate(250.0)
    assert clock.due(0.004) and clock.due(0.004) and not clock.due(0.005)
    assert clock.sent == 1


def test_without_a_rate_every_datagram_carries_one() -> None:
    clock = RcFrameClock.at_rate(None)
    assert all(clock.due(0.001 * step) for step in range(10))


@pytest.mark.parametrize("rate_hz", [0.0, 10.0, 2000.0, math.nan, math.inf])
def test_a_rate_the_firmware_cannot_measure_is_refused(rate_hz: float) -> None:
    with pytest.raises(ValueError, match="16 to 1000 Hz"):
        check_rc_rate(rate_hz)


def test_the_default_is_an_elrs_links_rate() -> None:
    check_rc_rate(DEFAULT_RC_RATE_HZ)
    assert DEFAULT_RC_RATE_HZ == 250.0
