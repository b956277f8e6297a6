"""What a scenario run saw, step by step: the truth next to what the FC reported.

One :class:`TraceRow` per control step (and per observation step once a fault has taken the
sticks), times in simulation seconds from arming.  Expectations are judged on it.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from bfsitl.atomic_file import write_atomically
from bfsitl.errors import ScenarioError
from bfsitl.protocol.failsafe_phase import FailsafePhase

if TYPE_CHECKING:
    from bfsitl.analysis import Finding
    from bfsitl.blackbox import BlackboxLog
    from bfsitl.replay.compare import ReplayComparison

#: The firmware's failsafe phase names, by number.
FAILSAFE_PHASES = tuple(phase.name for phase in FailsafePhase)


def phase_name(phase: int | None) -> str:
    if phase is None:
        return "unknown"
    return FAILSAFE_PHASES[phase] if 0 <= phase < len(FAILSAFE_PHASES) else f"phase {phase}"


@dataclass(frozen=True, slots=True)
class TraceRow:
    """One look at the run."""

    time_s: float  # simulation seconds from arming
    alt_m: float  # true height above the take-off point
    north_m: float  # true position from the take-off point
    east_m: float
    climb_m_s: float  # true vertical speed, up positive
    tilt_deg: float  # true angle from level
    on_ground: bool
    armed: bool  # as the FC reports it
    modes: tuple[str, ...]  # the FC's flight modes (MSP_STATUS_EX)
    blockers: tuple[str, ...]  # its arming-disable flags (RXLOSS, FAILSAFE, ...)
    #: debug[3] with ``debug_mode = FAILSAFE`` (the runner provisions it); None if unread.
    failsafe_phase: int | None = None
    #: The true heading, degrees clockwise from north (0..360).
    heading_deg: float = math.nan
    #: The throttle stick sent, a share of its travel (0 low, 1 full; NaN: not known).
    throttle_share: float = math.nan
    #: The motors' mean command, 0..1 (NaN: not known).
    motor_share: float = math.nan
    #: How many faults had been injected by this row.
    faults: int = 0

    @property
    def distance_m(self) -> float:
        """Horizontal distance from the take-off point."""
        return math.hypot(self.north_m, self.east_m)


@dataclass(slots=True)
class Trace:
    """A run's rows, and the moments that give them meaning."""

    rows: list[TraceRow] = field(default_factory=list)
    #: When each fault was injected (seconds from arming), in order.
    fault_times_s: list[float] = field(default_factory=list)
    #: When the autopilot reached the take-off altitude (None: never).
    takeoff_done_s: float | None = None
    #: Why bfsitl's own crash detection fired, and when (None: it did not).
    crash: tuple[float, str] | None = None
    #: The FC's own logs of the flight (empty when none was written or decoded).
    blackbox: list[BlackboxLog] = field(default_factory=list)
    #: What the analysers found (:mod:`bfsitl.analysis`), worst first.
    findings: list[Finding] = field(default_factory=list)
    #: The analysers that could not watch the run, each with why (their silence says
    #: nothing).
    unwatched: dict[str, str] = field(default_factory=dict)
    #: A replay's log against the real flight's (None: a flown scenario, no replay).
    replay: ReplayComparison | None = None

    @property
    def first_fault_s(self) -> float | None:
        return self.fault_times_s[0] if self.fault_times_s else None

    @property
    def end_s(self) -> float:
        return self.rows[-1].time_s if self.rows else 0.0

    def window(self, from_s: float | None, until_s: float | None) -> list[TraceRow]:
        low = -math.inf if from_s is None else from_s
        high = math.inf if until_s is None else until_s
        return [row for row in self.rows if low <= row.time_s <= high]


#: ``trace.csv``'s columns: what a comparison overlays (the modes and blockers stay out).
TRACE_COLUMNS = (
    "time_s",
    "alt_m",
    "north_m",
    "east_m",
    "climb_m_s",
    "tilt_deg",
    "on_ground",
    "armed",
    "failsafe_phase",
    "heading_deg",
    "throttle_share",
    "motor_share",
    "faults",
)
#: The columns before the throttle, the motors and the faults were written (still read).
_OLD_TRACE_COLUMNS = TRACE_COLUMNS[:-3]


def write_trace_csv(trace: Trace, path: Path) -> Path:
    """The trace's rows as CSV (``trace.csv`` in a run's directory), written whole."""
    lines = [",".join(TRACE_COLUMNS)]
    for row in trace.rows:
        lines.append(
            ",".join(
                (
                    f"{row.time_s:.4f}",
                    f"{row.alt_m:.4f}",
                    f"{row.north_m:.4f}",
                    f"{row.east_m:.4f}",
                    f"{row.climb_m_s:.4f}",
                    f"{row.tilt_deg:.3f}",
                    str(int(row.on_ground)),
                    str(int(row.armed)),
                    "" if row.failsafe_phase is None else str(row.failsafe_phase),
                    f"{row.heading_deg:.2f}",
                    f"{row.throttle_share:.4f}",
                    f"{row.motor_share:.4f}",
                    str(row.faults),
                )
            )
        )
    write_atomically(path, ("\n".join(lines) + "\n").encode("ascii"))
    return path


def read_trace_csv(path: Path) -> Trace:
    """A run's ``trace.csv`` back as a :class:`Trace` (rows only)."""
    try:
        with Path(path).open(newline="") as file:
            reader = csv.DictReader(file)
            if tuple(reader.fieldnames or ()) not in (TRACE_COLUMNS, _OLD_TRACE_COLUMNS):
                raise ScenarioError(f"{path} is not a scenario run's trace.csv")
            rows = [
                TraceRow(
                    float(r["time_s"]),
                    float(r["alt_m"]),
                    float(r["north_m"]),
                    float(r["east_m"]),
                    float(r["climb_m_s"]),
                    float(r["tilt_deg"]),
                    r["on_ground"] == "1",
                    r["armed"] == "1",
                    (),
                    (),
                    int(r["failsafe_phase"]) if r["failsafe_phase"] else None,
                    float(r["heading_deg"]),
                    float(r.get("throttle_share") or math.nan),
                    float(r.get("motor_share") or math.nan),
                    int(r.get("faults") or 0),
                )
                for r in reader
            ]
    except (OSError, ValueError, KeyError, csv.Error) as exc:
        raise ScenarioError(f"cannot read {path}: {exc}") from exc
    # Each fault's time is the first row that counts it.
    faults: list[float] = []
    for row in rows:
        faults.extend([row.time_s] * (row.faults - len(faults)))
    return Trace(rows=rows, fault_times_s=faults)
