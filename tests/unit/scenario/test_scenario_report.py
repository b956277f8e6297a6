"""The JUnit XML (read back with junitparser, an independent reader from the registry, and
parsed by ElementTree) and the HTML report page (parsed by html.parser)."""

from __future__ import annotations

import base64
import xml.etree.ElementTree as ElementTree
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote

import pytest
from junitparser import Error, Failure, JUnitXml, Skipped, TestSuite

from bfsitl.analysis import Finding, Severity
from bfsitl.scenario import report as report_module
from bfsitl.scenario.junit import write_junit
from bfsitl.scenario.report import write_report
from bfsitl.scenario.result import CheckResult, ScenarioResult, TimedEvent, Verdict

MASTER = "master-lockstep"
OLDER = "4.6.0-gps-lockstep"
EVIL = "<script>alert(1)</script>"

OK = CheckResult(
    "disarmed = true", True, "disarmed = true: the FC was disarmed at the end", "disarmed", 11.2
)
BAD = CheckResult(
    "disarmed_within_s = 0.2",
    False,
    "disarmed_within_s = 0.2: disarmed 0.52 s after the fault (expected within 0.2 s) at t=8.53 s",
    0.52,
    8.53,
)
CRASH = Finding(
    "crash",
    Severity.FAILURE,
    "hit the ground at 7.0 m/s, upside down",
    9.3,
    7.0,
    "m/s",
    {"touchdown_speed_m_s": 7.0, "tilt_at_rest_deg": 171.2},
)


def make_results(root: Path) -> list[ScenarioResult]:
    """Every verdict, two firmwares; the failed run has a plot and a log on disk, a file
    named but never written, and a source file under ``root``."""
    run_dir = root / "runs" / "drop"
    run_dir.mkdir(parents=True)
    (run_dir / "plot.png").write_bytes(b"\x89PNG fake")
    (run_dir / "flight log.csv").write_text("time_s\n0.0\n")
    source = root / "scenarios" / "drop.toml"
    source.parent.mkdir()
    source.write_text("# a scenario\n")
    return [
        ScenarioResult(
            "drop",
            MASTER,
            Verdict.FAILED,
            BAD.message,
            source=source,
            firmware_version="2026.12.0-alpha",
            checks=[OK, BAD],
            events=[TimedEvent(8.0, "RC lost (silence)"), TimedEvent(8.52, "disarmed")],
            sim_time_s=11.2,
            wall_time_s=2.0,
            findings=[CRASH],
            watched=["crash", "failsafe"],
            unwatched={"gps_glitch": "the flight track has no fc_north_m"},
            artifacts={
                "plot": run_dir / "plot.png",
                "log": run_dir / "flight log.csv",
                "blackbox": run_dir / "never-written.bbl",
            },
        ),
        ScenarioResult(
            "hover",
            MASTER,
            Verdict.PASSED,
            "all 1 expectations met",
            firmware_version="2026.12.0-alpha",
            checks=[OK],
            sim_time_s=20.0,
            wall_time_s=3.0,
        ),
        ScenarioResult(
            "gps-loss", OLDER, Verdict.SKIPPED, "gps_loss cannot happen on Betaflight 4.6.0"
        ),
        ScenarioResult(
            EVIL,
            OLDER,
            Verdict.ERROR,
            "the SITL exited with code 1",
            events=[TimedEvent(0.5, "SITL started")],
            sim_time_s=0.5,
            wall_time_s=1.0,
        ),
    ]


def suites_by_name(path: Path) -> dict[str, TestSuite]:
    return {suite.name: suite for suite in JUnitXml.fromfile(str(path))}


# --- JUnit --------------------------------------------------------------------------------


def test_junit_has_one_suite_per_firmware_with_the_right_counts(tmp_path: Path) -> None:
    path = write_junit(make_results(tmp_path), tmp_path / "out" / "results.xml")
    assert path == tmp_path / "out" / "results.xml"
    ElementTree.parse(path)  # well-formed, or this raises
    suites = suites_by_name(path)
    assert set(suites) == {f"bfsitl scenarios [{MASTER}]", f"bfsitl scenarios [{OLDER}]"}
    master, older = suites[f"bfsitl scenarios [{MASTER}]"], suites[f"bfsitl scenarios [{OLDER}]"]
    assert (master.tests, master.failures, master.errors, master.skipped) == (2, 1, 0, 0)
    assert (older.tests, older.failures, older.errors, older.skipped) == (2, 0, 1, 1)
    assert master.time == pytest.approx(5.0)


def test_junit_cases_carry_name_classname_time_and_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    path = write_junit(make_results(tmp_path), tmp_path / "results.xml")
    master = suites_by_name(path)[f"bfsitl scenarios [{MASTER}]"]
    drop = next(case for case in master if case.name == "drop")
    assert drop.classname == "scenarios.master-lockstep"
    assert drop.time == pytest.approx(2.0)
    older = suites_by_name(path)[f"bfsitl scenarios [{OLDER}]"]
    assert {case.classname for case in older} == {"scenarios.4_6_0-gps-lockstep"}
    files = {
        case.get("name"): case.get("file")
        for case in ElementTree.parse(path).getroot().iter("testcase")
    }
    assert files["drop"] == "scenarios/drop.toml"  # relative to the current directory
    assert files["hover"] is None  # no source, no attribute


