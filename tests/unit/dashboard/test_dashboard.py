"""``bfsitl top``: link statistics, the view model, the Rich frame and the polling loop.

The pure parts get literal inputs; the loop runs against the in-memory FC of
tests/support/fake_fc.py with scripted keys, so no terminal and no SITL is involved.
"""

from __future__ import annotations

import argparse
import io
import sys
from collections.abc import Iterator

import pytest
from support.fake_fc import FakeFcLink, telemetry_link  # noqa: E402

from bfsitl.cli import target as target_module  # noqa: E402
from bfsitl.cli import top_command  # noqa: E402
from bfsitl.dashboard.keys import NoKeys, is_quit  # noqa: E402
from bfsitl.dashboard.link_stats import LinkMeter, LinkStats  # noqa: E402
from bfsitl.dashboard.loop import run_dashboard  # noqa: E402
from bfsitl.dashboard.render import render_text  # noqa: E402
from bfsitl.dashboard.view_model import (  # noqa: E402
    DashboardView,
    build_view,
    flight_view,
    pwm_fill,
)
from bfsitl.errors import ExtraMissingError, LinkClosedError  # noqa: E402
from bfsitl.fc.msp_client import MspClient, Telemetry  # noqa: E402
from bfsitl.protocol import messages as msg  # noqa: E402
from bfsitl.protocol.arming import ArmingFlag, arming_flag_info  # noqa: E402
from bfsitl.protocol.boxes import SITL_DEFAULT_BOX_IDS  # noqa: E402
from bfsitl.protocol.msp_codes import MspCommand  # noqa: E402

BLOCKED = (ArmingFlag.RX_FAILSAFE, ArmingFlag.ANGLE, ArmingFlag.BOOT_GRACE_TIME)


def status(flags: int, *, armed: bool = False) -> msg.StatusEx:
    """A SITL-like STATUS_EX: ANGLE mode (BOXIDS position 1) on, ARM (position 0) if armed."""
    return msg.StatusEx(
        cycle_time_us=125,
        i2c_errors=0,
        sensors_mask=0x23,
        flight_mode_flags=0b10 | int(armed),
        pid_profile=0,
        cpu_load_percent=7,
        pid_profile_count=4,
        rate_profile_index=0,
        arming_disable_flag_count=29,
        arming_disable_flags=flags,
        config_state=0,
        cpu_temp_c=0,
        rate_profile_count=4,
    )


BLOCKED_STATUS = status(sum(flag.mask for flag in BLOCKED))
MESSAGES = dict(
    attitude=msg.Attitude(123, -45, 270),
    altitude=msg.Altitude(1234, -50),
    status=BLOCKED_STATUS,
    analog=msg.Analog(126, 0, 0, 0, 1260),
    rc=msg.Rc((1500, 1600, 1400, 1000, 1800) + (1500,) * 11),
    motor=msg.Motor((1000, 1100, 1200, 2100, 0, 1300, 0, 0)),
    imu=msg.RawImu((0, 0, 256), (0, 0, 0), (0, 0, 0)),
    box_ids=SITL_DEFAULT_BOX_IDS,
)


def snapshot(**changes: object) -> Telemetry:
    fields = {k: v for k, v in MESSAGES.items() if k != "box_ids"}
    fields.update(changes)
    return Telemetry(
        received_at_s=10.0,
        attitude=fields["attitude"],
        altitude=fields["altitude"],
        status=fields["status"],
        analog=fields["analog"],
        rc=fields["rc"],
        motors=fields["motor"],
        imu=fields["imu"],
        box_ids=SITL_DEFAULT_BOX_IDS,
    )


def link_stats(**changes: object) -> LinkStats:
    values = dict(
        updates=40,
        errors=2,
        updates_per_s=8.0,
        rtt_last_ms=11.5,
        rtt_mean_ms=10.2,
        rtt_max_ms=14.0,
        age_s=0.05,
        last_error=None,
        elapsed_s=5.0,
    )
    values.update(changes)
    return LinkStats(**values)  # type: ignore[arg-type]


