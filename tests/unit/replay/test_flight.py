"""The replay's stream with a fake session: every frame when it is due on the session's
clock, one datagram each, switches as the log had them, the FC's settings and blackbox
provisioned, and the stream's mode undone however it ends.  The real SITL flies it in
tests/integration/test_log_replay_sitl.py."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from bfsitl.errors import ReplayError, SitlExitedError
from bfsitl.fc.rc_link import RcCommand
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US
from bfsitl.physics.params import IRIS
from bfsitl.protocol.firmware_profile import Generation
from bfsitl.replay.flight import (
    RUN_MARKER,
    ReplayFirmware,
    blackbox_lines,
    fly_replay,
    lead_in_s,
    pid_process_denom,
    replay_firmware,
)
from bfsitl.replay.sticks import stick_stream
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from tests.support.synthetic_log import synthetic_log


class FakeClock:
    def __init__(self, session: FakeSession) -> None:
        self.session = session

    def now_s(self) -> float:
        return self.session.now_s

    def sleep_s(self, seconds: float) -> None:
        self.session.now_s += seconds


class FakeSession:
    made: list[FakeSession] = []

    def __init__(self, config: Any, *, progress: Any = None) -> None:
        self.config = config
        self.now_s = 0.0
        self.sent: list[tuple[float, RcCommand, bool]] = []
        self.bridge = SimpleNamespace(rc_frames_on_set=False)
        self.clock = FakeClock(self)
        self.lockstep = True
        self.firmware = SimpleNamespace(firmware_version="4.6.0", generation=Generation.V4_6)
        self.disarmed = False
        self.die_at_s: float | None = None
        FakeSession.made.append(self)

    def __enter__(self) -> FakeSession:
        return self

    def __exit__(self, *exc: object) -> None:
        pass

    def start(self) -> FakeSession:
        return self

    @property
    def time_s(self) -> float:
        return self.now_s

    def arm(self) -> None:
        self.now_s += 3.0  # boot grace and calibration

    def set_rc(self, command: RcCommand) -> None:
        self.sent.append((self.now_s, command, self.bridge.rc_frames_on_set))

    def check_alive(self) -> None:
        if self.die_at_s is not None and self.now_s >= self.die_at_s:
            raise SitlExitedError("the SITL exited", 1, "")

    def disarm(self) -> bool:
        self.disarmed = True
        workdir = Path(self.config.sitl.workdir)
        workdir.mkdir(parents=True, exist_ok=True)
        (workdir / "LOG00001.BF").write_bytes(b"H Product:Blackbox\n")
        return True


@pytest.fixture(autouse=True)
def _clear() -> None:
    FakeSession.made.clear()


FIRMWARE = ReplayFirmware(Path("sitl"), 8000.0)


def _stream(seconds: float = 2.0, interval_us: int = 20000) -> Any:
    time_s = np.arange(0, seconds, 0.001)
    command = np.zeros((len(time_s), 4))
    command[:, 3] = 1000.0 + 500.0 * (time_s > 0.5)
    command[:, 0] = 100.0 * np.sin(time_s)
    mask = np.where(time_s < 1.0, 0b011, 0b001)  # ANGLE for the first second, then acro
    log = synthetic_log(
        time_s, command, mode_mask=mask, headers={"rc_smoothing_rx_average": str(interval_us)}
    )
    return stick_stream(log)


def test_each_frame_goes_out_when_it_is_due(tmp_path: Path) -> None:
    stream = _stream()
    flight = fly_replay(
        stream,
        firmware=FIRMWARE,
        quad=IRIS,
        cli_lines=("set p_roll = 50",),
        out_dir=tmp_path,
        session_factory=FakeSession,
    )
    session = FakeSession.made[0]
    # A lead-in of the first frame at the receiver's rate (0.8 s: 40 frames of 20 ms), then
    # the log's frames, each when it is due, the first one interval after the lead-in.
    lead = round(lead_in_s(stream) / stream.frame_interval_s)
    assert lead == 40 and len(session.sent) == lead + len(stream)
    times = np.array([t for t, _c, _on in session.sent])
    assert np.diff(times[: lead + 1]) == pytest.approx(stream.frame_interval_s, abs=1e-9)
    logged = times[lead:]
    assert logged - logged[0] == pytest.approx(stream.time_s, abs=1e-9)
    assert all(c == session.sent[lead][1] for _t, c, _on in session.sent[:lead])
    assert all(on for _t, _c, on in session.sent)  # one datagram per frame
    assert session.bridge.rc_frames_on_set is False and session.disarmed
    first, last = session.sent[0][1], session.sent[-1][1]
    assert first.aux_us == (SWITCH_ON_US, SWITCH_ON_US, SWITCH_OFF_US)  # armed, ANGLE
    assert last.aux_us == (SWITCH_ON_US, SWITCH_OFF_US, SWITCH_OFF_US)  # armed, acro
    assert [c.roll_us for _t, c, _on in session.sent[lead:]] == pytest.approx(
        stream.roll_us.tolist()
    )
    assert flight.frames_sent == len(stream) and flight.firmware == "4.6.0"
    assert flight.blackbox.name == "replay-LOG00001.BF" and flight.blackbox.exists()
    profile = session.config.fc.profile
    assert "set p_roll = 50" in profile.cli_lines
    assert "set blackbox_sample_rate = 1/8" in profile.cli_lines
    assert session.config.fc.angle_mode is True  # armed as the log began


def test_a_dying_sitl_ends_the_stream_and_undoes_its_mode(tmp_path: Path) -> None:
    class Dying(FakeSession):
        def __init__(self, config: Any, *, progress: Any = None) -> None:
            super().__init__(config, progress=progress)
            self.die_at_s = 4.5

    with pytest.raises(SitlExitedError):
        fly_replay(
            _stream(4.0), firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
            session_factory=Dying,
        )  # fmt: skip
    session = FakeSession.made[0]
    assert session.bridge.rc_frames_on_set is False
    # It stops within a second (the health check's period) of the SITL's end.
    assert session.sent[-1][0] <= 4.5 + 1.0 and len(session.sent) < 200


def test_a_free_running_sitl_is_refused(tmp_path: Path) -> None:
    class FreeRunning(FakeSession):
        def __init__(self, config: Any, *, progress: Any = None) -> None:
            super().__init__(config, progress=progress)
            self.lockstep = False

    with pytest.raises(ReplayError, match="lockstep bridge"):
        fly_replay(
            _stream(), firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
            session_factory=FreeRunning,
        )  # fmt: skip


def test_a_replay_that_left_no_log_says_so(tmp_path: Path) -> None:
    class NoLog(FakeSession):
        def disarm(self) -> bool:
            return True

    with pytest.raises(ReplayError, match="no blackbox log"):
        fly_replay(
            _stream(), firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
            session_factory=NoLog,
        )  # fmt: skip


@pytest.mark.parametrize(
    ("loop_hz", "rate"),
    [(8000.0, "1/8"), (4000.0, "1/4"), (1000.0, "1/1"), (500.0, "1/1"), (64000.0, "1/16")],
)
def test_the_replays_log_is_kept_near_1_khz(loop_hz: float, rate: str) -> None:
    assert f"set blackbox_sample_rate = {rate}" in blackbox_lines(loop_hz)


def test_the_firmware_says_its_loop_rate_and_must_be_lockstep(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from bfsitl.replay import flight as flight_module

    monkeypatch.setattr(flight_module, "find_firmware", lambda _: SimpleNamespace(path="sitl"))
    traits = SimpleNamespace(lockstep=True, rx_frames=False)
    monkeypatch.setattr(flight_module, "binary_traits", lambda _: traits)
    for generation, loop_hz, frames in (
        (Generation.V4_6, 8000.0, False),  # an older 4.6.0 lockstep build
        (Generation.MASTER, 1000.0, True),  # master's receiver counts frames as they come
    ):
        monkeypatch.setattr(
            flight_module,
            "profile_of_binary",
            lambda _, g=generation: SimpleNamespace(generation=g),
        )
        assert replay_firmware("x") == ReplayFirmware(Path("sitl"), loop_hz, frames)
    traits.lockstep = False
    with pytest.raises(ReplayError, match="firmware build --lockstep"):
        replay_firmware("x")


def test_an_older_build_is_said_and_the_frames_are_asked_for(tmp_path: Path) -> None:
    said: list[str] = []
    flight = fly_replay(
        _stream(), firmware=ReplayFirmware(Path("sitl"), 8000.0, False), quad=IRIS,
        cli_lines=("set p_roll = 40",), out_dir=tmp_path, session_factory=FakeSession,
        progress=said.append,
    )  # fmt: skip
    assert flight.receiver_frames is False
    assert any("rebuild it" in line for line in said)
    # What the FC was given: the lines asked for, then the blackbox's.
    assert flight.cli_lines[0] == "set p_roll = 40"
    assert "set blackbox_device = VIRTUAL" in flight.cli_lines
    # Asked through the RC link's rate: the backend then asks a 4.6.0 build to count frames.
    assert FakeSession.made[0].config.fc.rc_rate_hz == DEFAULT_RC_RATE_HZ


def test_a_new_replay_starts_from_a_fresh_eeprom(tmp_path: Path) -> None:
    stale = tmp_path / "sitl" / "eeprom.bin"
    stale.parent.mkdir()
    (stale.parent / RUN_MARKER).write_text("")
    stale.write_bytes(b"an earlier replay's settings")
    fly_replay(
        _stream(), firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
        session_factory=FakeSession,
    )  # fmt: skip
    assert not stale.exists() and (stale.parent / RUN_MARKER).exists()


def test_a_sitl_folder_no_replay_made_is_left_alone(tmp_path: Path) -> None:
    mine = tmp_path / "sitl" / "notes.txt"
    mine.parent.mkdir()
    mine.write_text("a user's own folder named sitl")
    with pytest.raises(ReplayError, match="give another --out"):
        fly_replay(
            _stream(), firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
            session_factory=FakeSession,
        )  # fmt: skip
    assert mine.read_text() == "a user's own folder named sitl"
    assert not FakeSession.made


def test_the_log_rate_follows_the_carried_pid_denominator(tmp_path: Path) -> None:
    assert pid_process_denom(("set p_roll = 4", "set pid_process_denom = 8")) == 8
    assert pid_process_denom(()) == 1
    fly_replay(
        _stream(), firmware=FIRMWARE, quad=IRIS, cli_lines=("set pid_process_denom = 8",),
        out_dir=tmp_path, session_factory=FakeSession,
    )  # fmt: skip
    # 8 kHz / 8 is a 1 kHz PID loop: every loop logged, not every eighth (125 Hz).
    assert "set blackbox_sample_rate = 1/1" in FakeSession.made[0].config.fc.profile.cli_lines


def test_a_sitl_log_leaves_the_fc_counting_frames_as_it_did(tmp_path: Path) -> None:
    time_s = np.arange(0, 2.0, 0.001)
    command = np.tile([0.0, 0.0, 0.0, 1200.0], (len(time_s), 1))
    stream = stick_stream(synthetic_log(time_s, command, firmware="Betaflight 4.6.0 () SITL"))
    flight = fly_replay(
        stream, firmware=FIRMWARE, quad=IRIS, cli_lines=(), out_dir=tmp_path,
        session_factory=FakeSession,
    )  # fmt: skip
    assert FakeSession.made[0].config.sitl.env == ()
    assert FakeSession.made[0].config.fc.rc_rate_hz is None  # the stock receiver, every step
    assert flight.receiver_frames is False
