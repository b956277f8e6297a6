"""One place turns a flight's rows into every format: CSV, MCAP, plot, summary."""

from __future__ import annotations

import json
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from support.flight_rows import make_row, read_mcap

from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_row import COLUMNS, FlightRow
from bfsitl.records.csv_log import _cell, _cells, read_flight_log
from bfsitl.records.outputs import FlightOutputs, OutputOptions


def test_rows_and_events_reach_every_sink_and_the_files_agree(tmp_path):
    outputs = FlightOutputs(
        OutputOptions(
            csv_path=tmp_path / "f.csv",
            mcap_path=tmp_path / "f.mcap",
            summary_path=tmp_path / "out" / "f.json",
            plot_path=tmp_path / "f.png",
        )
    ).start()
    rows = [make_row(i) for i in range(40)]
    try:
        for row in rows[:10]:
            outputs.on_row(row)
        outputs.on_event("take-off to 2.00 m")  # stamped with the latest row's time
        for row in rows[10:]:
            outputs.on_row(row)
    finally:
        outputs.close()
    outputs.close()  # idempotent
    assert len(read_flight_log(tmp_path / "f.csv")) == 40
    counts, messages = read_mcap(tmp_path / "f.mcap")
    assert counts["/flight/altitude"] == 40
    take_off = [m for _s, m, d in messages["/events"] if d.message == "take-off to 2.00 m"]
    assert take_off[0].log_time == round(rows[9].time_s * 1e9)
    result = SimpleNamespace(rows=rows, controller="fused", outcome=SimpleNamespace(value="landed"))
    written = outputs.finish(result, {"outcome": "landed"})  # type: ignore[arg-type]
    # The analysers watched every row: what they found (nothing here) is in the summary.
    summary = json.loads((tmp_path / "out" / "f.json").read_text())
    assert summary["outcome"] == "landed" and summary["findings"] == []
    assert "crash" in summary["analysers"]["watched"]
    assert (tmp_path / "f.png").stat().st_size > 10_000
    assert [w.split()[0] for w in written] == ["log", "MCAP", "plot", "summary"]


def test_what_the_analysers_find_in_the_rows_goes_into_the_summary(tmp_path):
    outputs = FlightOutputs(OutputOptions(summary_path=tmp_path / "f.json")).start()
    rows = [make_row(i, motor2=1.0 if 20 <= i < 60 else 0.52) for i in range(100)]
    for row in rows:
        outputs.on_row(row)
    outputs.close()
    result = SimpleNamespace(rows=rows, controller="fused", outcome=SimpleNamespace(value="landed"))
    outputs.finish(result, {"outcome": "landed"})  # type: ignore[arg-type]
    (finding,) = json.loads((tmp_path / "f.json").read_text())["findings"]
    assert finding["analyser"] == "motor_saturation" and finding["severity"] == "warning"
    assert finding["evidence"]["motors"] == [2] and finding["value"] == 0.8
    unwatched = FlightOutputs(OutputOptions(watch=False)).start()
    unwatched.on_row(rows[0])
    summary: dict = {}
    unwatched.finish(result, summary)  # type: ignore[arg-type]
    assert "findings" not in summary and unwatched.analysis is None


def test_a_sink_that_fails_to_close_does_not_keep_the_others_open(tmp_path):
    outputs = FlightOutputs(
        OutputOptions(csv_path=tmp_path / "f.csv", mcap_path=tmp_path / "f.mcap")
    ).start()
    outputs.on_row(make_row(0))

    class Broken:
        def write(self, row, sample=None) -> None: ...  # noqa: ANN001
        def event(self, time_s, text) -> None: ...  # noqa: ANN001
        def close(self) -> None:
            raise OSError("disk gone")

    outputs.sinks.insert(1, Broken())  # type: ignore[arg-type]
    with pytest.raises(BfsitlError, match="disk gone"):
        outputs.close()
    assert outputs.sinks == []
    assert read_mcap(tmp_path / "f.mcap")[0]["/rc"] == 1  # the MCAP was still finished


def test_an_unwritable_log_fails_before_the_flight_and_opens_nothing(tmp_path):
    (tmp_path / "file").write_text("x")
    outputs = FlightOutputs(
        OutputOptions(csv_path=tmp_path / "file" / "f.csv", mcap_path=tmp_path / "f.mcap")
    )
    with pytest.raises(BfsitlError, match="cannot write the flight log"):
        outputs.start()
    assert outputs.sinks == [] and not (tmp_path / "f.mcap").exists()


