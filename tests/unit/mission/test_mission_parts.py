"""Climb-rate estimate, flight log, plot, and the fly command's small parts."""

from __future__ import annotations

import io
import math

import pytest

from bfsitl.errors import BfsitlError
from bfsitl.mission.climb_rate import ClimbRateEstimator
from bfsitl.mission.flight_row import COLUMNS, FlightRow
from bfsitl.records.csv_log import CsvFlightLog, read_flight_log


def row(time_s: float, phase: str = "hold", alt_m: float = 2.0) -> FlightRow:
    return FlightRow(
        time_s,
        phase,
        2.0,
        alt_m,
        alt_m - 0.01,
        0.0,
        0.0,
        0.1,
        0.5,
        -0.5,
        90.0,
        0.7,
        0.45,
        -0.45,
        90.2,
        1500,
        1500,
        1543,
        1500,
        1800,
        1800,
        0.54,
        0.54,
        0.55,
        0.53,
        True,
        time_s,
    )


# -- climb rate -------------------------------------------------------------------------------


def test_climb_rate_is_the_slope_of_a_ramp_whatever_the_sample_spacing():
    estimator = ClimbRateEstimator(window_s=0.25)
    t = 0.0
    for step in [0.02, 0.013, 0.031, 0.02, 0.009, 0.04] * 5:
        t += step
        rate = estimator.update(t, 0.7 * t + 1.0)
    assert rate == pytest.approx(0.7, abs=1e-9)


def test_climb_rate_averages_out_quantisation_steps():
    estimator = ClimbRateEstimator(window_s=0.25)
    rates = []
    for i in range(200):
        t = i * 0.02
        rates.append(estimator.update(t, math.floor(0.5 * t / 0.08) * 0.08))  # 8 cm steps
    assert sum(rates[50:]) / len(rates[50:]) == pytest.approx(0.5, abs=0.05)


def test_climb_rate_ignores_repeated_times_and_starts_at_zero():
    estimator = ClimbRateEstimator()
    assert estimator.update(1.0, 5.0) == 0.0
    assert estimator.update(1.0, 9.0) == 0.0  # same time: no information
    assert estimator.update(1.1, 5.1) == pytest.approx(1.0)
    estimator.reset()
    assert estimator.rate_m_s == 0.0
    with pytest.raises(ValueError):
        ClimbRateEstimator(window_s=0)


# -- flight log -------------------------------------------------------------------------------


def test_log_rows_are_on_disk_as_soon_as_written(tmp_path):
    path = tmp_path / "sub" / "f.csv"
    log = CsvFlightLog(path)
    log.write(row(1.0))
    log.write(row(1.02, alt_m=2.01))
    # Not closed yet: a crash now must not lose them.
    rows = read_flight_log(path)
    assert [r["time_s"] for r in rows] == ["1.0000", "1.0200"]
    assert rows[1]["sim_alt_m"] == "2.0100" and rows[1]["armed"] == "1"
    log.close()
    with pytest.raises(BfsitlError, match="closed"):
        log.write(row(2.0))


def test_log_columns_have_units_and_the_issue_fields():
    for name in (
        "time_s",
        "target_alt_m",
        "sim_alt_m",
        "fc_alt_m",
        "roll_deg",
        "pitch_deg",
        "yaw_deg",
        "rc_throttle_us",
        "motor1",
        "motor4",
    ):
        assert name in COLUMNS


def test_unwritable_log_and_foreign_csv_are_clear_errors(tmp_path):
    (tmp_path / "file").write_text("x")
    with pytest.raises(BfsitlError, match="cannot write the flight log"):
        CsvFlightLog(tmp_path / "file" / "f.csv")
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    with pytest.raises(BfsitlError, match="not a bfsitl flight log"):
        read_flight_log(other)


# -- plot -------------------------------------------------------------------------------------


