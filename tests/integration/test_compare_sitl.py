"""`bfsitl scenario compare` against the real firmware: a build against itself is the same on
every scenario over three seeds, and a changed default changes exactly the scenarios it
reaches."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from junitparser import Failure, JUnitXml
from test_scenarios_sitl import ALWAYS, LIBRARY, env_for

from bfsitl.blackbox import decode_blackbox
from bfsitl.build.cache import FirmwareCache

pytestmark = pytest.mark.sitl


def compare(
    tmp_path: Path, cache: FirmwareCache, names: list[str], *options: str
) -> tuple[subprocess.CompletedProcess[str], dict]:
    out = tmp_path / "cmp"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "bfsitl.cli.main",
            "scenario",
            "compare",
            *(str(LIBRARY / f"{name}.toml") for name in names),
            "--firmware",
            ALWAYS,
            "--jobs",
            "2",
            "--out",
            str(out),
            "--junit",
            str(tmp_path / "cmp.xml"),
            "--report",
            str(tmp_path / "report"),
            *options,
        ],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=tmp_path,
        env=env_for(cache),
    )
    data = json.loads((out / "compare.json").read_text()) if (out / "compare.json").exists() else {}
    return run, data


@pytest.mark.timeout(900)
def test_a_build_against_itself_is_the_same_on_every_scenario_over_three_seeds(
    lockstep_gps_46_firmware, firmware_build_cache: FirmwareCache, tmp_path: Path
) -> None:
    names = ["rc-loss-hover-drop", "gps-glitch-hold", "motor-weak"]
    run, data = compare(tmp_path, firmware_build_cache, names, "--firmware", ALWAYS, "--seeds", "3")
    assert run.returncode == 0, run.stdout + run.stderr[-3000:]
    assert [s["change"] for s in data["scenarios"]] == ["same"] * 3, run.stdout
    for scenario in data["scenarios"]:
        for figure in scenario["figures"]:
            # Seed by seed, side B flew exactly what side A flew (lockstep is repeatable).
            assert figure["a"] == figure["b"], (scenario["name"], figure)
    # The seeds really differ, so "same" was judged against a real spread.
    drop = next(s for s in data["scenarios"] if s["name"] == "rc-loss-hover-drop")
    landed = next(f for f in drop["figures"] if f["name"] == "landed_distance_m")
    assert len(set(landed["a"])) == 3, landed
    xml = JUnitXml.fromfile(str(tmp_path / "cmp.xml"))
    assert sum(len(list(suite)) for suite in xml) == 3 and xml.failures == 0


@pytest.mark.timeout(900)
def test_a_changed_default_changes_the_scenarios_it_reaches_and_only_those(
    lockstep_gps_46_firmware, firmware_build_cache: FirmwareCache, tmp_path: Path
) -> None:
    """The firmware's own hover throttle (1275 us, a light racer's) instead of the IRIS's
    1545 that bfsitl provisions: the FC's AUTO-LAND starts from it and falls. A DROP does
    not use it, nor does bfsitl's autopilot in the gusts."""
    names = ["rc-loss-hover-drop", "rc-loss-hover-autoland", "rc-loss-forward-autoland", "gusts"]
    run, data = compare(
        tmp_path,
        firmware_build_cache,
        names,
        "--b-cli",
        "set ap_hover_throttle = 1275",
        "--seeds",
        "2",
    )
    assert run.returncode == 1, run.stdout + run.stderr[-3000:]
    changes = {s["name"]: s["change"] for s in data["scenarios"]}
    assert changes["rc-loss-hover-drop"] == changes["gusts"] == "same", run.stdout
    for name in ("rc-loss-hover-autoland", "rc-loss-forward-autoland"):
        # B falls where A landed: a new crash is worse, whatever else changed.
        assert changes[name] == "worse", run.stdout
        scenario = next(s for s in data["scenarios"] if s["name"] == name)
        touchdown = next(f for f in scenario["figures"] if f["name"] == "touchdown_m_s")
        assert min(touchdown["b"]) > max(touchdown["a"]) + 1.0, touchdown
    assert "2 same" in run.stdout and "--accept NAME" in run.stderr
    # One build on both sides: each progress line says which side and seed it is.
    ran = [line for line in run.stdout.splitlines() if line.startswith("  ran ")]
    assert len(ran) == 16 and all("(side A, seed " in r or "(side B, seed " in r for r in ran)
    # JUnit: the two that changed fail; the report overlays both sides' runs.
    xml = JUnitXml.fromfile(str(tmp_path / "cmp.xml"))
    failed = {
        case.name
        for suite in xml
        for case in suite
        if any(isinstance(r, Failure) for r in case.result)
    }
    assert failed == {"rc-loss-hover-autoland", "rc-loss-forward-autoland"}
    page = (tmp_path / "report" / "index.html").read_text()
    assert page.count("<img") == 4 and "set ap_hover_throttle = 1275" in page
    # The overlays are in the page: copied anywhere, it shows every plot.
    assert page.count('<img src="data:image/png;base64,') == 4
    # Accepted, the same comparison passes.
    accepted, _ = compare(
        tmp_path,
        firmware_build_cache,
        ["rc-loss-hover-autoland"],
        "--b-cli",
        "set ap_hover_throttle = 1275",
        "--seeds",
        "1",
        "--accept",
        "rc-loss-hover-autoland",
    )
    assert accepted.returncode == 0, accepted.stdout + accepted.stderr[-2000:]
    assert "(accepted)" in accepted.stdout


@pytest.mark.timeout(600)
def test_each_side_flies_its_own_rc_link_rate(
    lockstep_gps_46_firmware, firmware_build_cache: FirmwareCache, tmp_path: Path
) -> None:
    """Side B's link at 50 Hz (a slow CRSF) against the scenario's own 250 Hz: the FC of each
    side measures its own receiver (its log's header), and both still lose it on silence."""
    run, data = compare(
        tmp_path, firmware_build_cache, ["rc-loss-hover-drop"], "--b-rc-rate", "50", "--seeds", "1"
    )
    assert run.returncode in (0, 1), run.stdout + run.stderr[-3000:]
    assert "B: 4.6.0-gps-lockstep, RC link 50 Hz" in run.stderr
    assert "rc_rate_hz" not in data["sides"][0] and data["sides"][1]["rc_rate_hz"] == 50.0
    smoothed = {}
    for side in ("A", "B"):
        (summary,) = (tmp_path / "cmp" / side).glob("rc-loss-hover-drop/seed-*/result.json")
        result = json.loads(summary.read_text())
        assert result["verdict"] == "passed", result["reason"]
        assert any(e["text"].startswith("RC lost (silence)") for e in result["events"])
        (log, *_) = decode_blackbox(Path(result["artifacts"]["blackbox"]))
        smoothed[side] = log.headers["rc_smoothing_rx_smoothed"]
    assert smoothed == {"A": "250", "B": "50"}