def test_junit_failure_message_is_the_reason_and_its_text_lists_checks_and_events(
    tmp_path: Path,
) -> None:
    path = write_junit(make_results(tmp_path), tmp_path / "results.xml")
    master = suites_by_name(path)[f"bfsitl scenarios [{MASTER}]"]
    drop = next(case for case in master if case.name == "drop")
    (failure,) = drop.result
    assert isinstance(failure, Failure)
    assert failure.message == BAD.message
    assert f"FAIL {BAD.message}" in failure.text
    assert f"PASS {OK.message}" in failure.text
    assert "t=   8.000 s  RC lost (silence)" in failure.text
    assert "RC lost (silence)" in drop.system_out
    hover = next(case for case in master if case.name == "hover")
    assert hover.is_passed and not hover.result


def test_junit_error_and_skipped_carry_their_reasons(tmp_path: Path) -> None:
    path = write_junit(make_results(tmp_path), tmp_path / "results.xml")
    older = suites_by_name(path)[f"bfsitl scenarios [{OLDER}]"]
    cases = {case.name: case for case in older}
    (skipped,) = cases["gps-loss"].result
    assert isinstance(skipped, Skipped)
    assert skipped.message == "gps_loss cannot happen on Betaflight 4.6.0"
    (error,) = cases[EVIL].result  # the name survives the round trip unchanged
    assert isinstance(error, Error)
    assert error.message == "the SITL exited with code 1"
    assert "SITL started" in error.text


def test_junit_properties_hold_version_sim_time_and_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    path = write_junit(make_results(tmp_path), tmp_path / "results.xml")
    master = suites_by_name(path)[f"bfsitl scenarios [{MASTER}]"]
    properties = {p.name: p.value for p in master.properties()}
    assert properties["firmware_version"] == "2026.12.0-alpha"
    assert properties["drop.sim_time_s"] == "11.2"
    assert properties["drop.vehicle"] == "iris"
    assert properties["hover.sim_time_s"] == "20"
    assert properties["drop.plot"] == "runs/drop/plot.png"
    assert properties["drop.log"] == "runs/drop/flight log.csv"
    assert (
        properties["drop.finding.crash"]
        == "failure at t=9.30 s: hit the ground at 7.0 m/s, upside down"
    )
    assert not any(".finding." in name for name in properties if name.startswith("hover"))
    older = suites_by_name(path)[f"bfsitl scenarios [{OLDER}]"]
    assert "firmware_version" not in {p.name for p in older.properties()}


def test_junit_survives_control_characters_in_messages(tmp_path: Path) -> None:
    """A SITL's stdout can hold ANSI escapes and NULs, which XML 1.0 cannot carry."""
    broken = ScenarioResult(
        "noisy",
        MASTER,
        Verdict.ERROR,
        "exited: \x1b[31mboom\x00",
        events=[TimedEvent(1.0, "bell \x07")],
    )
    path = write_junit([broken], tmp_path / "results.xml")
    ElementTree.parse(path)
    (case,) = next(iter(JUnitXml.fromfile(str(path))))
    assert case.result[0].message == "exited: \\x1b[31mboom\\x00"


def test_junit_replaces_an_older_file_whole(tmp_path: Path) -> None:
    path = tmp_path / "results.xml"
    path.write_text("an older run")
    write_junit(make_results(tmp_path)[:1], path)
    assert JUnitXml.fromfile(str(path)).tests == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.xml", "runs", "scenarios"]