# --- link statistics ---------------------------------------------------------------------------


def test_link_meter_before_any_poll_has_no_figures() -> None:
    stats = LinkMeter(started_at_s=100.0).stats(100.0)
    assert (stats.updates, stats.errors, stats.updates_per_s) == (0, 0, 0.0)
    assert stats.rtt_last_ms is None and stats.rtt_mean_ms is None and stats.age_s is None


def test_link_meter_rate_and_round_trip_over_the_window() -> None:
    """Ten polls in the last second of a 2 s window: 5/s; the mean/max cover the window."""
    meter = LinkMeter(started_at_s=0.0, window_s=2.0)
    for i in range(10):
        meter.record_update(rtt_s=0.010 + 0.001 * i, at_s=9.1 + 0.1 * i)
    stats = meter.stats(now_s=10.0)
    assert stats.updates == 10
    assert stats.updates_per_s == pytest.approx(5.0)
    assert stats.rtt_last_ms == pytest.approx(19.0)
    assert stats.rtt_mean_ms == pytest.approx(14.5)
    assert stats.rtt_max_ms == pytest.approx(19.0)
    assert stats.age_s == pytest.approx(0.0)
    assert stats.elapsed_s == pytest.approx(10.0)


def test_link_meter_forgets_old_polls_but_keeps_the_totals() -> None:
    """After a stall the rate drops to what the window saw; totals and errors remain."""
    meter = LinkMeter(started_at_s=0.0, window_s=1.0)
    for i in range(20):
        meter.record_update(rtt_s=0.050, at_s=0.05 * i)
    meter.record_update(rtt_s=0.002, at_s=5.0)
    meter.record_error("no MSP reply", at_s=5.2)
    stats = meter.stats(now_s=5.5)
    assert stats.updates == 21 and stats.errors == 1
    assert stats.updates_per_s == pytest.approx(1.0)
    assert stats.rtt_max_ms == pytest.approx(2.0)
    assert stats.age_s == pytest.approx(0.5)
    assert stats.last_error == "no MSP reply"


def test_link_meter_early_rate_uses_the_time_elapsed() -> None:
    """Half a second in, 4 polls are 8/s, not 4 divided by the whole window."""
    meter = LinkMeter(started_at_s=0.0, window_s=2.0)
    for i in range(4):
        meter.record_update(rtt_s=0.01, at_s=0.1 * (i + 1))
    assert meter.stats(now_s=0.5).updates_per_s == pytest.approx(8.0)


def test_link_meter_rejects_an_empty_window() -> None:
    with pytest.raises(ValueError):
        LinkMeter(started_at_s=0.0, window_s=0.0)


# --- view model --------------------------------------------------------------------------------


def test_flight_view_decodes_attitude_altitude_modes_and_blockers() -> None:
    view = flight_view(snapshot())
    assert (view.roll_deg, view.pitch_deg, view.heading_deg) == (12.3, -4.5, 270)
    assert (view.altitude_m, view.vario_m_s, view.battery_v) == (12.34, -0.5, 12.6)
    assert view.flight_modes == ("ANGLE",)
    assert not view.armed
    assert [b.name for b in view.blockers] == ["RXLOSS", "ANGLE", "BOOTGRACE"]
    angle = view.blockers[1]
    assert angle.fix == arming_flag_info(ArmingFlag.ANGLE).fix
    assert angle.meaning == arming_flag_info(ArmingFlag.ANGLE).meaning
    assert angle.bit == ArmingFlag.ANGLE


def test_flight_view_shows_four_motors_and_any_other_that_exists() -> None:
    """MSP_MOTOR always has 8 values; 0 means absent, except that M1-M4 always show."""
    view = flight_view(snapshot(motor=msg.Motor((1000, 0, 1200, 1300, 0, 1500, 0, 0))))
    assert [m.label for m in view.motors] == ["M1", "M2", "M3", "M4", "M6"]
    assert [m.value_us for m in view.motors] == [1000, 0, 1200, 1300, 1500]