# -- the registry: a sink per file suffix ---------------------------------------------------
def test_each_suffix_opens_its_sink_and_an_unknown_one_says_which_exist(tmp_path):
    from bfsitl.records.sinks import CsvSink, FoxgloveSink, PlotSink, SummarySink, open_sink

    kinds = {
        suffix: type(open_sink(tmp_path / f"f{suffix}"))
        for suffix in (".csv", ".CSV", ".png", ".svg", ".json")
    }
    assert kinds == {
        ".csv": CsvSink,
        ".CSV": CsvSink,
        ".png": PlotSink,
        ".svg": PlotSink,
        ".json": SummarySink,
    }
    mcap = open_sink(tmp_path / "f.mcap")
    assert isinstance(mcap, FoxgloveSink) and mcap.live_url is None
    mcap.close()
    with pytest.raises(BfsitlError, match=r"no record format for \.txt; known: \.csv"):
        open_sink(tmp_path / "f.txt")
    with pytest.raises(BfsitlError, match="without a suffix"):
        open_sink(tmp_path / "f")


def test_a_registered_format_is_written_like_the_built_in_ones(tmp_path):
    from bfsitl.records import sinks

    class Lines(sinks.SinkBase):
        def __init__(self, path, **_options):  # type: ignore[no-untyped-def]
            self.file = path.open("w")

        def write(self, row, sample=None):  # type: ignore[no-untyped-def]
            self.file.write(f"{row.time_s:.2f} {row.phase}\n")

        def close(self):  # type: ignore[no-untyped-def]
            self.file.close()

    with pytest.raises(BfsitlError, match="starts with a dot"):
        sinks.register_sink("lines", Lines)
    sinks.register_sink(".lines", Lines)
    try:
        outputs = FlightOutputs(
            OutputOptions(csv_path=tmp_path / "f.csv", extra_paths=(tmp_path / "f.lines",))
        ).start()
        for index in range(5):
            outputs.on_row(make_row(index))
        outputs.close()
    finally:
        sinks._SINKS.pop(".lines")
    assert (tmp_path / "f.lines").read_text().splitlines()[-1] == "3.08 hold"
    assert len(read_flight_log(tmp_path / "f.csv")) == 5


def test_the_autopilot_records_in_the_format_its_log_names(tmp_path):
    from support.fake_vehicles import FakeVehicle, PController

    from bfsitl.autopilot import Autopilot

    vehicle = FakeVehicle()
    pilot = Autopilot(vehicle, PController(), log=tmp_path / "flight.mcap")  # type: ignore[arg-type]
    pilot.takeoff(1.0)
    vehicle.close()  # the log is closed with the vehicle
    counts, _messages = read_mcap(tmp_path / "flight.mcap")
    assert counts["/flight/altitude"] == len(pilot.rows) > 50


def test_the_autopilot_log_carries_its_events_and_refuses_a_format_written_only_at_the_end(
    tmp_path,
):
    from support.fake_vehicles import FakeVehicle, PController

    from bfsitl.autopilot import Autopilot
    from bfsitl.errors import MissionError

    heard: list[str] = []
    vehicle = FakeVehicle()
    pilot = Autopilot(
        vehicle,
        PController(),
        log=tmp_path / "flight.mcap",  # type: ignore[arg-type]
        on_event=heard.append,
    )
    pilot.takeoff(1.0)
    vehicle.close()
    _counts, messages = read_mcap(tmp_path / "flight.mcap")
    logged = [decoded.message for _schema, _message, decoded in messages["/events"]]
    assert heard and all(line in logged for line in heard)
    for name in ("flight.png", "flight.json"):
        with pytest.raises(MissionError, match="written as it flies; name a .csv or .mcap"):
            Autopilot(FakeVehicle(), PController(), log=tmp_path / name)  # type: ignore[arg-type]
        assert not (tmp_path / name).exists()


@settings(max_examples=200, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.floats(allow_nan=True, allow_infinity=True),
            st.integers(-5000, 5000),
            st.booleans(),
            st.text(max_size=8),
            st.floats(-1e6, 1e6).map(np.float64),  # a float's subclass takes the long way
        ),
        min_size=len(COLUMNS),
        max_size=len(COLUMNS),
    )
)
def test_a_row_s_cells_are_each_cell_as_written_one_at_a_time(values) -> None:
    """The row's cells made in one pass are the one-cell-at-a-time ones, whatever the type
    each value has (a float column may hold an int, a numpy float, NaN)."""
    row = FlightRow(**dict(zip(COLUMNS, values, strict=True)))
    assert _cells(row) == [_cell(value) for value in values]
