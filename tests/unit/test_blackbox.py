"""The FC's blackbox: real logs from both firmwares (tests/data/blackbox, see its README),
decoded with orangebox plus bfsitl's reading of the disarm event; finding and collecting."""

from __future__ import annotations

from pathlib import Path

import pytest

from bfsitl.blackbox import (
    FailsafePhase,
    collect_blackbox,
    decode_blackbox,
    find_blackbox_files,
)
from bfsitl.errors import BlackboxError

DATA = Path(__file__).resolve().parents[1] / "data" / "blackbox"


def only_log(name: str):  # type: ignore[no-untyped-def]
    logs = decode_blackbox(DATA / name)
    assert len(logs) == 1
    return logs[0]


@pytest.mark.parametrize(("name", "revision", "signal_kept"), [
    ("drop-4.6.0.BF", "Betaflight 4.6.0", True),         # the switch: frames keep coming
    ("drop-master.BFL", "Betaflight 2026.12.0-alpha", False),  # silence: the signal goes
])
def test_a_drop_shows_the_link_lost_and_a_failsafe_disarm(name: str, revision: str,
                                                           signal_kept: bool) -> None:
    log = only_log(name)
    assert log.firmware_revision.startswith(revision) and not log.truncated
    times = [frame.time_s for frame in log.frames]
    assert times == sorted(times) and len(set(times)) == len(times)
    assert 3.0 < log.duration_s < 6.0  # armed at ~1 s of ground and 4 s of hover
    lost = next(frame for frame in log.frames if frame.rx_flight_channels_valid is False)
    assert lost.rx_signal_received is signal_kept
    assert 3.5 < lost.time_s - log.frames[0].time_s < 4.5  # the fault came at 4 s
    assert log.disarm_reason == 1 and log.disarm_reason_name == "FAILSAFE"
    # The flight is in it: four motors, gyro on three axes, the throttle up while hovering.
    hover = log.frames[len(log.frames) // 2]
    assert len(hover.motors) == 4 and len(hover.gyro_adc) == 3 and len(hover.debug) == 8
    assert min(hover.motors) > log.frames[0].motors[0]


def test_the_phases_and_a_switch_disarm() -> None:
    log = only_log("switch-landing-master.BFL")
    phases = log.phase_changes()
    assert [phase for _, phase in phases] == [FailsafePhase.IDLE, FailsafePhase.LANDING,
                                              FailsafePhase.IDLE]
    landing_s = phases[2][0] - phases[1][0]
    assert 0.5 < landing_s < 0.8  # the switch was on for 0.6 s
    assert log.disarm_reason_name == "SWITCH"
    # debug_mode = FAILSAFE puts the phase in debug[3] as well: the two agree.
    during = next(f for f in log.frames if f.failsafe_phase == FailsafePhase.LANDING)
    assert during.debug[3] == FailsafePhase.LANDING


def test_a_log_cut_short_keeps_its_frames(tmp_path: Path) -> None:
    whole = (DATA / "drop-master.BFL").read_bytes()
    cut = tmp_path / "LOG00001.BFL"
    cut.write_bytes(whole[: len(whole) * 2 // 3])
    log = decode_blackbox(cut)[0]
    assert log.truncated and log.disarm_reason is None
    assert 0 < len(log.frames) < len(only_log("drop-master.BFL").frames)


def test_two_flights_in_one_file_are_two_logs(tmp_path: Path) -> None:
    both = tmp_path / "LOG00001.BFL"
    both.write_bytes((DATA / "drop-master.BFL").read_bytes()
                     + (DATA / "switch-landing-master.BFL").read_bytes())
    logs = decode_blackbox(both)
    assert [log.index for log in logs] == [1, 2]
    assert [log.disarm_reason_name for log in logs] == ["FAILSAFE", "SWITCH"]


def test_garbage_and_missing_files_say_what_they_are(tmp_path: Path) -> None:
    garbage = tmp_path / "LOG00001.BFL"
    garbage.write_bytes(b"\x00\xff" * 100)
    with pytest.raises(BlackboxError, match="not a blackbox log"):
        decode_blackbox(garbage)
    with pytest.raises(BlackboxError, match="cannot read"):
        decode_blackbox(tmp_path / "nope.BFL")


def test_find_and_collect_keep_every_log(tmp_path: Path) -> None:
    run = tmp_path / "sitl"
    run.mkdir()
    for name in ("LOG00001.BF", "LOG00002.BFL", "eeprom.bin", "LOG1.BFL", "sitl.log"):
        (run / name).write_bytes(b"x")
    assert [p.name for p in find_blackbox_files(run)] == ["LOG00001.BF", "LOG00002.BFL"]
    assert find_blackbox_files(tmp_path / "none") == []
    first = collect_blackbox(run, tmp_path / "out")
    again = collect_blackbox(run, tmp_path / "out")  # a 4.6.0 SITL reuses LOG00001.BF
    assert [p.name for p in first] == ["LOG00001.BF", "LOG00002.BFL"]
    assert [p.name for p in again] == ["LOG00001-2.BF", "LOG00002-2.BFL"]
    assert (run / "LOG00001.BF").exists()  # copied, not moved
    assert collect_blackbox(tmp_path / "empty", tmp_path / "out2") == []
