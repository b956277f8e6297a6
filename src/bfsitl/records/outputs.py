"""Where a flight's rows go: the sinks of one flight (:mod:`bfsitl.records.sinks`, chosen by
file suffix), opened together, fed together and closed together.

During the flight each row (and each event) goes to the sinks that stream: the CSV log, the
MCAP file and the live Foxglove server, and to the analysers that watch every flight
(:class:`~bfsitl.analysis.FlightWatch`).  After it, the same rows make the plot and the
summary, whose ``findings`` are what the analysers found.
Streaming sinks flush as they go and are closed on every way out (Ctrl-C, a crash of the SITL,
an exception), so what was flown is never lost: the CSV row by row, the MCAP finished with its
index.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from bfsitl.analysis import Analysis, FlightWatch
from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_row import FlightRow
from bfsitl.records.sinks import FoxgloveSink, RowSink, open_sink

if TYPE_CHECKING:
    from bfsitl.mission.plan import MissionPlan
    from bfsitl.mission.results import MissionResult
    from bfsitl.mission.vehicle import FlightSample


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
    #: More record files, each written by the sink its suffix picks.
    extra_paths: tuple[str | Path, ...] = ()
    #: Run the analysers on the flight (crash, saturation, excursions, ...): their findings
    #: go into the summary.
    watch: bool = True


class FlightOutputs:
    """The streaming sinks of one flight, and what is written from its rows afterwards.

    Use :meth:`on_row` and :meth:`on_event` as the mission's callbacks; :meth:`close` on every
    way out; :meth:`finish` once the result is known.
    """

    def __init__(
        self, options: OutputOptions, *, progress: Callable[[str], None] | None = None
    ) -> None:
        self.options = options
        self._progress = progress or (lambda _line: None)
        self.sinks: list[RowSink] = []
        self.rows_written = 0
        self._last_time_s = 0.0
        self.foxglove_url: str | None = None
        #: Every sink opened, in order (closing empties :attr:`sinks`; finishing uses these).
        self._opened: list[RowSink] = []
        #: The analysers' record of the flight (None: not watched).
        self.watch: FlightWatch | None = FlightWatch() if options.watch else None
        #: What they found, once :meth:`finish` ran.
        self.analysis: Analysis | None = None

    def start(self) -> FlightOutputs:
        """Open every streaming sink, each chosen by its file's suffix
        (:mod:`bfsitl.records.sinks`); a failure closes the ones already open."""
        options = self.options
        paths = [
            Path(p)
            for p in (
                options.csv_path,
                options.mcap_path,
                options.plot_path,
                options.summary_path,
                *options.extra_paths,
            )
            if p
        ]
        live_port = options.foxglove_port
        try:
            for path in paths:
                extra: dict[str, Any] = {}
                if live_port is not None and path.suffix.lower() == ".mcap":
                    # The MCAP file's recorder serves the live view too.
                    extra = {"live_port": live_port, "allow_origins": options.allow_origins}
                    live_port = None
                self._open(
                    open_sink(path, progress=self._progress, waypoints=options.waypoints, **extra)
                )
            if live_port is not None:
                self._open(
                    FoxgloveSink(
                        None,
                        live_port=live_port,
                        allow_origins=options.allow_origins,
                        progress=self._progress,
                    )
                )
            self.foxglove_url = next(
                (url for sink in self._opened if (url := getattr(sink, "live_url", None))), None
            )
            if self.foxglove_url:
                self._progress(
                    f"Foxglove can watch this flight live: open a Foxglove "
                    f"WebSocket connection to {self.foxglove_url}"
                )
        except BaseException:
            self.close()
            raise
        return self

    def _open(self, sink: RowSink) -> None:
        self.sinks.append(sink)
        self._opened.append(sink)

    # -- during the flight ----------------------------------------------------------------
    def on_row(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        self._last_time_s = row.time_s
        for sink in self.sinks:
            sink.write(row, sample)
        if self.watch is not None:
            self.watch.add(row, sample)
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
        """What each sink writes from the whole flight (the plot, the summary); what was
        written, in words.  The analysers' findings go into ``summary`` first
        (``findings``, ``analysers``), so the summary file has them."""
        if self.watch is not None:
            self.analysis = self.watch.analysis()
            summary["findings"] = [f.as_dict() for f in self.analysis.findings]
            summary["analysers"] = {
                "watched": self.analysis.watched,
                "skipped": self.analysis.skipped,
            }
        written = [sink.finish(result, summary) for sink in self._opened]
        return [line for line in written if line]


def plan_waypoints(plan: MissionPlan) -> list[tuple[float, float]]:
    """The plan's waypoints as (north, east) for the plot."""
    return [(w.north_m, w.east_m) for w in plan.waypoints]
