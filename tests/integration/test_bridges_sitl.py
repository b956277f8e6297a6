"""The bridges against the real SITL, each SITL in its own network namespace.

The WebSocket server listens on the host's 127.0.0.1 and reaches the namespaced SITL through
the namespace's socket factory, so a browser on the host talks to a SITL that nothing else on
the host can see.  The real Configurator in headless Chromium is driven against it in
test_configurator_app.py (and during a flight in test_watch_flight_sitl.py).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import serial  # type: ignore[import-untyped]
from process_checks import process_alive
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from bfsitl.bridges.websocket_relay import CLOSE_BUSY, CLOSE_UPSTREAM_GONE, WebSocketRelay
from bfsitl.cli.bridge_commands import sitl_upstream
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame, MspParser, encode_request
from bfsitl.sitl.process import SitlProcess

pytestmark = pytest.mark.sitl

API_VERSION_REQUEST = encode_request(MspCommand.API_VERSION)
#: The real command line: its stop signals (SIGTERM like Ctrl-C) and its one-line errors.
BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]


#: MSP API of each generation (4.6.0 msp.c; master 301d01a msp_protocol.h).
API_OF_GENERATION = {"4.6.0": (1, 47), "master": (1, 49)}


@pytest.fixture
def generation_relay(generation_firmware, request, tmp_path) -> Iterator[tuple[str, tuple]]:
    """(URL, expected MSP API) of a relay to each supported firmware in turn."""
    process = SitlProcess(generation_firmware, workdir=tmp_path / "run", isolate=True)
    process.start()
    try:
        with WebSocketRelay(sitl_upstream(process), port=0).running() as url:
            yield url, API_OF_GENERATION[request.node.callspec.params["generation_firmware"]]
    finally:
        process.stop()


def api_over_websocket(ws, timeout_s: float = 3.0) -> msg.ApiVersion:
    ws.send(API_VERSION_REQUEST)
    parser = MspParser()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for event in parser.feed(ws.recv(timeout=max(0.0, deadline - time.monotonic()))):
            if isinstance(event, MspFrame) and event.command == MspCommand.API_VERSION:
                return msg.ApiVersion.decode(event.payload)
    raise AssertionError("no MSP_API_VERSION reply through the bridge")


def test_websocket_client_reaches_the_namespaced_sitl(generation_relay):
    relay_url, api = generation_relay
    with connect(relay_url, subprotocols=["wsSerial"]) as ws:
        assert api_over_websocket(ws).api == api
        with connect(relay_url, subprotocols=["binary"]) as second:
            with pytest.raises(ConnectionClosed):
                second.recv(timeout=3.0)
            assert second.close_code == CLOSE_BUSY
        assert api_over_websocket(ws).api == api  # the first client still works
    # The TCP slot was released: the next client gets the SITL.
    with connect(relay_url, subprotocols=["binary"]) as ws:
        assert api_over_websocket(ws).api == api


def test_reboot_ends_the_client_and_the_started_sitl_comes_back(sitl, relay_url):
    """A Configurator's "save and reboot" ends a SITL process; the bridge restarts it."""
    ended_pid = sitl.pid
    assert ended_pid is not None
    with connect(relay_url, subprotocols=["wsSerial"]) as ws:
        ws.send(encode_request(MspCommand.REBOOT))
        with pytest.raises(ConnectionClosed):
            while True:
                ws.recv(timeout=10.0)
        assert ws.close_code == CLOSE_UPSTREAM_GONE
    # The ended process is reaped by the namespace agent on its own, not left a zombie until
    # the next client comes.
    deadline = time.monotonic() + 3.0
    while Path(f"/proc/{ended_pid}").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not Path(f"/proc/{ended_pid}").exists(), f"pid {ended_pid} left as a zombie"
    with connect(relay_url, subprotocols=["wsSerial"], open_timeout=15) as ws:
        # The relay restarts the SITL once this client is connected, so the first reply waits
        # for a whole start: ~1 s, or ~3 s when a launch lost a race at boot and was retried
        # (that made a 3 s wait fail on a loaded CI machine).
        assert api_over_websocket(ws, timeout_s=15.0).api == (1, 47)
    assert sitl.starts == 2


