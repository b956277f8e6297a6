"""One place turns a flight's rows into every format: CSV, MCAP, plot, summary."""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest
from test_flight_record import make_row, read_mcap

from bfsitl.errors import BfsitlError
from bfsitl.mission.flight_log import read_flight_log
from bfsitl.mission.outputs import FlightOutputs, OutputOptions


def test_rows_and_events_reach_every_sink_and_the_files_agree(tmp_path):
    outputs = FlightOutputs(OutputOptions(csv_path=tmp_path / "f.csv",
                                          mcap_path=tmp_path / "f.mcap",
                                          summary_path=tmp_path / "out" / "f.json",
                                          plot_path=tmp_path / "f.png")).start()
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
    result = SimpleNamespace(rows=rows, controller="fused", outcome=SimpleNamespace(
        value="landed"))
    written = outputs.finish(result, {"outcome": "landed"})  # type: ignore[arg-type]
    assert json.loads((tmp_path / "out" / "f.json").read_text()) == {"outcome": "landed"}
    assert (tmp_path / "f.png").stat().st_size > 10_000
    assert [w.split()[0] for w in written] == ["log", "MCAP", "plot", "summary"]


def test_a_sink_that_fails_to_close_does_not_keep_the_others_open(tmp_path):
    outputs = FlightOutputs(OutputOptions(csv_path=tmp_path / "f.csv",
                                          mcap_path=tmp_path / "f.mcap")).start()
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
    outputs = FlightOutputs(OutputOptions(csv_path=tmp_path / "file" / "f.csv",
                                          mcap_path=tmp_path / "f.mcap"))
    with pytest.raises(BfsitlError, match="cannot write the flight log"):
        outputs.start()
    assert outputs.sinks == [] and not (tmp_path / "f.mcap").exists()
