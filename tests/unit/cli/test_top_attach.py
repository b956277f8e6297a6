"""``bfsitl top`` attaching to a running flight: which flight it picks, what it says, and that
it only reads.  The flight's UART2 is a TCP port on 127.0.0.1 served by a fake FC; the flight
is this test process itself (so it "runs"), advertised in a cache folder of the test's own."""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import os
import socket
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.fake_fc import fixed, multiple_msp, telemetry_handlers
from support.storing_fc import STATUS

from bfsitl.cli import attach as attach_module
from bfsitl.cli import top_command
from bfsitl.cli.attach import attached_target, flight_to_attach
from bfsitl.errors import AttachError
from bfsitl.fc.msp_pipeline import is_idempotent
from bfsitl.link import SocketFactory
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import SITL_DEFAULT_BOX_IDS
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import Direction, MspFrame, MspParser, encode_frame
from bfsitl.sitl.running_flights import FlightAdvert, FlightRegistry, process_start_ticks

# ARM and ANGLE (BOXIDS positions 0 and 1), a little CPU load.
ARMED = dataclasses.replace(STATUS, flight_mode_flags=0b11, cpu_load_percent=7)


class TcpFakeFc:
    """A SITL UART on a TCP port: MSP answered from handlers, every command recorded.

    ``refuse``: accept and close at once, as the SITL does to a second client on a UART.
    ``close_after``: close the connection after that many replies (the flight ended)."""

    def __init__(self, *, refuse: bool = False, close_after: int | None = None) -> None:
        self.handlers = telemetry_handlers(
            attitude=msg.Attitude(12, -3, 90),
            altitude=msg.Altitude(200, 0),
            status=ARMED,
            analog=msg.Analog(126, 0, 0, 0, 1260),
            rc=msg.Rc((1500, 1500, 1500, 1550, 1800, 1800) + (1500,) * 10),
            motor=msg.Motor((1542, 1542, 1542, 1542, 0, 0, 0, 0)),
            imu=msg.RawImu((0, 0, 512), (0, 0, 0), (0, 0, 0)),
            box_ids=SITL_DEFAULT_BOX_IDS,
        )
        self.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(self.handlers)
        self.handlers[MspCommand.API_VERSION] = fixed(bytes((0, 1, 47)))
        self.refuse = refuse
        self.close_after = close_after
        self.commands: list[int] = []
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        with contextlib.suppress(OSError):
            conn, _ = self._server.accept()
            with conn:
                if self.refuse:
                    return
                parser, replies = MspParser(), 0
                while data := conn.recv(4096):
                    for frame in parser.feed(data):
                        if not isinstance(frame, MspFrame) or frame.direction is not (
                            Direction.REQUEST
                        ):
                            continue
                        self.commands.append(frame.command)
                        payload = self.handlers[frame.command](frame)
                        conn.sendall(encode_frame(MspFrame(frame.command, payload or b"")))
                        replies += 1
                        if self.close_after is not None and replies >= self.close_after:
                            return

    def close(self) -> None:
        with contextlib.suppress(OSError):
            self._server.shutdown(socket.SHUT_RDWR)  # wakes an accept() still waiting
        self._server.close()
        self._thread.join(timeout=5)


@pytest.fixture
def fake_fc() -> Iterator[TcpFakeFc]:
    fc = TcpFakeFc()
    yield fc
    fc.close()


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setenv("BFSITL_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def this_flight(port: int, *, key: str | None = None, netns_pid: int | None = None) -> FlightAdvert:
    """An advert of a flight flown by this (running) process, its UART2 at ``port``."""
    pid = os.getpid()
    ticks = process_start_ticks(pid)
    assert ticks is not None
    return FlightAdvert(
        key=key or str(pid),
        pid=pid,
        started_ticks=ticks,
        command="bfsitl fly --hold 60",
        firmware="4.6.0 (4.6 conventions)",
        host="127.0.0.1",
        port=port,
        netns_pid=netns_pid,
        started_at_s=1.0e9,
        workdir="run",
    )


def top_args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="bfsitl")
    top_command.add_top_parser(parser.add_subparsers(dest="command_name", required=True))
    return parser.parse_args(["top", *argv])


def run_top(*argv: str, monkeypatch: pytest.MonkeyPatch) -> tuple[int, str]:
    out = io.StringIO()
    monkeypatch.setattr(sys, "stdout", out)
    code = top_command.cmd_top(top_args("--once", *argv))
    return code, out.getvalue()