def test_plot_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib")
    from bfsitl.records.plot import write_flight_plot

    rows = [
        row(t * 0.02, "takeoff" if t < 50 else "hold", alt_m=min(2.0, t * 0.04)) for t in range(150)
    ]
    out = write_flight_plot(rows, tmp_path / "f.png", title="test")
    assert out.read_bytes()[:4] == b"\x89PNG"
    with pytest.raises(BfsitlError, match="nothing to plot"):
        write_flight_plot([], tmp_path / "g.png")


# -- the fly command's parts --------------------------------------------------------------------


def test_gains_parse_and_bad_ones_say_how():
    from bfsitl.cli.fly_command import parse_gains

    assert parse_gains(["kp=120", " ki = 0.5"]) == {"kp": 120.0, "ki": 0.5}
    with pytest.raises(BfsitlError, match="NAME=VALUE"):
        parse_gains(["kp"])
    with pytest.raises(BfsitlError, match="not a number"):
        parse_gains(["kp=fast"])


def test_live_progress_redraws_one_line_and_prints_events_on_their_own():
    from bfsitl.cli.fly_command import LiveProgress

    class Sample:
        arming_blockers = ()

    stream = io.StringIO()
    progress = LiveProgress(stream, live=True)
    progress.row(row(3.0, "takeoff", 1.2), Sample())
    progress.event("reached 2.00 m")
    text = stream.getvalue()
    assert "takeoff" in text and "alt  1.19/2.00 m" in text and "ARMED" in text
    assert text.endswith("\r\x1b[Kbfsitl: reached 2.00 m\n")
    quiet = io.StringIO()
    LiveProgress(quiet, live=False).row(row(3.0), Sample())
    assert quiet.getvalue() == ""


def test_summary_text_names_outcome_hold_and_link():
    from bfsitl.cli.fly_command import render_summary

    text = render_summary(
        {
            "outcome": "landed",
            "reason": "landed and disarmed",
            "controller": "cascade",
            "blockers": [],
            "armed_after_s": 5.2,
            "step_response": {"rise_time_s": 1.5, "overshoot_pct": 2.0},
            "hold": {"rms_error_m": 0.012, "max_abs_error_m": 0.03, "mean_error_m": -0.004},
            "rc_link": {"packets": 2000, "period_mean_ms": 10.0, "period_max_ms": 12.0},
            "physics": {"answered_ratio": 0.97, "speed": 1.0},
        }
    )
    assert "landed" in text and "RMS 1.2 cm" in text and "97.0 %" in text
    assert "rise_time_s 1.500" in text
    assert "findings" not in text  # not watched: nothing said
    watched = render_summary(
        {
            "outcome": "landed",
            "reason": "landed",
            "controller": "fused",
            "analysers": {"watched": ["crash", "hard_landing"], "skipped": {}},
            "findings": [
                {
                    "analyser": "hard_landing",
                    "severity": "warning",
                    "time_s": 12.5,
                    "summary": "touched down at 1.9 m/s",
                }
            ],
        }
    )
    assert "findings       warning  hard_landing: touched down at 1.9 m/s (t=12.50 s)" in watched
    clean = render_summary(
        {
            "outcome": "landed",
            "reason": "landed",
            "controller": "fused",
            "analysers": {"watched": ["crash"], "skipped": {}},
            "findings": [],
        }
    )
    assert "findings       none (1 analysers watched)" in clean


def test_fly_with_gazebo_missing_says_how_to_install_before_starting_anything(
    tmp_path, monkeypatch, capsys
):
    from bfsitl.cli.main import main

    monkeypatch.setenv("PATH", str(tmp_path))  # no gz here
    monkeypatch.delenv("GZ_SIM_SYSTEM_PLUGIN_PATH", raising=False)
    assert main(["fly", "--physics", "gazebo", "--workdir", str(tmp_path / "run")]) == 1
    err = capsys.readouterr().err
    assert "gz" in err and "Gazebo Harmonic" in err
    assert not (tmp_path / "run").exists()  # nothing was started


def test_fly_lists_gains_without_starting_a_sitl(capsys):
    from bfsitl.cli.main import main

    assert main(["fly", "--controller", "tutorial-pid", "--list-gains"]) == 0
    out = capsys.readouterr().out
    assert "kp = " in out and "hover_base_us = " in out
