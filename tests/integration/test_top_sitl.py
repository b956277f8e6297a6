"""``bfsitl top`` against a real, freshly booted 4.6.0 SITL (each in its own network namespace).

The frame is rendered without a terminal, through Rich's recording console.  Which arming
blockers to expect is read from the SITL itself with MSP_STATUS (a different message from the
STATUS_EX the dashboard polls), before and after the frames: a flag set in both reads was set
throughout, so it must be in the frame.  RXLOSS and ANGLE must always be among them: nothing
ever sends RC or fdm packets to a fresh SITL (docs/firmware-facts.md#fresh-sitl-blockers).
"""

from __future__ import annotations

import argparse
import io
import os
import sys
import time
from pathlib import Path

import pytest

from bfsitl.cli import target as target_module
from bfsitl.cli import top_command
from bfsitl.dashboard.keys import NoKeys
from bfsitl.dashboard.loop import run_dashboard
from bfsitl.dashboard.render import render_text
from bfsitl.dashboard.view_model import DashboardView
from bfsitl.protocol import messages as msg
from bfsitl.protocol.arming import ArmingFlag, arming_flag_info
from bfsitl.sitl.firmware import FirmwareBinary
from bfsitl.sitl.process import SitlProcess

pytestmark = pytest.mark.sitl

#: Blockers of a SITL that never got RC (RXLOSS) nor an fdm packet (ANGLE).
ALWAYS_BLOCKED = (ArmingFlag.RX_FAILSAFE, ArmingFlag.ANGLE)


def blocker_names(sitl: SitlProcess) -> set[str]:
    assert sitl.client is not None
    return {info.cli_name for info in sitl.client.get(msg.Status).arming_blockers}


def reported_blockers(sitl: SitlProcess, expected: set[str], timeout_s: float = 5.0) -> set[str]:
    """The SITL's blockers once ``expected`` are among them (its first arming check may not
    have run in the instant it starts answering MSP); fails after ``timeout_s``."""
    deadline_s = time.monotonic() + timeout_s
    names = blocker_names(sitl)
    while not expected <= names and time.monotonic() < deadline_s:
        time.sleep(0.05)
        names = blocker_names(sitl)
    assert expected <= names, (
        f"a fresh SITL should report {sorted(expected)}, got {names}; its log:\n"
        f"{sitl.log_tail()}\n{_namespace_sockets(sitl)}"
    )
    return names


def _namespace_sockets(sitl: SitlProcess) -> str:
    """UDP sockets in the SITL's namespace: who else could be feeding it."""
    pid = sitl.network.netns_pid if sitl.network else None
    try:
        return Path(f"/proc/{pid or 'self'}/net/udp").read_text()
    except OSError as exc:
        return str(exc)


def test_top_frame_shows_the_blockers_the_sitl_reports(sitl: SitlProcess) -> None:
    assert sitl.client is not None
    always = {arming_flag_info(flag).cli_name for flag in ALWAYS_BLOCKED}
    before = reported_blockers(sitl, always)
    views: list[DashboardView] = []
    result = run_dashboard(
        sitl.client, show=views.append, keys=NoKeys(), target=sitl.uri, rate_hz=10.0, max_frames=3
    )
    after = blocker_names(sitl)
    steady = before & after  # set throughout the frames: must be in the last one

    # 4.6.0 SITL now and then corrupts a reply (see msp_client.py): a failed poll may
    # happen and is counted, but most polls must be answered.
    assert result.link.updates >= 2, result.link
    assert result.link.updates + result.link.errors == 3, result.link
    assert result.link.rtt_last_ms is not None and 0 < result.link.rtt_last_ms < 500
    view = views[-1]
    assert view.flight is not None and not view.flight.armed
    text = render_text(view, width=160)
    flat = " ".join(text.split())
    assert f"arming blocked by {len(view.flight.blockers)} flag(s)" in text
    shown = {blocker.name for blocker in view.flight.blockers}
    assert always <= shown, (shown, before, after)
    for name in steady | always:
        assert name in text, (name, before, after, text)
    for flag in ALWAYS_BLOCKED:
        fix = arming_flag_info(flag).fix
        assert " ".join(fix.split()[:5]) in flat, (fix, text)
    # A disarmed SITL drives its four motors at mincommand.
    assert [m.value_us for m in view.flight.motors] == [1000, 1000, 1000, 1000]
    assert sitl.uri in text
    assert f"{result.link.updates} answered, {result.link.errors} failed" in text


class _RecordingSitl(SitlProcess):
    started: list[_RecordingSitl] = []

    def start(self) -> _RecordingSitl:
        super().start()
        self.started_pid = self.pid
        _RecordingSitl.started.append(self)
        return self


def test_top_start_once_prints_the_frame_and_stops_its_sitl(
    firmware: FirmwareBinary,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """`bfsitl top --start --once`: an isolated SITL of its own, one frame, SITL gone after."""
    _RecordingSitl.started = []
    monkeypatch.setattr(target_module, "SitlProcess", _RecordingSitl)
    monkeypatch.setattr(sys, "stdout", io.StringIO())
    parser = argparse.ArgumentParser(prog="bfsitl")
    top_command.add_top_parser(parser.add_subparsers(dest="command_name", required=True))
    args = parser.parse_args(
        [
            "top",
            "--start",
            "--once",
            "--firmware",
            str(firmware.path),
            "--workdir",
            str(tmp_path / "run"),
        ]
    )
    out = sys.stdout
    assert top_command.cmd_top(args) == 0
    text = out.getvalue()  # type: ignore[attr-defined]

    assert len(_RecordingSitl.started) == 1
    started = _RecordingSitl.started[0]
    assert started.network is None
    assert not os.path.exists(f"/proc/{started.started_pid}"), "the SITL was left running"
    for flag in ALWAYS_BLOCKED:
        assert arming_flag_info(flag).cli_name in text, text
    assert "private network namespace" in text
    assert "1 frame(s), 1 update(s)" in capsys.readouterr().err