def test_flight_view_rc_channels_in_msp_rc_order_with_aux_labels() -> None:
    view = flight_view(snapshot())
    assert [c.label for c in view.rc] == [
        "roll",
        "pitch",
        "yaw",
        "thr",
        "AUX1",
        "AUX2",
        "AUX3",
        "AUX4",
        "AUX5",
        "AUX6",
    ]
    assert [c.value_us for c in view.rc[:5]] == [1500, 1600, 1400, 1000, 1800]


def test_pwm_fill_is_clamped_to_the_bar() -> None:
    assert [pwm_fill(v) for v in (0, 1000, 1500, 2000, 2100)] == [0.0, 0.0, 0.5, 1.0, 1.0]


def test_build_view_marks_old_data_stale_and_no_data_not_stale() -> None:
    fresh = build_view(snapshot(), link_stats(age_s=0.2), target="t", rate_hz=8.0)
    old = build_view(snapshot(), link_stats(age_s=3.0), target="t", rate_hz=8.0)
    nothing = build_view(None, link_stats(age_s=None), target="t", rate_hz=8.0)
    assert not fresh.stale and old.stale
    assert nothing.flight is None and not nothing.stale


# --- the rendered frame ------------------------------------------------------------------------


def frame(view: DashboardView, width: int = 140) -> str:
    return render_text(view, width)


def test_frame_names_every_blocker_with_its_fix() -> None:
    text = frame(build_view(snapshot(), link_stats(), target="tcp://x:5761", rate_hz=8.0))
    assert "arming blocked by 3 flag(s)" in text
    flat = " ".join(text.split())
    for flag in BLOCKED:
        info = arming_flag_info(flag)
        assert info.cli_name in text
        # Wrapped across lines in the table, so compare with whitespace collapsed.
        assert " ".join(info.fix.split()[:5]) in flat


def test_frame_shows_attitude_altitude_motors_rc_modes_and_link() -> None:
    text = frame(build_view(snapshot(), link_stats(), target="tcp://x:5761", rate_hz=8.0))
    for expected in (
        "tcp://x:5761",
        "disarmed",
        "+12.3°",
        "-4.5°",
        "270°",
        "+12.34 m",
        "12.60 V",
        "125 us",
        "M4",
        "2100",
        "AUX1",
        "1800",
        "flight modes: ANGLE",
        "8.0 updates/s",
        "40 answered, 2 failed",
        "11.5 ms",
        "polling at 8 Hz",
    ):
        assert expected in text, expected


def test_frame_when_armed_and_when_nothing_blocks() -> None:
    armed = snapshot(status=status(0, armed=True))
    clear = snapshot(status=status(0))
    armed_text = frame(build_view(armed, link_stats(), target="t", rate_hz=8.0))
    clear_text = frame(build_view(clear, link_stats(), target="t", rate_hz=8.0))
    assert "ARMED" in armed_text and "RXLOSS" not in armed_text
    assert "nothing blocks arming" in clear_text


def test_frame_before_the_first_reply_and_when_stale() -> None:
    waiting = frame(
        build_view(
            None,
            link_stats(
                updates=0,
                age_s=None,
                rtt_last_ms=None,
                rtt_mean_ms=None,
                rtt_max_ms=None,
                last_error="no MSP reply to MSP_X",
            ),
            target="tcp://x:5761",
            rate_hz=5.0,
        )
    )
    assert "waiting for telemetry" in waiting and "no telemetry yet" in waiting
    assert "no MSP reply to MSP_X" in waiting and "none yet" in waiting
    stale = frame(build_view(snapshot(), link_stats(age_s=4.0), target="t", rate_hz=8.0))
    assert "STALE" in stale


def test_frame_prints_brackets_literally_not_as_markup() -> None:
    """An error text with [tags] is shown as written, never interpreted by Rich."""
    text = frame(
        build_view(
            None, link_stats(last_error="bad [bold]reply[/bold] [x"), target="t", rate_hz=8.0
        )
    )
    assert "bad [bold]reply[/bold] [x" in text


