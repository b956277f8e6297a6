"""The FC's blackbox: real logs from both firmwares (tests/data/blackbox, see its README),
decoded with orangebox plus bfsitl's reading of the events; cut logs; finding and collecting."""

from __future__ import annotations

import contextlib
import logging
from pathlib import Path

import pytest
from orangebox import Parser

from bfsitl.blackbox import (
    BlackboxLog,
    collect_blackbox,
    decode_blackbox,
    find_blackbox_files,
    frames_to_rows,
)
from bfsitl.errors import BfsitlError, BlackboxError
from bfsitl.protocol.failsafe_phase import FailsafePhase

DATA = Path(__file__).resolve().parents[2] / "data" / "blackbox"
V46, MASTER = "Betaflight 4.6.0", "Betaflight 2026.12.0-alpha"
#: ``BOXFAILSAFE`` in the firmware's internal ``boxId_e`` ([4.6] src/main/fc/rc_modes.h:31-40):
#: the bit the FAILSAFE switch sets in the slow frame's switch mask.
BOXFAILSAFE_BIT = 1 << 8


def only_log(name: str) -> BlackboxLog:
    logs = decode_blackbox(DATA / name)
    assert len(logs) == 1 and logs[0].index == 1
    return logs[0]


def times(log: BlackboxLog) -> list[float]:
    return [frame.time_s for frame in log.frames]


def seconds_after_start(log: BlackboxLog, time_s: float | None) -> float:
    assert time_s is not None
    return time_s - log.frames[0].time_s


# -- every complete log -----------------------------------------------------------------------

COMPLETE = [  # file, firmware, disarm reason, failsafe phases the log shows
    ("plain-4.6.0.BF", V46, "SWITCH", ["IDLE"]),
    ("plain-master.BFL", MASTER, "SWITCH", ["IDLE"]),
    ("autoland-master.BFL", MASTER, "FAILSAFE", ["IDLE", "LANDING"]),
    ("drop-4.6.0.BF", V46, "FAILSAFE", ["IDLE"]),
    ("drop-master.BFL", MASTER, "FAILSAFE", ["IDLE"]),
    ("switch-landing-master.BFL", MASTER, "SWITCH", ["IDLE", "LANDING", "IDLE"]),
]


@pytest.mark.parametrize(("name", "revision", "reason", "phases"), COMPLETE)
def test_a_complete_log_decodes_with_its_disarm(
    name: str, revision: str, reason: str, phases: list[str]
) -> None:
    log = only_log(name)
    assert log.firmware_revision.startswith(revision) and log.path == DATA / name
    assert not log.truncated and len(log.frames) > 5
    stamps = times(log)
    assert all(a < b for a, b in zip(stamps, stamps[1:], strict=False))  # strictly increasing
    assert [phase.name for _, phase in log.phase_changes()] == phases
    assert log.disarm_reason_name == reason
    # The firmware's disarm: DISARM, then LOG_END, after the last frame.
    assert [event.kind for event in log.events[-2:]] == ["DISARM", "LOG_END"]
    assert log.events[-2].data["reason_name"] == reason
    assert log.events[-1].time_s == log.frames[-1].time_s
    # Raw headers as text, field definitions included.
    assert log.headers["Data version"] == "2" and "Field I name" in log.headers
    assert len(log.frames[-1].motors) == 4 and len(log.frames[-1].gyro_adc) == 3


def test_the_slow_frame_comes_after_the_first_main_frame() -> None:
    """Before it the receiver and phase are unknown (None), not 'lost' or IDLE."""
    log = only_log("plain-master.BFL")
    first, second = log.frames[:2]
    assert first.failsafe_phase is None and first.rx_signal_received is None
    assert second.failsafe_phase == FailsafePhase.IDLE and second.rx_flight_channels_valid


# -- plain flights: arm, 1500 us for 1 s, disarm by the switch --------------------------------


