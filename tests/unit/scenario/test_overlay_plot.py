"""The comparison's overlay: every seed of both sides, the throttle and motors, the faults,
and the plot cut once the runs touched down (a trace.csv round trip carries what it needs)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from bfsitl.errors import ScenarioError
from bfsitl.scenario.plot import AFTER_TOUCHDOWN_S, _landed_s, fault_times_s, write_overlay_plot
from bfsitl.scenario.trace import Trace, TraceRow, read_trace_csv, write_trace_csv


def flight(*, touchdown_s: float, disarm_s: float, end_s: float = 40.0, fault_s: float = 8.0):
    rows = []
    for step in range(int(end_s * 10) + 1):
        t = step / 10
        in_air = 2.0 <= t < touchdown_s
        rows.append(
            TraceRow(
                t, 3.0 if in_air else 0.0, 0.0, 0.0, 0.0, 2.0, not in_air, t < disarm_s,
                (), (), 0, 0.0, 0.5 if in_air else 0.0, 0.45 if t < disarm_s else 0.0,
                int(t >= fault_s),
            )
        )  # fmt: skip
    return Trace(rows=rows, fault_times_s=[fault_s])


def test_a_trace_keeps_the_throttle_the_motors_and_the_faults_through_its_csv(
    tmp_path: Path,
) -> None:
    trace = flight(touchdown_s=11.0, disarm_s=33.5)
    again = read_trace_csv(write_trace_csv(trace, tmp_path / "trace.csv"))
    assert again.fault_times_s == [8.0]
    assert again.rows[30].throttle_share == 0.5 and again.rows[30].motor_share == 0.45
    assert [r.faults for r in again.rows[79:82]] == [0, 1, 1]


def test_an_older_trace_without_those_columns_is_still_read(tmp_path: Path) -> None:
    old = tmp_path / "trace.csv"
    old.write_text(
        "time_s,alt_m,north_m,east_m,climb_m_s,tilt_deg,on_ground,armed,failsafe_phase,"
        "heading_deg\n0.0000,0.0,0.0,0.0,0.0,1.0,1,1,0,90.00\n"
    )
    (row,) = read_trace_csv(old).rows
    assert row.armed and math.isnan(row.motor_share) and row.faults == 0
    old.write_text("time_s,alt_m\n0,0\n")
    with pytest.raises(ScenarioError, match="not a scenario run's trace.csv"):
        read_trace_csv(old)


def test_the_overlay_ends_soon_after_the_last_touchdown_not_at_the_late_disarm(
    tmp_path: Path,
) -> None:
    a = [flight(touchdown_s=10.4, disarm_s=33.5), flight(touchdown_s=10.1, disarm_s=33.5)]
    b = [flight(touchdown_s=9.2, disarm_s=33.5)]
    # The last row in the air is at 10.3 s (rows every 0.1 s).
    assert _landed_s([*a, *b]) == pytest.approx(10.3 + AFTER_TOUCHDOWN_S, abs=1e-6)
    # A run that ends in the air keeps every row.
    assert _landed_s([*a, flight(touchdown_s=50.0, disarm_s=50.0)]) is None
    path = write_overlay_plot([("A: x", a), ("B: y", b)], tmp_path / "o.png", title="t")
    assert path.stat().st_size > 10_000


def test_one_fault_is_one_marker_however_many_runs_injected_it() -> None:
    """Seeds and sides arm within a control step of each other: the same fault lands a few
    milliseconds apart, and must still be drawn once."""
    runs = [flight(touchdown_s=11.0, disarm_s=12.0, fault_s=at_s) for at_s in (8.0, 8.004, 8.01)]
    assert fault_times_s(runs) == [8.0]
    assert fault_times_s([Trace(), *runs[1:]]) == [8.004]
    assert fault_times_s([Trace()]) == []