def test_frame_fits_an_80_column_terminal_without_losing_blocker_names() -> None:
    text = frame(build_view(snapshot(), link_stats(), target="t", rate_hz=8.0), width=80)
    assert max(len(line) for line in text.splitlines()) <= 80
    for flag in BLOCKED:
        assert arming_flag_info(flag).cli_name in text


# --- the loop ----------------------------------------------------------------------------------


class ScriptedKeys:
    """Returns the scripted answers one per wait; None (no key) once they run out."""

    def __init__(self, *answers: str | None | BaseException) -> None:
        self.answers = list(answers)
        self.waits = 0

    def wait_key(self, timeout_s: float) -> str | None:
        self.waits += 1
        if not self.answers:
            return None
        answer = self.answers.pop(0)
        if isinstance(answer, BaseException):
            raise answer
        return answer


def fake_client(link: FakeFcLink | None = None) -> MspClient:
    return MspClient(link or telemetry_link(**MESSAGES), timeout_s=0.1)


def test_loop_shows_frames_from_the_fc_until_max_frames() -> None:
    views: list[DashboardView] = []
    result = run_dashboard(
        fake_client(), show=views.append, keys=NoKeys(), target="fake", rate_hz=100.0, max_frames=3
    )
    assert (result.frames, result.ended_by) == (3, "frames")
    assert len(views) == 3 and all(v.flight is not None for v in views)
    assert views[-1].flight is not None
    assert [b.name for b in views[-1].flight.blockers] == ["RXLOSS", "ANGLE", "BOOTGRACE"]
    assert result.link.updates == 3 and result.link.errors == 0
    assert result.link.rtt_last_ms is not None and result.link.rtt_last_ms > 0


def test_loop_quits_on_q_and_ignores_other_keys() -> None:
    keys = ScriptedKeys(None, "x", "q")
    views: list[DashboardView] = []
    result = run_dashboard(fake_client(), show=views.append, keys=keys, target="fake", rate_hz=1.0)
    assert result.ended_by == "key"
    assert result.frames == 2  # frame 1, no key; frame 2, "x" ignored then "q"


def test_loop_treats_ctrl_c_as_a_clean_quit() -> None:
    keys = ScriptedKeys(None, KeyboardInterrupt())
    result = run_dashboard(
        fake_client(), show=lambda view: None, keys=keys, target="fake", rate_hz=1.0
    )
    assert (result.ended_by, result.frames) == ("interrupt", 2)


def test_loop_counts_a_failed_poll_and_keeps_the_last_values_marked_stale() -> None:
    link = telemetry_link(**MESSAGES)
    client = fake_client(link)
    views: list[DashboardView] = []

    def show(view: DashboardView) -> None:
        views.append(view)
        if len(views) == 1:  # the FC stops answering telemetry after the first frame
            link.handlers[MspCommand.MULTIPLE_MSP] = lambda _request: None

    result = run_dashboard(
        client,
        show=show,
        keys=NoKeys(),
        target="fake",
        rate_hz=100.0,
        max_frames=2,
        stale_after_s=0.05,
    )
    assert result.link.updates == 1 and result.link.errors == 1
    assert "no MSP reply" in (result.link.last_error or "")
    last = views[-1]
    assert last.flight is not None and last.stale
    assert last.flight.roll_deg == 12.3


def test_loop_ends_with_the_error_when_the_fc_closes_the_link() -> None:
    link = telemetry_link(**MESSAGES)
    link.closed_by_peer = True
    with pytest.raises(LinkClosedError):
        run_dashboard(
            fake_client(link),
            show=lambda view: None,
            keys=NoKeys(),
            target="fake",
            rate_hz=100.0,
            max_frames=2,
        )


def test_loop_rejects_a_non_positive_rate() -> None:
    with pytest.raises(ValueError):
        run_dashboard(
            fake_client(), show=lambda view: None, keys=NoKeys(), target="fake", rate_hz=0.0
        )


def test_quit_keys() -> None:
    assert is_quit("q") and is_quit("Q") and is_quit("xq") and is_quit("\x04")
    assert not is_quit("x") and not is_quit("")


