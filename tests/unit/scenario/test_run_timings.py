"""Where a run's wall time goes: the stopwatch adds each phase up, and the table shows each
run, their sum and each phase's share."""

from __future__ import annotations

import itertools

from bfsitl.scenario.timings import PHASES, Stopwatch, timings_table


def test_the_stopwatch_adds_up_each_phase_on_its_clock() -> None:
    ticks = itertools.count(0.0, 0.5)  # every reading of the clock is 0.5 s later
    watch = Stopwatch(clock=lambda: next(ticks))
    with watch.span("start-up"):
        pass
    with watch.span("flight"):
        pass
    with watch.span("flight"):
        pass
    assert watch.spans_s == {"start-up": 0.5, "flight": 1.0}
    try:
        with watch.span("plots"):
            raise ValueError("a plot that fails still took its time")
    except ValueError:
        pass
    assert watch.spans_s["plots"] == 0.5


def test_the_table_shows_each_run_their_sum_and_each_phases_share() -> None:
    runs = [
        ("drop[4.6.0]", {"start-up": 1.0, "flight": 2.0, "blackbox": 1.0}, 20.0),
        ("far[4.6.0]", {"start-up": 1.0, "flight": 4.0, "blackbox": 1.0}, 60.0),
    ]
    lines = timings_table(runs)
    header = lines[0].split()
    # Only the phases some run had, in the order a run goes through them.
    assert header[1:4] == ["start-up", "flight", "blackbox"]
    assert [PHASES.index(p) for p in header[1:4]] == sorted(PHASES.index(p) for p in header[1:4])
    assert lines[1].split()[-3:] == ["4.00", "20.0", "5.0x"]
    assert lines[3].split()[0] == "sum" and lines[3].split()[-3:] == ["10.00", "80.0", "8.0x"]
    assert lines[4].split() == ["share", "20%", "60%", "20%"]
    assert len(timings_table(runs[:1])) == 3  # one run: no sum row
