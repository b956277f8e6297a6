"""Record sinks, chosen by the file's suffix: the one place where rows become records.

A sink takes each row as it is flown (:meth:`RowSink.write`), each event, and is closed on
every way out; what it writes from the whole flight (a plot, a summary) it writes in
:meth:`RowSink.finish`.  :func:`open_sink` picks the sink for a path from the registry:

=========================  =====================================================
suffix                     sink
=========================  =====================================================
``.csv``                   the flight log, one row per control step, flushed row by row
``.mcap``                  Foxglove's schemas in an MCAP file (the ``foxglove`` extra)
``.png`` ``.svg`` ``.pdf`` the flight plot, drawn from the rows at the end
``.json``                  the summary of the result, at the end
=========================  =====================================================

``bfsitl fly``, the :class:`~bfsitl.autopilot.Autopilot` and scenario runs all open their
files here; :func:`register_sink` adds a format (``register_sink(".parquet", MySink)``).
"""

from __future__ import annotations

import json
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_row import FlightRow
from bfsitl.records.csv_log import CsvFlightLog

if TYPE_CHECKING:
    from bfsitl.mission.results import MissionResult
    from bfsitl.mission.vehicle import FlightSample


class RowSink(Protocol):
    """Something that takes the rows as they are flown."""

    streams: ClassVar[bool]

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None: ...

    def event(self, time_s: float, text: str) -> None: ...

    def close(self) -> None: ...

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        """Write what needs the whole flight; what was written, in words (None: nothing)."""
        ...


class SinkBase:
    """A sink that ignores what it does not use (subclasses override the rest)."""

    #: Whether it writes as the rows come (a log) or only from the whole flight, at
    #: :meth:`finish` (a plot, a summary): a caller that never finishes (the
    #: :class:`~bfsitl.autopilot.Autopilot`) takes streaming sinks only.
    streams: ClassVar[bool] = True

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        pass

    def event(self, time_s: float, text: str) -> None:
        pass

    def close(self) -> None:
        pass

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        return None


class CsvSink(SinkBase):
    """The CSV flight log (it has no events: its rows are the record)."""

    def __init__(self, path: Path, **_options: Any) -> None:
        self.log = CsvFlightLog(path)

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        self.log.write(row)

    def close(self) -> None:
        self.log.close()

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        return f"log {self.log.path} ({self.log.rows_written} rows)"


class FoxgloveSink(SinkBase):
    """The flight in Foxglove's schemas: to an MCAP file as it is flown, and/or served live
    on 127.0.0.1 at ``live_port`` (0: any free port; :attr:`live_url` once serving).  One
    recorder does both, so a watched and recorded flight encodes each message once."""

    def __init__(
        self,
        path: Path | None,
        *,
        live_port: int | None = None,
        allow_origins: tuple[str, ...] = (),
        progress: Callable[[str], None] | None = None,
        **_options: Any,
    ) -> None:
        from bfsitl.records.foxglove import FoxgloveRecorder

        say = progress or (lambda _line: None)
        self.path = path
        self.recorder = FoxgloveRecorder(
            mcap_path=path,
            live_port=live_port,
            allow_origins=allow_origins,
            on_event=lambda line: say(f"foxglove: {line}"),
        )
        self.recorder.start()
        self.live_url: str | None = self.recorder.live_url

    def write(self, row: FlightRow, sample: FlightSample | None = None) -> None:
        self.recorder.write(row, sample)

    def event(self, time_s: float, text: str) -> None:
        self.recorder.event(time_s, text)

    def close(self) -> None:
        self.recorder.close()

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        return f"MCAP {self.path}" if self.path is not None else None


class PlotSink(SinkBase):
    """Altitude, throttle, attitude (and the ground track with waypoints), drawn at the end."""

    streams = False

    def __init__(
        self, path: Path, *, waypoints: Sequence[tuple[float, float]] = (), **_options: Any
    ) -> None:
        self.path = path
        self.waypoints = list(waypoints)

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        if not result.rows:
            return None
        from bfsitl.records.plot import write_flight_plot

        write_flight_plot(
            result.rows,
            self.path,
            title=f"bfsitl fly: {result.controller}, {result.outcome.value}",
            waypoints=self.waypoints,
        )
        return f"plot {self.path}"


class SummarySink(SinkBase):
    """The result's summary as JSON, at the end."""

    streams = False

    def __init__(self, path: Path, **_options: Any) -> None:
        self.path = path

    def finish(self, result: MissionResult, summary: dict[str, Any]) -> str | None:
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.path.write_text(json.dumps(summary, indent=2) + "\n")
        except OSError as exc:
            raise BfsitlError(f"cannot write the summary {self.path}: {exc}") from exc
        return f"summary {self.path}"


SinkFactory = Callable[..., RowSink]
_SINKS: dict[str, SinkFactory] = {
    ".csv": CsvSink,
    ".mcap": FoxgloveSink,
    ".png": PlotSink,
    ".svg": PlotSink,
    ".pdf": PlotSink,
    ".json": SummarySink,
}


def register_sink(suffix: str, factory: SinkFactory) -> None:
    """Records written to files ending in ``suffix`` (``".parquet"``) come from ``factory``,
    called as ``factory(path, progress=..., waypoints=...)``."""
    if not suffix.startswith(".") or len(suffix) < 2:
        raise BfsitlError(f"a sink suffix starts with a dot, like '.csv', not {suffix!r}")
    _SINKS[suffix.lower()] = factory


def sink_suffixes() -> tuple[str, ...]:
    return tuple(sorted(_SINKS))


def open_sink(path: str | Path, **options: Any) -> RowSink:
    """The sink for ``path``, chosen by its suffix (see the module docstring)."""
    path = Path(path)
    factory = _SINKS.get(path.suffix.lower())
    if factory is None:
        what = path.suffix or "a file without a suffix"
        raise BfsitlError(
            f"{path}: no record format for {what}; known: {', '.join(sink_suffixes())}"
        )
    return factory(path, **options)
