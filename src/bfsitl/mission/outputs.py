"""Where a flight's rows go: the one place that turns them into every output format.

During the flight each row (and each event) goes to the sinks that stream: the CSV log, the
MCAP file and the live Foxglove server.  After it, the same rows make the plot and the summary.
Streaming sinks flush as they go and are closed on every way out (Ctrl-C, a crash of the SITL,
an exception), so what was flown is never lost: the CSV row by row, the MCAP finished with its
index.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_log import CsvFlightLog, FlightRow

if TYPE_CHECKING:
    from bfsitl.mission.plan import MissionPlan
    from bfsitl.mission.runner import MissionResult
    from bfsitl.mission.vehicle import FlightSample


class RowSink(Protocol):
    """Something that takes the rows as they are flown."""

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None: ...

    def event(self, time_s: float, text: str) -> None: ...

    def close(self) -> None: ...


class _CsvSink:
    """The CSV log as a sink (it has no events: its rows are the record)."""

    def __init__(self, path: str | Path) -> None:
        self.log = CsvFlightLog(path)

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        self.log.write(row)

    def event(self, time_s: float, text: str) -> None:
        pass

    def close(self) -> None:
        self.log.close()


@dataclass
class OutputOptions:
    """Which outputs a flight writes; every path optional."""

    csv_path: str | Path | None = None
    plot_path: str | Path | None = None
    summary_path: str | Path | None = None
    mcap_path: str | Path | None = None
    #: Serve the flight live to Foxglove on 127.0.0.1 at this port (0: any free one).
    foxglove_port: int | None = None
    allow_origins: tuple[str, ...] = ()
    waypoints: list[tuple[float, float]] = field(default_factory=list)


class FlightOutputs:
    """The streaming sinks of one flight, and what is written from its rows afterwards.

    Use :meth:`on_row` and :meth:`on_event` as the mission's callbacks; :meth:`close` on every
    way out; :meth:`finish` once the result is known.
    """

    def __init__(self, options: OutputOptions, *,
                 progress: Callable[[str], None] | None = None) -> None:
        self.options = options
        self._progress = progress or (lambda _line: None)
        self.sinks: list[RowSink] = []
        self.rows_written = 0
        self._last_time_s = 0.0
        self.foxglove_url: str | None = None
        self.recorder: Any = None

    def start(self) -> FlightOutputs:
        """Open every streaming sink; a failure closes the ones already open."""
        options = self.options
        try:
            if options.csv_path:
                self.sinks.append(_CsvSink(options.csv_path))
            if options.mcap_path or options.foxglove_port is not None:
                from bfsitl.flight_record import FoxgloveRecorder

                self.recorder = FoxgloveRecorder(
                    mcap_path=Path(options.mcap_path) if options.mcap_path else None,
                    live_port=options.foxglove_port, allow_origins=options.allow_origins,
                    on_event=lambda line: self._progress(f"foxglove: {line}"))
                self.recorder.start()
                self.sinks.append(self.recorder)
                self.foxglove_url = self.recorder.live_url
                if self.foxglove_url:
                    self._progress(f"Foxglove can watch this flight live: open a Foxglove "
                                   f"WebSocket connection to {self.foxglove_url}")
        except BaseException:
            self.close()
            raise
        return self

    # -- during the flight ----------------------------------------------------------------
    def on_row(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        self._last_time_s = row.time_s
        for sink in self.sinks:
            sink.write(row, sample)
        self.rows_written += 1

    def on_event(self, text: str) -> None:
        """An event, stamped with the simulation time of the latest row."""
        for sink in self.sinks:
            sink.event(self._last_time_s, text)

    def close(self) -> None:
        """Close every streaming sink (idempotent; each is closed even if another fails)."""
        errors: list[BaseException] = []
        while self.sinks:
            sink = self.sinks.pop()
            try:
                sink.close()
            except Exception as exc:  # noqa: BLE001 - the others must still be closed
                errors.append(exc)
        if errors:
            raise BfsitlError(f"closing the flight's outputs failed: {errors[0]}") from errors[0]

    # -- after the flight -----------------------------------------------------------------
    def finish(self, result: MissionResult, summary: dict[str, Any]) -> list[str]:
        """Write the plot and the summary from the flight's rows; what was written, in words."""
        options = self.options
        written = []
        if options.csv_path:
            written.append(f"log {options.csv_path} ({len(result.rows)} rows)")
        if options.mcap_path:
            written.append(f"MCAP {options.mcap_path}")
        if options.plot_path and result.rows:
            from bfsitl.mission.plot import write_flight_plot

            write_flight_plot(result.rows, options.plot_path,
                              title=f"bfsitl fly: {result.controller}, {result.outcome.value}",
                              waypoints=options.waypoints)
            written.append(f"plot {options.plot_path}")
        if options.summary_path:
            path = Path(options.summary_path)
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_text(json.dumps(summary, indent=2) + "\n")
            except OSError as exc:
                raise BfsitlError(f"cannot write the summary {path}: {exc}") from exc
            written.append(f"summary {options.summary_path}")
        return written


def plan_waypoints(plan: MissionPlan) -> list[tuple[float, float]]:
    """The plan's waypoints as (north, east) for the plot."""
    return [(w.north_m, w.east_m) for w in plan.waypoints]
