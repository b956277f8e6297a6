"""The JUnit XML (read back with junitparser, a parser from the registry) and the report page."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest
from junitparser import Error, Failure, JUnitXml, Skipped

from bfsitl.scenario.junit import write_junit
from bfsitl.scenario.report import write_report
from bfsitl.scenario.result import CheckResult, ScenarioResult, TimedEvent, Verdict


def results(tmp_path: Path) -> list[ScenarioResult]:
    plot = tmp_path / "runs" / "drop" / "plot.png"
    plot.parent.mkdir(parents=True)
    plot.write_bytes(b"\x89PNG fake")
    ok = CheckResult("disarmed = true", True, "disarmed = true: the FC was disarmed at the end",
                     "disarmed", 11.2)
    bad = CheckResult("disarmed_within_s = 0.2", False,
                      "disarmed_within_s = 0.2: disarmed 0.52 s after the fault (expected "
                      "within 0.2 s) at t=8.53 s", 0.52, 8.53)
    return [
        ScenarioResult("drop", "master-lockstep", Verdict.FAILED, bad.message,
                       firmware_version="2026.12.0-alpha", checks=[ok, bad],
                       events=[TimedEvent(8.0, "RC lost (silence)")], sim_time_s=11.2,
                       wall_time_s=2.0, artifacts={"plot": plot}),
        ScenarioResult("hover", "master-lockstep", Verdict.PASSED, "all 1 expectations met",
                       checks=[ok], sim_time_s=20.0, wall_time_s=3.0),
        ScenarioResult("gps-loss", "4.6.0-gps-lockstep", Verdict.SKIPPED,
                       "gps_loss cannot happen on Betaflight 4.6.0"),
        ScenarioResult("<script>alert(1)</script>", "4.6.0-gps-lockstep", Verdict.ERROR,
                       "the SITL exited with code 1"),
    ]


def test_the_junit_file_reads_back_with_a_suite_per_firmware(tmp_path: Path) -> None:
    path = write_junit(results(tmp_path), tmp_path / "out" / "results.xml")
    ElementTree.parse(path)  # well-formed
    xml = JUnitXml.fromfile(str(path))
    suites = {suite.name: suite for suite in xml}
    master = suites["bfsitl scenarios [master-lockstep]"]
    older = suites["bfsitl scenarios [4.6.0-gps-lockstep]"]
    assert (master.tests, master.failures, master.errors, master.skipped) == (2, 1, 0, 0)
    assert (older.tests, older.failures, older.errors, older.skipped) == (2, 0, 1, 1)
    drop = next(case for case in master if case.name == "drop")
    failure = next(r for r in drop.result if isinstance(r, Failure))
    assert failure.message.startswith("disarmed_within_s = 0.2: disarmed 0.52 s")
    assert "FAIL disarmed_within_s = 0.2" in failure.text and "PASS disarmed = true" in \
        failure.text
    assert "RC lost (silence)" in drop.system_out
    assert any(isinstance(r, Skipped) for r in next(c for c in older
                                                     if c.name == "gps-loss").result)
    assert any(isinstance(r, Error) for r in next(c for c in older if "script" in c.name).result)
    properties = {p.name: p.value for p in master.properties()}
    assert properties["firmware_version"] == "2026.12.0-alpha"
    assert properties["drop.sim_time_s"] == "11.2"
    assert properties["drop.plot"].endswith("plot.png")


def test_a_junit_file_is_replaced_whole(tmp_path: Path) -> None:
    path = tmp_path / "results.xml"
    path.write_text("an older run")
    write_junit(results(tmp_path)[:1], path)
    assert JUnitXml.fromfile(str(path)).tests == 1
    assert not list(tmp_path.glob("*.tmp"))


def test_the_report_escapes_names_and_links_files_relatively(tmp_path: Path) -> None:
    page = write_report(results(tmp_path), tmp_path / "report").read_text()
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page and "<script>" not in page
    assert 'src="../runs/drop/plot.png"' in page and 'href="../runs/drop/plot.png"' in page
    for word in ("FAILED", "PASSED", "SKIPPED", "ERROR", "drop", "hover", "gps-loss"):
        assert word in page
    assert "4 runs" in page and "1 passed, 1 failed, 1 error, 1 skipped" in page
    assert "disarmed 0.52 s after the fault" in page


@pytest.mark.parametrize("missing", [True, False])
def test_a_missing_plot_is_left_out(tmp_path: Path, missing: bool) -> None:
    runs = results(tmp_path)
    if missing:
        runs[0].artifacts["plot"].unlink()
    page = write_report(runs, tmp_path / "report").read_text()
    assert ("<img" in page) is not missing
