"""The real Betaflight Configurator (web build, headless Chromium) against ``bfsitl configurator``.

What a user does, step by step, with ``bfsitl configurator --start --port PORT`` running (a 4.6.0
SITL in its own network namespace behind a WebSocket on 127.0.0.1):

* the Connect menu offers manual connections only once Expert Mode is on (Options); then
  "Manual Selection" with the printed URL connects, and Setup shows Board SITL, Firmware
  BTFL 4.6.0, MSP API 1.47.0 and the attitude readout; the app talks subprotocol ``binary``;
* the CLI tab answers; leaving it sends ``exit``, which reboots (ends) the SITL and leaves the
  app disconnected; Connect again reaches the SITL the bridge restarted;
* a ``set`` and ``save`` in the CLI survive that reboot;
* Ctrl-C ends the command cleanly (exit code 0, SITL stopped) while the app is connected, and
  the app notices;
* without --port (6761, if free here) the app's own "Betaflight SITL" entry connects, once
  Expert Mode is on.

The app comes from ``configurator_app`` (see there for the selectors and the app's quirks).  One
Chromium per module, one bridge for the first three tests; the file takes 40 to 50 s here (2
cores), each test well inside its budget.
"""

from __future__ import annotations

import os
import re
import secrets
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import pytest
from configurator_app import (  # noqa: F401  (pytest fixtures, and the app's driver)
    ConfiguratorPage,
    configurator_app_url,
    configurator_browser,
    configurator_chromium,
    configurator_dist,
    open_configurator,
)
from process_checks import process_alive

if TYPE_CHECKING:
    from playwright.sync_api import Browser

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]
#: The bridge's default port: the app's built-in "Betaflight SITL" entry.
DEFAULT_PORT = 6761
#: Per test, on a busy 2-core CI machine: loading the app ~3 s, each connect ~2 s, each SITL
#: (re)start ~1 s (3 s when a launch is retried).
TEST_TIMEOUT_S = 60