def test_attach_is_a_third_way_to_pick_the_fc() -> None:
    assert top_args().attach is None
    assert top_args("--attach").attach == ""
    assert top_args("--attach", "123").attach == "123"
    for other in (["--uri", "tcp://h:1"], ["--start"]):
        with pytest.raises(SystemExit):
            top_args("--attach", *other)


def test_top_attaches_to_the_running_flight_says_which_and_only_reads(
    cache: Path,
    fake_fc: TcpFakeFc,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    flight = this_flight(fake_fc.port)
    FlightRegistry().advertise(flight)
    code, frame = run_top(monkeypatch=monkeypatch)
    assert code == 0
    assert f"flight {flight.key}, UART2" in frame and "ARMED" in frame
    assert "M1 1542" in frame
    err = capsys.readouterr().err
    assert f"attaching to flight {flight.key}: `bfsitl fly --hold 60`" in err
    assert "1 frame(s), 1 update(s), 0 error(s)" in err
    assert fake_fc.commands and all(is_idempotent(c) for c in fake_fc.commands)
    assert MspCommand.MULTIPLE_MSP in fake_fc.commands


def test_a_flight_in_a_namespace_is_reached_through_it_and_left_alone(
    cache: Path, fake_fc: TcpFakeFc, monkeypatch: pytest.MonkeyPatch
) -> None:
    joined: list[str] = []

    @contextlib.contextmanager
    def fake_join(netns_pid: int) -> Iterator[SocketFactory]:
        joined.append(f"join {netns_pid}")
        yield socket.socket
        joined.append("left")

    monkeypatch.setattr(attach_module, "_joined", fake_join)
    FlightRegistry().advertise(this_flight(fake_fc.port, netns_pid=4242))
    code, _frame = run_top("--attach", monkeypatch=monkeypatch)
    assert code == 0 and joined == ["join 4242", "left"]


def test_no_flight_keeps_the_usual_target_and_uri_or_start_win(
    cache: Path, fake_fc: TcpFakeFc
) -> None:
    assert flight_to_attach(top_args()) is None  # nothing advertised: tcp://127.0.0.1:5761
    FlightRegistry().advertise(this_flight(fake_fc.port))
    assert flight_to_attach(top_args()) is not None
    assert flight_to_attach(top_args("--uri", "tcp://127.0.0.1:5761")) is None
    assert flight_to_attach(top_args("--start")) is None


def test_attach_with_no_flight_says_how_to_get_one(cache: Path) -> None:
    with pytest.raises(AttachError, match="no running flight to attach to: start one with"):
        flight_to_attach(top_args("--attach"))


def test_several_flights_are_named_and_one_is_chosen_by_key(
    cache: Path, fake_fc: TcpFakeFc, monkeypatch: pytest.MonkeyPatch
) -> None:
    pid = os.getpid()
    registry = FlightRegistry()
    registry.advertise(this_flight(1, key=f"{pid}"))
    registry.advertise(this_flight(fake_fc.port, key=f"{pid}.2"))
    with pytest.raises(AttachError, match=rf"2 flights are running: {pid} .*, {pid}\.2 "):
        top_command.cmd_top(top_args("--once"))
    code, frame = run_top("--attach", f"{pid}.2", monkeypatch=monkeypatch)
    assert code == 0 and f"flight {pid}.2, UART2" in frame


def test_a_port_held_by_another_client_is_said_so(cache: Path) -> None:
    busy = TcpFakeFc(refuse=True)
    try:
        with (
            pytest.raises(AttachError, match="another client holds it"),
            attached_target(this_flight(busy.port), 0.2),
        ):
            pass
    finally:
        busy.close()


def test_nothing_listening_means_the_flight_is_ending(cache: Path) -> None:
    with socket.create_server(("127.0.0.1", 0)) as placeholder:
        port = placeholder.getsockname()[1]
    with (
        pytest.raises(AttachError, match="cannot be reached .*it may be ending"),
        attached_target(this_flight(port), 0.2),
    ):
        pass


def test_top_ends_quietly_when_the_flight_ends(
    cache: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    ending = TcpFakeFc(close_after=1)  # answers the attach probe, then the SITL is gone
    try:
        flight = this_flight(ending.port)
        FlightRegistry().advertise(flight)
        code, _frame = run_top(monkeypatch=monkeypatch)
    finally:
        ending.close()
    assert code == 0
    assert f"flight {flight.key} ended" in capsys.readouterr().err
