"""``bfsitl log replay``'s command line: bad input is one clear line and exit 2 before any SITL
starts; a replay's summary and exit code follow its targets.  The flight itself is faked
here (tests/integration/test_log_replay_sitl.py flies it)."""

from __future__ import annotations

import importlib
import json
from pathlib import Path

import numpy as np
import pytest

from bfsitl.cli.main import main
from bfsitl.replay.compare import compare_logs
from bfsitl.replay.flight import ReplayedFlight
from bfsitl.replay.header_settings import header_settings
from bfsitl.replay.replay_log import Replay
from bfsitl.replay.sticks import stick_stream
from tests.support.synthetic_log import lagged_log, pilot_sticks, synthetic_log


def test_a_missing_vehicle_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as stopped:
        main(["log", "replay", "x.bbl"])
    assert stopped.value.code == 2
    assert "--vehicle" in capsys.readouterr().err


def test_an_unknown_vehicle_names_the_choices(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["log", "replay", "x.bbl", "--vehicle", "no-such-quad"])
    assert "5inch-freestyle" in capsys.readouterr().err


def test_a_file_that_is_no_log_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = tmp_path / "notes.bbl"
    text.write_text("not a blackbox log\n")
    code = main(
        ["log", "replay", str(text), "--vehicle", "5inch-freestyle", "--out", str(tmp_path)]
    )
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("bfsitl: error:") == 1 and "Traceback" not in err


def test_an_out_that_cannot_be_made_is_said_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    code = main(
        ["log", "replay", "x.bbl", "--vehicle", "5inch-freestyle", "--out", str(blocker / "sub")]
    )
    assert code == 2
    assert "cannot make the folder --out" in capsys.readouterr().err


def test_a_log_that_cannot_be_replayed_leaves_no_folder_behind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = tmp_path / "notes.txt"
    text.write_text("not a blackbox log\n")
    out = tmp_path / "replay"
    assert (
        main(["log", "replay", str(text), "--vehicle", "5inch-freestyle", "--out", str(out)]) == 2
    )
    assert not out.exists()