class RunningBridge:
    """``bfsitl configurator --start`` in the background; its stderr collected line by line."""

    def __init__(self, *args: str) -> None:
        self.process = subprocess.Popen(
            [*BFSITL, "configurator", "--start", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        self.lines: list[str] = []
        self._url: list[str] = []
        self._printed = threading.Event()
        self._readers = [
            threading.Thread(target=self._read_stdout, daemon=True),
            threading.Thread(target=self._read_stderr, daemon=True),
        ]
        for reader in self._readers:
            reader.start()

    def _read_stdout(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            if line.strip() and not self._url:
                self._url.append(line.strip())
                self._printed.set()
        self._printed.set()

    def _read_stderr(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.lines.append(line.rstrip("\n"))

    def url(self, timeout_s: float = 30.0) -> str:
        """The URL it prints on stdout once the SITL is up and the WebSocket listens."""
        if not self._printed.wait(timeout_s) or not self._url:
            raise AssertionError(f"the bridge printed no URL; stderr:\n{self.stderr()}")
        return self._url[0]

    def stderr(self) -> str:
        return "\n".join(self.lines)

    def sitl_pids(self) -> list[int]:
        """Every SITL it started, in order ("SITL ready (pid N)")."""
        return [int(m.group(1)) for m in re.finditer(r"SITL ready \(pid (\d+)\)", self.stderr())]

    def wait_for(self, pattern: str, timeout_s: float = 15.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            match = re.search(pattern, self.stderr())
            if match:
                return match
            time.sleep(0.05)
        raise AssertionError(
            f"no {pattern!r} from the bridge within {timeout_s} s; stderr:\n{self.stderr()}"
        )

    def ctrl_c(self, timeout_s: float = 15.0) -> int:
        """SIGINT, as Ctrl-C in its terminal; its exit code once it and its readers are done."""
        self.process.send_signal(signal.SIGINT)
        code = self.process.wait(timeout=timeout_s)
        for reader in self._readers:
            reader.join(timeout=5)
        return code

    def stop(self) -> None:
        if self.process.poll() is None:
            try:
                self.ctrl_c()
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait()
        for stream in (self.process.stdout, self.process.stderr):
            if stream is not None:
                stream.close()


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def _port_free(port: int) -> bool:
    """Whether a server could listen on ``port`` now (as asyncio's: TIME_WAIT is no hold)."""
    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


def _start_bridge(firmware, workdir: Path, port: int | None = None) -> RunningBridge:
    """With ``port`` None a free one, given with --port; with DEFAULT_PORT, no --port."""
    port = port or _free_port()
    chosen = () if port == DEFAULT_PORT else ("--port", str(port))
    bridge = RunningBridge(*chosen, "--firmware", str(firmware.path), "--workdir", str(workdir))
    try:
        assert bridge.url() == f"ws://127.0.0.1:{port}"
    except BaseException:
        bridge.stop()
        raise
    return bridge


@pytest.fixture(scope="module")
def bridge(firmware, tmp_path_factory: pytest.TempPathFactory) -> Iterator[RunningBridge]:
    """One bridge (and SITL, restarted after each reboot) for the module's app tests."""
    running = _start_bridge(firmware, tmp_path_factory.mktemp("bridge-run"))
    try:
        yield running
    finally:
        running.stop()


@pytest.fixture
def site(request: pytest.FixtureRequest) -> tuple[Browser, str]:
    """(the module's Chromium, the served app's URL): skips without them, before a SITL."""
    app_url = request.getfixturevalue("configurator_app_url")  # the build first: cheaper
    return request.getfixturevalue("configurator_browser"), app_url


@pytest.fixture
def app(site: tuple[Browser, str]) -> Iterator[ConfiguratorPage]:
    """The app freshly loaded in its own browser context (no settings from other tests)."""
    with open_configurator(*site) as page:
        yield page


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_expert_mode_then_manual_selection_shows_the_sitl_in_setup(app, bridge, tmp_path):
    assert "Manual Selection" not in app.connect_menu_items()  # Expert Mode is off
    app.enable_expert_mode()
    assert {"Betaflight SITL", "Manual Selection"} <= set(app.connect_menu_items())

    app.connect(bridge.url(), via="manual")
    assert app.active_tab() == "Setup"
    assert app.connect_label() == "Disconnect (Manual)"
    assert app.board_text() == "SITL"
    assert app.firmware_text() == "BTFL 4.6.0"
    assert app.api_version_text() == "1.47.0"
    attitude = app.attitude()  # at rest, no simulator: level
    assert all(abs(value) <= 180 for value in (attitude.heading, attitude.pitch, attitude.roll))
    assert "CLI" in app.tabs() and "Motors" in app.tabs()
    # What the bridge saw: the app's page origin, and the subprotocol it settled on.
    bridge.wait_for(r"connected \(http://127\.0\.0\.1:\d+, subprotocol binary\)")
    shot = app.screenshot(tmp_path / "setup.png")
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"

    app.disconnect()
    assert app.connect_label() == bridge.url()  # Connect now offers the same URL again


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_cli_answers_and_after_leaving_it_connect_reaches_the_restarted_sitl(app, bridge):
    app.enable_expert_mode()
    app.connect(bridge.url())
    assert "Entering CLI Mode" in app.open_cli()
    status = app.cli("status")
    assert "MCU SIMULATOR" in status
    assert re.search(r"Arming disable flags:.*\bCLI\b", status), status
    assert "Betaflight / SITL (SITL) 4.6.0" in app.cli("version")
    assert "craft_name = " in app.cli("get name")  # `get` matches names: craft_name, ...
    starts = len(bridge.sitl_pids())
    ended = bridge.sitl_pids()[-1]

    app.leave_cli()  # the app sends `exit`: the SITL reboots, which ends its process
    assert app.connect_label() == bridge.url()
    deadline = time.monotonic() + 5.0
    while process_alive(ended) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not process_alive(ended), f"the SITL (pid {ended}) did not end on `exit`"

    app.reconnect()  # Connect, as the user would: the bridge starts a new SITL
    assert app.firmware_text() == "BTFL 4.6.0"
    assert app.api_version_text() == "1.47.0"
    assert len(bridge.sitl_pids()) == starts + 1
    assert bridge.sitl_pids()[-1] != ended
    app.open_cli()
    assert "Arming disable flags" in app.cli("status")


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_a_setting_saved_in_the_cli_is_there_after_the_reboot(app, bridge):
    name = f"BFSITL{secrets.token_hex(3).upper()}"  # new in each run; craft_name takes 16
    app.enable_expert_mode()
    app.connect(bridge.url())
    assert f"craft_name = {name}" not in app.cli("get craft_name")
    assert f"craft_name set to {name}" in app.cli(f"set craft_name = {name}")
    starts = len(bridge.sitl_pids())
    saved = app.cli_save()  # writes eeprom.bin in the run directory, then reboots
    assert "Rebooting" in saved, saved

    app.reconnect()
    assert app.firmware_text() == "BTFL 4.6.0"
    assert len(bridge.sitl_pids()) == starts + 1  # a new process: it came from eeprom.bin
    assert f"craft_name = {name}" in app.cli("get craft_name")


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_ctrl_c_stops_the_bridge_cleanly_while_the_app_is_connected(site, firmware, tmp_path):
    with open_configurator(*site) as app:
        bridge = _start_bridge(firmware, tmp_path / "run")
        try:
            app.enable_expert_mode()
            app.connect(bridge.url())
            assert app.firmware_text() == "BTFL 4.6.0"
            sitl = bridge.sitl_pids()[-1]
            assert bridge.ctrl_c() == 0
        finally:
            bridge.stop()
        assert "SITL stopped" in bridge.stderr()
        assert "Traceback" not in bridge.stderr()
        assert not process_alive(sitl)
        app.wait_disconnected()  # the app saw its link go
        assert app.connect_label() == bridge.url()


@pytest.mark.timeout(TEST_TIMEOUT_S)
def test_on_the_default_port_the_built_in_betaflight_sitl_entry_connects(site, firmware, tmp_path):
    """``bfsitl configurator --start`` without --port: the app's own "Betaflight SITL" entry
    (ws://127.0.0.1:6761), which is a manual entry too: Expert Mode first."""
    if not _port_free(DEFAULT_PORT):
        pytest.skip(f"port {DEFAULT_PORT} is in use (another bridge?)")
    with open_configurator(*site) as app:
        bridge = _start_bridge(firmware, tmp_path / "run", port=DEFAULT_PORT)
        try:
            assert "Betaflight SITL" not in app.connect_menu_items()
            app.enable_expert_mode()
            app.connect(bridge.url(), via="bookmark")  # picking the entry connects at once
            assert app.firmware_text() == "BTFL 4.6.0"
            app.disconnect()
            assert app.connect_label() == "Betaflight SITL"  # remembered by its name
        finally:
            bridge.stop()