# --- the command -------------------------------------------------------------------------------


def top_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bfsitl")
    top_command.add_top_parser(parser.add_subparsers(dest="command_name", required=True))
    return parser


def test_top_arguments() -> None:
    args = top_parser().parse_args(["top", "--uri", "tcp://h:1", "--rate", "5", "--once"])
    assert (args.uri, args.rate, args.once, args.func) == (
        "tcp://h:1",
        5.0,
        True,
        top_command.cmd_top,
    )
    defaults = top_parser().parse_args(["top"])
    assert defaults.rate == 8.0 and not defaults.once and not defaults.start
    for bad in ("0", "-1", "fast"):
        with pytest.raises(SystemExit):
            top_parser().parse_args(["top", "--rate", bad])
    with pytest.raises(SystemExit):
        top_parser().parse_args(["top", "--uri", "tcp://h:1", "--start"])


@pytest.fixture
def fake_target(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """open_target yields a client of the fake FC; records that it was left."""
    events: list[str] = []

    import contextlib

    @contextlib.contextmanager
    def fake_open_target(args: argparse.Namespace) -> Iterator[target_module.Target]:
        events.append("open")
        try:
            yield target_module.Target(fake_client(), None)
        finally:
            events.append("closed")

    monkeypatch.setattr(top_command, "open_target", fake_open_target)
    yield events


def test_top_once_prints_one_frame_and_closes_the_target(
    fake_target: list[str], capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(sys, "stdout", io.StringIO())
    args = top_parser().parse_args(["top", "--uri", "tcp://fake:5761", "--once"])
    out = sys.stdout
    assert top_command.cmd_top(args) == 0
    text = out.getvalue()  # type: ignore[attr-defined]
    assert fake_target == ["open", "closed"]
    assert "tcp://fake:5761" in text
    for flag in BLOCKED:
        assert arming_flag_info(flag).cli_name in text
    assert "1 frame(s), 1 update(s), 0 error(s)" in capsys.readouterr().err


def test_top_without_rich_says_which_extra_to_install(
    fake_target: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "rich.console", None)
    with pytest.raises(ExtraMissingError, match=r"bfsitl\[top\]"):
        top_command.cmd_top(top_parser().parse_args(["top", "--once"]))
    assert fake_target == []  # nothing was opened


def test_live_screen_draws_frames_on_a_terminal_console() -> None:
    """The full-screen sink, on a recording console that claims to be a terminal."""
    from rich.console import Console

    from bfsitl.dashboard.live import LiveScreen

    console = Console(
        file=io.StringIO(),
        force_terminal=True,
        width=120,
        height=40,
        record=True,
        color_system=None,
    )
    with LiveScreen(console) as screen:
        screen.show(build_view(None, link_stats(), target="t", rate_hz=8.0))
        screen.show(build_view(snapshot(), link_stats(), target="t", rate_hz=8.0))
    text = console.export_text()
    assert "waiting for telemetry" in text
    for flag in BLOCKED:
        assert arming_flag_info(flag).cli_name in text
    raw = console.file.getvalue()  # type: ignore[attr-defined]
    assert "\x1b[?1049h" in raw and "\x1b[?1049l" in raw  # entered and left the alt screen


def test_a_lost_reply_is_retried_when_asked_to() -> None:
    """--once retries: a frame from one poll must not come out empty for one lost reply."""
    link = telemetry_link(**MESSAGES)
    link.drop_next.add(MspCommand.MULTIPLE_MSP)
    result = run_dashboard(
        fake_client(link),
        show=lambda view: None,
        keys=NoKeys(),
        target="fake",
        rate_hz=100.0,
        max_frames=1,
        retries=1,
    )
    assert (result.link.updates, result.link.errors) == (1, 0)
    link.drop_next.add(MspCommand.MULTIPLE_MSP)
    result = run_dashboard(
        fake_client(link),
        show=lambda view: None,
        keys=NoKeys(),
        target="fake",
        rate_hz=100.0,
        max_frames=1,
    )
    assert (result.link.updates, result.link.errors) == (0, 1)