def test_an_interrupted_write_leaves_the_old_file_and_no_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "results.xml"
    path.write_text("an older run")

    def interrupted(source: object, target: object) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(report_module.os, "replace", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_junit(make_results(tmp_path), path)
    assert path.read_text() == "an older run"
    assert not list(tmp_path.glob(".*.tmp"))


# --- HTML report ----------------------------------------------------------------------------


class PageParser(HTMLParser):
    """The tags, links and image sources of a page, as a browser would see them."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: set[str] = set()
        self.hrefs: list[str] = []
        self.srcs: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.add(tag)
        values = dict(attrs)
        if tag == "a" and values.get("href"):
            self.hrefs.append(values["href"] or "")
        if tag == "img" and values.get("src"):
            self.srcs.append(values["src"] or "")

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def parse_page(path: Path) -> tuple[str, PageParser]:
    page = path.read_text(encoding="utf-8")
    parser = PageParser()
    parser.feed(page)
    return page, parser


def test_the_report_lists_every_run_and_verdict(tmp_path: Path) -> None:
    path = write_report(make_results(tmp_path), tmp_path / "report")
    assert path == tmp_path / "report" / "index.html" and path.is_file()
    page, parser = parse_page(path)
    text = " ".join(parser.text)
    for word in ("drop", "hover", "gps-loss", EVIL, "FAILED", "PASSED", "SKIPPED", "ERROR"):
        assert word in text  # the escaped name reads as the name once parsed
    assert "4 runs" in text and "1 passed, 1 failed, 1 error, 1 skipped" in text
    assert "31.7 s simulated in 6.0 s" in text and "5.3x real time" in text
    assert BAD.message in text and OK.message in text
    assert "RC lost (silence)" in text and "gps_loss cannot happen on Betaflight 4.6.0" in text
    # What the analysers found, with its evidence, and what they could not watch.
    assert "hit the ground at 7.0 m/s, upside down" in text
    assert "touchdown_speed_m_s=7.0" in text
    assert "not watched: gps_glitch (the flight track has no fc_north_m)" in text
    assert 'class="finding failure"' in page


def test_the_report_escapes_user_text_and_runs_no_script(tmp_path: Path) -> None:
    page, parser = parse_page(
        write_report(make_results(tmp_path), tmp_path / "report", title="<b>nightly</b>")
    )
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert "<script" not in page and "script" not in parser.tags
    assert "&lt;b&gt;nightly&lt;/b&gt;" in page and "<b>nightly</b>" in " ".join(parser.text)
    assert "://" not in page  # nothing fetched: no external CSS, fonts or images
    assert "<style>" in page


def test_the_report_links_existing_files_relatively(tmp_path: Path) -> None:
    directory = tmp_path / "report"
    _, parser = parse_page(write_report(make_results(tmp_path), directory))
    files = [href for href in parser.hrefs if not href.startswith("#")]
    assert sorted(files) == ["../runs/drop/flight%20log.csv", "../runs/drop/plot.png"]
    for href in files:
        assert (directory / unquote(href)).is_file()
    assert "never-written.bbl" not in " ".join(parser.hrefs)  # named, absent: no dead link
    # The plots are in the page itself: copied anywhere (a CI artefact), it still shows them.
    (src,) = parser.srcs
    plot = (tmp_path / "runs" / "drop" / "plot.png").read_bytes()
    assert src == "data:image/png;base64," + base64.b64encode(plot).decode("ascii")
    anchors = [href for href in parser.hrefs if href.startswith("#")]
    assert len(anchors) == 4


def test_the_report_leaves_out_a_plot_that_was_not_written(tmp_path: Path) -> None:
    runs = make_results(tmp_path)
    runs[0].artifacts["plot"].unlink()
    _, parser = parse_page(write_report(runs, tmp_path / "report"))
    assert parser.srcs == [] and "img" not in parser.tags


def test_the_report_replaces_an_older_page_whole(tmp_path: Path) -> None:
    directory = tmp_path / "report"
    directory.mkdir()
    (directory / "index.html").write_text("an older run")
    write_report(make_results(tmp_path)[1:2], directory)
    page = (directory / "index.html").read_text()
    assert "hover" in page and "an older run" not in page
    assert [p.name for p in directory.iterdir()] == ["index.html"]


def test_a_run_retried_on_a_cluster_says_so_once_in_junit_and_in_the_report(tmp_path: Path) -> None:
    retried = ScenarioResult(
        "hover",
        "4.6.0",
        Verdict.PASSED,
        "all 2 expectations met",
        retried=("its Ray worker or node was lost (NodeDiedError)",),
    )
    other = ScenarioResult("drop", "4.6.0", Verdict.PASSED, "all 1 expectations met")
    write_junit([retried, other], tmp_path / "results.xml")
    cases = {
        case.name: case
        for suite in JUnitXml.fromfile(str(tmp_path / "results.xml"))
        for case in suite
    }
    assert sorted(cases) == ["drop", "hover"]  # once each
    assert (cases["hover"].system_out or "").startswith(
        "retried: attempt 1 was lost: its Ray worker or node was lost (NodeDiedError)"
    )
    assert "retried" not in (cases["drop"].system_out or "")
    write_report([retried, other], tmp_path / "report")
    html = (tmp_path / "report" / "index.html").read_text()
    assert "all 2 expectations met (run 2 times: its Ray worker or node was lost" in html
    assert "all 1 expectations met (run" not in html


def test_the_report_shows_what_each_runs_fc_was_given(tmp_path: Path) -> None:
    results = make_results(tmp_path)
    results[0].settings = [
        ("bfsitl", "set ap_hover_throttle = 1545", "iris's hover"),
        ("the side", "set ap_hover_throttle = 1275", ""),
        ("the scenario", "set failsafe_procedure = DROP<x>", ""),
    ]
    page, parser = parse_page(write_report(results, tmp_path / "report"))
    text = " ".join(parser.text)
    assert "configuration: the 3 lines its FC was given" in text
    assert "iris's hover (a later line sets it again)" in text  # the side's 1275 won
    assert text.count("(a later line sets it again)") == 1
    assert "DROP&lt;x&gt;" in page  # escaped like every other user text
    assert text.count("lines its FC was given") == 1  # runs without settings show none