@pytest.mark.parametrize(
    ("name", "duration_s"),
    [
        ("plain-4.6.0.BF", 0.89),  # 8 kHz loop: the header is written in 0.1 s
        ("plain-master.BFL", 0.72),  # 1 kHz loop: 0.3 s
    ],
)
def test_a_plain_flight_ends_with_the_switch(name: str, duration_s: float) -> None:
    log = only_log(name)
    assert log.duration_s == pytest.approx(duration_s, abs=0.02)
    assert all(frame.rx_flight_channels_valid for frame in log.frames[1:])
    # ARM and ANGLE switches (box ids 0 and 1) on, then both off just before the disarm.
    assert log.frames[len(log.frames) // 2].mode_switch_mask == 0b11
    switches = [e for e in log.events if e.kind == "FLIGHTMODE"]
    assert switches[-1].data == {"mode_switch_mask": 0, "previous_mode_switch_mask": 0b11}
    assert log.events[-2].data["reason"] == 4
    # Throttle 1500 us: rcCommand[3] is 1473 after the deadband and scaling, the motors up.
    assert log.frames[len(log.frames) // 2].rc_command[3] == 1473
    assert min(log.frames[len(log.frames) // 2].motors) > 1400


# -- failsafe -----------------------------------------------------------------------------------


def test_rc_silence_with_auto_land_shows_the_landing_and_a_failsafe_disarm() -> None:
    """master, AUTO-LAND, failsafe_delay 0.5 s, failsafe_landing_time 1 s; RC stopped."""
    log = only_log("autoland-master.BFL")
    lost = next(frame for frame in log.frames if frame.rx_flight_channels_valid is False)
    assert lost.rx_signal_received is False  # silence: the signal itself is gone
    assert lost.failsafe_phase == FailsafePhase.IDLE  # stage 1 keeps the phase IDLE
    (_, idle), (landing_s, landing) = log.phase_changes()
    assert (idle, landing) == (FailsafePhase.IDLE, FailsafePhase.LANDING)
    # Stage 2 comes failsafe_delay after the last valid data, which was 150 ms before the
    # flight channels were declared invalid: 0.35 s after the first invalid frame.
    assert landing_s - lost.time_s == pytest.approx(0.35, abs=0.05)
    disarm = log.events[-2]
    assert disarm.kind == "DISARM" and disarm.data["reason_name"] == "FAILSAFE"
    assert disarm.time_s is not None
    assert disarm.time_s - landing_s == pytest.approx(1.0, abs=0.05)  # failsafe_landing_time
    # Never RX_LOSS_DETECTED or LANDED: both pass inside one failsafe update, and LANDED
    # disarms, closing the log before a slow frame could show it.
    assert {frame.failsafe_phase for frame in log.frames} == {None, 0, 2}


@pytest.mark.parametrize(
    ("name", "signal_kept"),
    [
        ("drop-4.6.0.BF", True),  # the FAILSAFE switch: frames keep coming
        ("drop-master.BFL", False),  # silence: the signal goes
    ],
)
def test_a_drop_shows_the_link_lost_and_a_failsafe_disarm(name: str, signal_kept: bool) -> None:
    log = only_log(name)
    assert 3.0 < log.duration_s < 6.0  # ~1 s of ground and 4 s of hover
    lost = next(frame for frame in log.frames if frame.rx_flight_channels_valid is False)
    assert lost.rx_signal_received is signal_kept
    assert 3.5 < seconds_after_start(log, lost.time_s) < 4.5  # the fault came at 4 s
    assert log.disarm_reason == 1 and log.disarm_reason_name == "FAILSAFE"
    hover = log.frames[len(log.frames) // 2]
    assert len(hover.debug) == 8  # debug_mode = FAILSAFE
    assert min(hover.motors) > log.frames[0].motors[0]


def test_the_failsafe_switch_shows_in_the_switch_mask_and_its_event() -> None:
    log = only_log("drop-4.6.0.BF")
    event = next(e for e in log.events if e.kind == "FLIGHTMODE")
    assert event.data["mode_switch_mask"] & BOXFAILSAFE_BIT
    assert not event.data["previous_mode_switch_mask"] & BOXFAILSAFE_BIT
    assert any(frame.mode_switch_mask & BOXFAILSAFE_BIT for frame in log.frames)


def test_the_phases_and_a_switch_disarm() -> None:
    log = only_log("switch-landing-master.BFL")
    phases = log.phase_changes()
    assert 0.5 < phases[2][0] - phases[1][0] < 0.8  # the switch was on for 0.6 s
    # debug_mode = FAILSAFE puts the phase in debug[3] as well: the two agree.
    during = next(f for f in log.frames if f.failsafe_phase == FailsafePhase.LANDING)
    assert during.debug[3] == FailsafePhase.LANDING


# -- logs cut short -------------------------------------------------------------------------------


def test_a_file_cut_in_the_middle_keeps_the_frames_before_the_cut() -> None:
    whole, cut = only_log("plain-4.6.0.BF"), only_log("plain-4.6.0-cut.BF")
    assert cut.truncated and not whole.truncated
    assert cut.disarm_reason is None and cut.disarm_reason_name is None and cut.events == ()
    assert 100 < len(cut.frames) < len(whole.frames)
    assert cut.frames == whole.frames[: len(cut.frames)]  # the same frames, none invented


def test_a_killed_sitl_leaves_a_truncated_log() -> None:
    log = only_log("killed-master.BFL")
    assert log.truncated and log.disarm_reason is None and log.events == ()
    assert len(log.frames) > 10 and log.frames[-1].motors[0] > 1400  # still flying
    stamps = times(log)
    assert stamps == sorted(stamps)


def test_a_log_cut_anywhere_decodes_or_says_it_is_no_log(tmp_path: Path) -> None:
    data = (DATA / "autoland-master.BFL").read_bytes()
    whole = only_log("autoland-master.BFL")
    cut = tmp_path / "LOG00001.BFL"
    for length in range(0, len(data), 293):
        cut.write_bytes(data[:length])
        if length < len(b"H Product:"):
            with pytest.raises(BlackboxError):
                decode_blackbox(cut)
            continue
        log = decode_blackbox(cut)[0]
        assert log.truncated
        assert log.frames == whole.frames[: len(log.frames)]


# -- files with several logs, and what is no log --------------------------------------------------


def test_two_flights_in_one_file_are_two_logs(tmp_path: Path) -> None:
    both = tmp_path / "LOG00001.BFL"
    both.write_bytes(
        (DATA / "drop-master.BFL").read_bytes() + (DATA / "plain-master.BFL").read_bytes()
    )
    logs = decode_blackbox(both)
    assert [log.index for log in logs] == [1, 2]
    assert [log.disarm_reason_name for log in logs] == ["FAILSAFE", "SWITCH"]
    assert logs[1].frames == only_log("plain-master.BFL").frames
    assert not any(log.truncated for log in logs)


@pytest.mark.parametrize("content", [b"", b"\x00\xff" * 100, b"I\x00\x01 not a header\n"])
def test_garbage_says_it_is_no_blackbox_log(tmp_path: Path, content: bytes) -> None:
    garbage = tmp_path / "LOG00001.BFL"
    garbage.write_bytes(content)
    with pytest.raises(BlackboxError, match="is not a blackbox log") as error:
        decode_blackbox(garbage)
    assert isinstance(error.value, BfsitlError)


def test_a_missing_file_says_so(tmp_path: Path) -> None:
    with pytest.raises(BlackboxError, match="cannot read the blackbox file"):
        decode_blackbox(tmp_path / "nope.BFL")


def test_orangebox_alone_loses_the_events(caplog: pytest.LogCaptureFixture) -> None:
    """Why bfsitl reads the events itself: if this fails, a new orangebox keeps them."""
    caplog.set_level(logging.ERROR, logger="orangebox")
    parser = Parser.load(str(DATA / "plain-master.BFL"))
    assert sum(1 for _ in parser.frames()) == len(only_log("plain-master.BFL").frames)
    assert parser.events == []


def test_frames_to_rows_flattens_each_frame() -> None:
    log = only_log("plain-master.BFL")
    rows = frames_to_rows(log)
    assert len(rows) == len(log.frames) and rows[0]["time_from_start_s"] == 0.0
    row = rows[len(rows) // 2]
    frame = log.frames[len(rows) // 2]
    assert row["motor3"] == frame.motors[3] and row["gyro_adc2"] == frame.gyro_adc[2]
    assert row["rc_command3"] == frame.rc_command[3] and row["failsafe_phase"] == 0


# -- finding and collecting -------------------------------------------------------------------


def test_find_and_collect_keep_every_log(tmp_path: Path) -> None:
    run = tmp_path / "sitl"
    run.mkdir()
    for name in (
        "LOG00001.BF",
        "LOG00002.BFL",
        "eeprom.bin",
        "LOG1.BFL",
        "sitl.log",
        "LOG00003.BFL.tmp",
    ):
        (run / name).write_bytes(name.encode())
    (run / "LOG00009.BFL").mkdir()  # a directory is no log
    assert [p.name for p in find_blackbox_files(run)] == ["LOG00001.BF", "LOG00002.BFL"]
    assert find_blackbox_files(tmp_path / "none") == []
    first = collect_blackbox(run, tmp_path / "out")
    again = collect_blackbox(run, tmp_path / "out")  # a 4.6.0 SITL reuses LOG00001.BF
    assert [p.name for p in first] == ["LOG00001.BF", "LOG00002.BFL"]
    assert [p.name for p in again] == ["LOG00001-2.BF", "LOG00002-2.BFL"]
    assert [p.read_bytes() for p in again] == [b"LOG00001.BF", b"LOG00002.BFL"]
    assert (run / "LOG00001.BF").exists()  # copied, not moved
    assert collect_blackbox(tmp_path / "empty", tmp_path / "out2") == []
    assert not (tmp_path / "out2").exists()  # nothing to copy, nothing created


def test_collect_names_copies_with_a_prefix(tmp_path: Path) -> None:
    run = tmp_path / "sitl"
    run.mkdir()
    (run / "LOG00001.BFL").write_bytes((DATA / "plain-master.BFL").read_bytes())
    (copy,) = collect_blackbox(run, tmp_path / "out", prefix="hover-")
    assert copy == tmp_path / "out" / "hover-LOG00001.BFL"
    assert decode_blackbox(copy)[0].disarm_reason_name == "SWITCH"


def test_a_value_orangebox_wrapped_to_32_bits_comes_back_negative() -> None:
    from bfsitl.blackbox.decode import _FrameLayout

    # 3.x logs throttle as a difference from minthrottle, which orangebox decodes unsigned:
    # a stick at 1000 reads 2**32 + 1000 (measured on the CS110 logs).
    row = {"time": 75_000_000, "rcCommand[0]": 12, "rcCommand[1]": 2**32 - 5}
    row |= {"rcCommand[2]": 0, "rcCommand[3]": 2**32 + 1000, "failsafePhase": ""}
    frame = _FrameLayout.of(list(row)).frame(list(row.values()))
    assert frame.rc_command == (12, -5, 0, 1000)
    assert frame.time_s == 75.0
    assert frame.failsafe_phase is None  # a slow field before the first slow frame
    assert frame.motors == () and frame.baro_alt_cm is None  # not in this log


def test_a_frame_cut_short_or_with_a_value_that_is_no_number_ends_its_group() -> None:
    from bfsitl.blackbox.decode import _FrameLayout

    names = ["time", "motor[0]", "motor[1]", "motor[2]", "motor[3]", "rxSignalReceived"]
    layout = _FrameLayout.of(names)
    assert layout.frame([1_000_000, 1100, "", 1300, 1400, 1]).motors == (1100,)
    cut = layout.frame([2_000_000, 1100, 1200])
    assert cut.motors == (1100, 1200) and cut.rx_signal_received is None
    assert layout.frame([0, 1, 2, 3, 4, 0]).rx_signal_received is False
    assert layout.frame([0, 1.0, 2.0, 3, 4, True]).motors == (1, 2, 3, 4)


@pytest.mark.parametrize("name", ["plain-4.6.0.BF", "drop-master.BFL"])
def test_the_faster_frame_loop_gives_orangebox_s_own_frames(
    name: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The frame loop bfsitl puts in place of 0.4.0's (a list, not a tuple grown field by
    field) is the one in use, and it decodes the same values as orangebox's own."""
    from orangebox import Parser
    from orangebox.reader import Reader

    from bfsitl.blackbox.events import EventKeepingParser

    calls: list[int] = []
    faster = EventKeepingParser._parse_frame

    def counted(self, fdefs, reader):  # type: ignore[no-untyped-def]
        calls.append(1)
        return faster(self, fdefs, reader)

    def frames(parser: Parser) -> list[tuple[object, ...]]:
        data: list[tuple[object, ...]] = []
        with contextlib.suppress(TypeError, IndexError):  # 0.4.0 ends on the missing data
            data.extend(frame.data for frame in parser.frames())
        return data

    monkeypatch.setattr(EventKeepingParser, "_parse_frame", counted)
    ours = frames(EventKeepingParser(Reader(str(DATA / name), log_index=1)))
    theirs = frames(Parser(Reader(str(DATA / name), log_index=1)))
    assert ours == theirs and len(ours) > 100
    assert len(calls) >= len(ours)  # every main frame (and the slow ones) went through it