@pytest.mark.parametrize(("tau_s", "code"), [(0.02, 0), (0.045, 1)])
def test_the_exit_code_follows_the_targets(
    tau_s: float,
    code: int,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    command = pilot_sticks(8)
    real, replayed = lagged_log(command, tau_s=0.02), lagged_log(command, tau_s=tau_s)
    given: dict[str, object] = {}

    def fake_replay(log: object, **options: object) -> Replay:
        given.update(options)
        flight = ReplayedFlight(tmp_path / "replay-LOG00001.BF", "4.6.0", 100, 20.0, 0.5)
        return Replay(
            real,
            "5inch-freestyle",
            header_settings(real.headers),
            stick_stream(real),
            flight,
            compare_logs(real, replayed),
            replayed,
        )

    replay_log_module = importlib.import_module("bfsitl.replay.replay_log")
    monkeypatch.setattr(replay_log_module, "replay_log", fake_replay)
    # The package exports fit_log the function, which hides the module of the same name.
    fit_log_module = importlib.import_module("bfsitl.fit.fit_log")
    monkeypatch.setattr(fit_log_module, "pick_log", lambda path, index: real)
    out = tmp_path / "out"
    result = main(
        [
            "log", "replay", "real.bbl", "--vehicle", "5inch-freestyle", "--out", str(out),
            "--cli", "set p_roll = 60",
        ]
    )  # fmt: skip
    printed = capsys.readouterr().out
    assert result == code
    assert given["extra_cli"] == ("set p_roll = 60",)
    report = json.loads((out / "replay-report.json").read_text())
    assert report["targets"]["met"] is (code == 0)
    assert report["comparison"]["axes"]["roll"]["setpoint_correlation"] > 0.999
    assert (out / "replay-report.png").stat().st_size > 10_000
    assert ("MISSED" in printed) is (code == 1)
    assert "roll" in printed and "setpoint r" in printed


def test_synthetic_logs_are_well_formed() -> None:
    log = synthetic_log(np.arange(10) / 1000.0, np.zeros((10, 4)))
    assert len(log.frames) == 10 and log.frames[0].rc_command == (0, 0, 0, 0)


def test_settings_a_build_lacks_are_listed_not_sent(tmp_path: Path) -> None:
    from bfsitl.replay.header_settings import CarriedSetting, HeaderSettings, NotCarried
    from bfsitl.replay.replay_log import known_to, line_name

    assert line_name("set p_roll = 45") == "p_roll"
    assert line_name("feature -AIRMODE") == "AIRMODE"
    binary = tmp_path / "sitl"
    binary.write_bytes(b"\x00p_roll\x00i_roll\x00AIRMODE\x00")
    settings = HeaderSettings(
        firmware="Betaflight 4.2.9",
        carried=(
            CarriedSetting("rollPID", "47,85,38", ("set p_roll = 47", "set i_roll = 85")),
            CarriedSetting("abs_control_gain", "0", ("set abs_control_gain = 0",)),
            CarriedSetting("features", "1", ("feature AIRMODE", "feature -MOTOR_STOP")),
        ),
        not_carried=(NotCarried("magPID", "40", "no 4.6.0 setting"),),
    )
    kept = known_to(settings, binary)
    assert kept.cli_lines == ("set p_roll = 47", "set i_roll = 85", "feature AIRMODE")
    assert [(n.header, n.why) for n in kept.not_carried] == [
        ("magPID", "no 4.6.0 setting"),
        ("abs_control_gain", "this build has no abs_control_gain"),
        ("features", "this build has no MOTOR_STOP"),
    ]


def test_a_b_replays_the_log_twice_and_compares_b_with_a(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    command = pilot_sticks(11)
    real, slower = lagged_log(command, tau_s=0.02), lagged_log(command, tau_s=0.045)
    calls: list[dict[str, object]] = []

    def fake_replay(log: object, **options: object) -> Replay:
        calls.append(options)
        # A's replay flew as the real quad, B's as the slower one: B against A is slower.
        replayed = real if len(calls) == 1 else slower
        out = Path(str(options["out_dir"]))
        flight = ReplayedFlight(out / "replay-LOG00001.BF", "4.6.0", 100, 20.0, 0.5)
        return Replay(
            real, "5inch-freestyle", header_settings(real.headers), stick_stream(real), flight,
            compare_logs(real, replayed), replayed,
        )  # fmt: skip

    replay_log_module = importlib.import_module("bfsitl.replay.replay_log")
    monkeypatch.setattr(replay_log_module, "replay_log", fake_replay)
    fit_log_module = importlib.import_module("bfsitl.fit.fit_log")
    monkeypatch.setattr(fit_log_module, "pick_log", lambda path, index: real)
    out = tmp_path / "out"
    code = main(
        [
            "log", "replay", "real.bbl", "--vehicle", "5inch-freestyle", "--out", str(out),
            "--cli", "set p_roll = 60", "--b-firmware", "master-lockstep",
            "--b-cli", "set f_roll = 0",
        ]
    )  # fmt: skip
    printed = capsys.readouterr().out
    assert code == 0
    assert calls[0]["extra_cli"] == ("set p_roll = 60",)
    assert calls[1]["extra_cli"] == ("set p_roll = 60", "set f_roll = 0")
    assert calls[1]["firmware"] == "master-lockstep" and calls[1]["out_dir"] == out / "b"
    report = json.loads((out / "b-against-a.json").read_text())
    assert report["b"]["cli"] == ["set p_roll = 60", "set f_roll = 0"]
    assert report["b_against_a"]["axes"]["roll"]["rise_time_ratio"] > 1.5
    assert (out / "b-against-a.png").stat().st_size > 10_000
    assert "against A" in printed and "CHANGED" in printed
