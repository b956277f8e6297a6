"""The analysers on real blackbox logs (tests/data/blackbox, written by the firmware in SITL)
and on bfsitl's own flight logs, through ``bfsitl log check``."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import pytest
from support.flight_rows import make_row

from bfsitl.analysis import Severity, analyse, track_from_blackbox, track_from_rows
from bfsitl.blackbox import decode_blackbox
from bfsitl.cli.main import main
from bfsitl.records.csv_log import CsvFlightLog, read_flight_rows

DATA = Path(__file__).resolve().parents[2] / "data" / "blackbox"


def findings_of(name: str) -> dict[str, object]:
    (log,) = decode_blackbox(DATA / name)
    return {f.analyser: f for f in analyse(track_from_blackbox(log)).findings}


def test_a_log_is_read_in_physical_units() -> None:
    (log,) = decode_blackbox(DATA / "switch-landing-master.BFL")
    track = track_from_blackbox(log)
    assert track.source == "blackbox" and track.disarm_reason == "SWITCH"
    assert track.points[0].time_s == 0.0
    # motorOutput 1055,2000: a hover's ~1540 is about half; level; about 1 g (the SITL's
    # accelerometer truncates its z axis: 0.83 g in a hover).
    hovering = track.points[len(track.points) // 4]
    assert 0.4 < sum(hovering.motors) / 4 < 0.7
    assert hovering.tilt_deg < 1.0 and 0.75 < hovering.accel_g < 1.1
    assert max(p.alt_m for p in track.points) == pytest.approx(1.74, abs=0.2)


def test_the_drops_failsafe_is_read_from_the_receiver_and_the_disarm_reason() -> None:
    # A DROP disarms inside one failsafe pass: its phases never reach the log (see
    # bfsitl.blackbox.decode); the receiver's state and the disarm reason do.
    for name in ("drop-4.6.0.BF", "drop-master.BFL"):
        finding = findings_of(name)["failsafe"]
        assert finding.severity is Severity.INFO  # type: ignore[attr-defined]
        assert "RX lost" in finding.summary and "disarmed by the failsafe" in finding.summary  # type: ignore[attr-defined]
        assert 0.3 < finding.evidence["to_disarmed_by_the_failsafe_s"] < 0.6  # type: ignore[attr-defined]


def test_the_autoland_log_shows_its_landing_phase_in_order() -> None:
    finding = findings_of("autoland-master.BFL")["failsafe"]
    assert [p[0] for p in finding.evidence["phases"]] == [  # type: ignore[attr-defined]
        "IDLE",
        "RX lost",
        "LANDING",
        "disarmed by the failsafe",
    ]


def test_a_landing_at_two_metres_a_second_is_a_hard_landing_in_the_log() -> None:
    finding = findings_of("switch-landing-master.BFL")["hard_landing"]
    assert finding.severity is Severity.WARNING  # type: ignore[attr-defined]
    assert finding.evidence["baro_descent_m_s"] == pytest.approx(2.3, abs=0.3)  # type: ignore[attr-defined]


def test_a_plain_flight_has_no_finding_and_a_cut_log_says_what_it_cannot_judge() -> None:
    for name in ("plain-4.6.0.BF", "plain-master.BFL"):
        assert findings_of(name) == {}
    (log,) = decode_blackbox(DATA / "killed-master.BFL")
    analysis = analyse(track_from_blackbox(log))
    assert analysis.findings == [] and "cut" in analysis.skipped["crash"]


def test_log_check_prints_each_logs_findings_and_exits_by_the_worst(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["log", "check", str(DATA / "plain-4.6.0.BF")]) == 0
    assert "nothing found" in capsys.readouterr().out
    landing = str(DATA / "switch-landing-master.BFL")
    assert main(["log", "check", landing]) == 0  # a warning < failure
    assert main(["log", "check", landing, "--fail-on", "warning"]) == 1
    out = capsys.readouterr().out
    assert "hard_landing" in out and "not watched: altitude_estimate" in out
    assert main(["log", "check", landing, "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    (entry,) = data["logs"]
    assert entry["disarm_reason"] == "SWITCH"
    assert {f["analyser"] for f in entry["findings"]} == {"hard_landing", "failsafe"}


def test_log_check_names_a_file_it_cannot_read_and_goes_on(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    garbage = tmp_path / "LOG00001.BFL"
    garbage.write_bytes(b"\x00garbage" * 10)
    assert main(["log", "check", str(garbage), str(DATA / "plain-master.BFL")]) == 2
    captured = capsys.readouterr()
    assert "is not a blackbox log" in captured.err and "plain-master.BFL" in captured.out
    assert main(["log", "check"]) == 2
    assert main(["log", "check", "--list"]) == 0
    assert "motor_saturation" in capsys.readouterr().out


def test_a_bfsitl_flight_log_is_read_back_and_checked(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "flight.csv"
    with CsvFlightLog(path) as log:
        for index in range(300):
            log.write(
                make_row(
                    index,
                    motor1=1.0 if 100 <= index < 150 else 0.51,
                    sim_alt_m=2.0,
                    fc_alt_m=2.0,
                    target_north_m=math.nan,
                )
            )
    rows = read_flight_rows(path)
    # Every column comes back with its type; an empty cell is NaN again.
    nan_free = {
        name: 0.0
        for name in (
            "target_north_m",
            "target_east_m",
            "target_heading_deg",
            "fc_north_m",
            "fc_east_m",
        )
    }
    assert math.isnan(rows[5].target_north_m)
    assert replace(rows[5], **nan_free) == replace(
        make_row(5, sim_alt_m=2.0, fc_alt_m=2.0, motor1=0.51), **nan_free
    )
    findings = analyse(track_from_rows(rows)).findings
    assert [f.analyser for f in findings] == ["motor_saturation"]
    assert main(["log", "check", str(path), "--fail-on", "warning"]) == 1
    assert "motor 1 at full for 1.00 s" in capsys.readouterr().out