# --- the commands, end to end ---------------------------------------------------------------


@contextlib.contextmanager
def run_bridge(*args: str) -> Iterator[tuple[subprocess.Popen[str], str]]:
    """Start a bridge command; yield it and the first line it prints (its URL or path)."""
    process = subprocess.Popen(
        [*BFSITL, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        line = process.stdout.readline().strip() if process.stdout else ""
        if not line:
            process.wait(timeout=10)
            raise AssertionError(
                f"the bridge printed nothing; stderr:\n"
                f"{process.stderr.read() if process.stderr else ''}"
            )
        yield process, line
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()


def _sitl_pid(stderr: str) -> int:
    line = next(ln for ln in stderr.splitlines() if "SITL ready (pid " in ln)
    return int(line.split("(pid ")[1].split(")")[0])


STOPS = [pytest.param(signal.SIGINT, id="ctrl-c"), pytest.param(signal.SIGTERM, id="sigterm")]


@pytest.mark.parametrize("stop", STOPS)
def test_serial_bridge_command_start_and_stop(firmware, tmp_path, stop):
    link = tmp_path / "ttyBF"
    with run_bridge("serial-bridge", "--start", "--link", str(link)) as (process, printed):
        assert printed == str(link) and link.is_symlink()
        with serial.Serial(printed, timeout=0.1) as port:
            port.write(API_VERSION_REQUEST)
            parser, frames = MspParser(), []
            deadline = time.monotonic() + 3.0
            while not frames and time.monotonic() < deadline:
                frames = [e for e in parser.feed(port.read(64)) if isinstance(e, MspFrame)]
        assert frames and msg.ApiVersion.decode(frames[0].payload).api == (1, 47)
        process.send_signal(stop)
        assert process.wait(timeout=15) == 0
        stderr = process.stderr.read() if process.stderr else ""
    assert not link.exists() and not link.is_symlink()
    assert "SITL stopped" in stderr
    assert not process_alive(_sitl_pid(stderr))


@pytest.mark.parametrize("stop", STOPS)
def test_configurator_command_start_and_stop(firmware, stop):
    with run_bridge("configurator", "--start", "--port", "0") as (process, url):
        assert url.startswith("ws://127.0.0.1:")
        with connect(url, subprotocols=["wsSerial"]) as ws:
            assert api_over_websocket(ws).api == (1, 47)
            process.send_signal(stop)
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=10.0)
        assert process.wait(timeout=15) == 0
        stderr = process.stderr.read() if process.stderr else ""
    assert "SITL stopped" in stderr
    assert not process_alive(_sitl_pid(stderr))


def test_configurator_command_errors_are_one_clear_line(tmp_path):
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = str(taken.getsockname()[1])
        refused = subprocess.run(
            [*BFSITL, "configurator", "--uri", "tcp://127.0.0.1:1"],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert refused.returncode == 1 and "connection refused" in refused.stderr
        assert len(refused.stderr.strip().splitlines()) == 1
        not_tcp = subprocess.run(
            [*BFSITL, "serial-bridge", "--uri", "serial:///dev/x"],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert not_tcp.returncode == 1 and "tcp://HOST:PORT" in not_tcp.stderr
        regular = tmp_path / "file"
        regular.write_text("x")
        # A listening socket stands in for a SITL: the path check must come first anyway.
        occupied = subprocess.run(
            [
                *BFSITL,
                "serial-bridge",
                "--uri",
                f"tcp://127.0.0.1:{port}",
                "--link",
                str(regular),
            ],
            capture_output=True,
            text=True,
            timeout=30,
        )
        assert occupied.returncode == 1 and "refusing to overwrite" in occupied.stderr
        assert regular.read_text() == "x"
