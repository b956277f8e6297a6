"""Watching a flight while bfsitl flies it: the Configurator on UART2, Foxglove, MCAP.

`bfsitl fly --configurator` puts MSP on the SITL's UART2 as well and bridges it to a WebSocket,
while bfsitl keeps UART1.  What is checked, on both firmware generations, in wind (so that the
attitude and the motors move, and a wrong port or a stale reading would show):

* through the bridge, during the flight, the FC answers as the firmware it is, and the
  altitude and motors it reports follow the flight bfsitl's own log records;
* with the user's Configurator build (``BFSITL_CONFIGURATOR_DIST``), the real app connects as a
  user connects it and shows the flight's attitude and receiver (without it, that part is
  skipped and the scripted client alone watches);
* a page from a foreign origin is refused with 1008 while the watcher is connected;
* the mission's metrics are those of the same flight unwatched (same seed, same wind);
* the MCAP file holds one message per CSV row on every per-row channel, stamped in
  simulation time; the live Foxglove server advertises the channels and streams them.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import threading
import time
from pathlib import Path

import pytest
from configurator_app import (  # noqa: F401  (pytest fixtures)
    DIST_ENV_VAR,
    configurator_app_url,
    configurator_browser,
    configurator_chromium,
    configurator_dist,
    watch_flight,
)
from mcap.reader import make_reader
from test_fly_sitl import BFSITL, read_rows
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from bfsitl.bridges.origin_policy import CLOSE_POLICY_VIOLATION
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame, MspParser, encode_request

pytestmark = pytest.mark.sitl

API_OF = {"4.6.0-gps": (1, 47), "master": (1, 49)}
#: Long enough a hold for the browser to connect and sample while the quad leans into the wind.
FLIGHT_ARGS = (
    "--wind",
    "3",
    "--wind-from",
    "60",
    "--gusts",
    "1",
    "--seed",
    "3",
    "--hold",
    "14",
    "--json",
)
#: Where a run may keep the browser's screenshot (the README's picture is taken this way).
SCREENSHOT_ENV = "BFSITL_SAVE_SCREENSHOT"


@pytest.fixture(params=["4.6.0-gps", "master"])
def generation(request: pytest.FixtureRequest) -> tuple[str, Path]:
    name = (
        "lockstep_gps_46_firmware" if request.param == "4.6.0-gps" else "lockstep_master_firmware"
    )
    return request.param, request.getfixturevalue(name)


class RunningFly:
    """``bfsitl fly`` in the background, its stderr collected line by line."""

    def __init__(self, cwd: Path, *args: str) -> None:
        self.process = subprocess.Popen(
            [*BFSITL, "fly", *args],
            cwd=cwd,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stderr is not None
        for line in self.process.stderr:
            self.lines.append(line)

    def wait_for(self, pattern: str, timeout_s: float = 60.0) -> re.Match[str]:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for line in list(self.lines):
                if found := re.search(pattern, line):
                    return found
            if self.process.poll() is not None and not self._reader.is_alive():
                break
            time.sleep(0.05)
        raise AssertionError(f"no {pattern!r} in the output:\n{''.join(self.lines)}")

    def finish(self, timeout_s: float = 120.0) -> tuple[int, str]:
        try:
            stdout, _ = self.process.communicate(timeout=timeout_s)
        finally:
            if self.process.poll() is None:
                self.process.kill()
        self._reader.join(timeout=5)
        return self.process.returncode, stdout


def msp_request(ws: ClientConnection, command: MspCommand, timeout_s: float = 3.0) -> bytes:
    """One MSP request through the bridge; the reply's payload."""
    ws.send(encode_request(command))
    parser = MspParser()
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for event in parser.feed(ws.recv(timeout=max(0.01, deadline - time.monotonic()))):
            if isinstance(event, MspFrame) and event.command == command:
                return event.payload
    raise AssertionError(f"no {command.name} reply through the Configurator bridge")


def refused_code(url: str, origin: str) -> int | None:
    with connect(url, subprotocols=["binary"], origin=origin) as ws:
        with pytest.raises(ConnectionClosed):
            ws.send(encode_request(MspCommand.API_VERSION))
            ws.recv(timeout=5.0)
        return ws.close_code


def foxglove_sees(url: str, topic: str, wanted: int = 5) -> tuple[set[str], list[int]]:
    """Connect as Foxglove does; the advertised topics and the log times of ``wanted``
    messages of ``topic``."""
    with connect(url, subprotocols=["foxglove.sdk.v1"], origin="https://app.foxglove.dev") as ws:
        assert json.loads(ws.recv(timeout=5))["op"] == "serverInfo"
        channels: dict[str, int] = {}
        times: list[int] = []
        deadline = time.monotonic() + 15
        while len(times) < wanted and time.monotonic() < deadline:
            data = ws.recv(timeout=5)
            if isinstance(data, str):
                message = json.loads(data)
                if message["op"] == "advertise":
                    channels.update({c["topic"]: c["id"] for c in message["channels"]})
                    if topic in channels and not times:
                        ws.send(
                            json.dumps(
                                {
                                    "op": "subscribe",
                                    "subscriptions": [{"id": 1, "channelId": channels[topic]}],
                                }
                            )
                        )
            elif data[0] == 1:  # message data: opcode, subscription id, log time, payload
                times.append(int.from_bytes(data[5:13], "little"))
    return set(channels), times


def _real_app(request: pytest.FixtureRequest) -> tuple[object, str] | None:
    """(Chromium, the served app's URL) when the user gave a Configurator build, else None."""
    if not os.environ.get(DIST_ENV_VAR, "").strip():
        return None
    app_url = request.getfixturevalue("configurator_app_url")
    return request.getfixturevalue("configurator_browser"), app_url


def test_the_configurator_watches_a_flight_in_wind(generation, request, tmp_path):
    name, firmware = generation
    real_app = _real_app(request)  # before any flight: a broken build fails at once
    baseline = subprocess.run(
        [*BFSITL, "fly", "--firmware", str(firmware), *FLIGHT_ARGS],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=tmp_path,
    )
    assert baseline.returncode == 0, baseline.stderr
    unwatched = json.loads(baseline.stdout)

    flight = RunningFly(
        tmp_path,
        "--firmware",
        str(firmware),
        *FLIGHT_ARGS,
        "--configurator",
        "--configurator-port",
        "0",
        "--foxglove",
        "--foxglove-port",
        "0",
        "--log",
        "watched.csv",
        "--mcap",
        "watched.mcap",
    )
    try:
        url = flight.wait_for(r"watch this flight at (ws://\S+)").group(1)
        foxglove_url = flight.wait_for(r"Foxglove WebSocket connection to (ws://\S+)").group(1)
        flight.wait_for(r"reached \d", timeout_s=60)  # airborne, leaning into the wind
        # A foreign page is refused by both servers, whoever else is connected.
        assert refused_code(url, "https://evil.example") == CLOSE_POLICY_VIOLATION
        with connect(
            foxglove_url, subprotocols=["foxglove.sdk.v1"], origin="https://evil.example"
        ) as ws:
            with pytest.raises(ConnectionClosed):
                ws.recv(timeout=5)
            assert ws.close_code == CLOSE_POLICY_VIOLATION
        topics, pose_times_ns = foxglove_sees(foxglove_url, "/sim/pose")
        # The real Configurator, as a user connects it (Expert Mode, Manual Selection).
        shot = tmp_path / "configurator-flight.png"
        seen = None
        if real_app is not None:
            browser, app_url = real_app
            seen = watch_flight(
                url, browser=browser, app_url=app_url, seconds=4.0, rc_seconds=1.5, screenshot=shot
            )
        # Then a script on the same bridge, until the flight ends.
        seen_alt_m, seen_motors = [], []
        with connect(url, subprotocols=["binary"], origin="http://127.0.0.1:8000") as ws:
            api = msg.ApiVersion.decode(msp_request(ws, MspCommand.API_VERSION))
            with contextlib.suppress(ConnectionClosed, AssertionError):
                while flight.process.poll() is None:
                    altitude = msg.Altitude.decode(msp_request(ws, MspCommand.ALTITUDE))
                    motors = msg.Motor.decode(msp_request(ws, MspCommand.MOTOR))
                    seen_alt_m.append(altitude.altitude_m)
                    seen_motors.append(max(motors.motors_us[:4]))
                    time.sleep(0.2)
        code, stdout = flight.finish()
    finally:
        if flight.process.poll() is None:
            flight.process.kill()
    assert code == 0, "".join(flight.lines)
    watched = json.loads(stdout)
    assert watched["outcome"] == "landed"
    rows = read_rows(tmp_path / "watched.csv")

    # The Configurator showed the flying SITL: its firmware, and the attitude the FC reports
    # (leaning into 3 m/s of wind; a Configurator on an idle SITL would read level).
    if seen is not None:
        version = {"4.6.0-gps": "4.6.0", "master": "2026.12.0"}[name]
        assert version in seen.firmware and seen.api_version.startswith(
            ".".join(map(str, API_OF[name]))
        )
        assert seen.moved(), seen.attitudes
        airborne = [r for r in rows if r["phase"] in ("takeoff", "hold")]
        leans = []
        for axis in ("pitch", "roll"):
            shown = [getattr(a, axis) for a in seen.attitudes]
            flown = [float(r[f"{axis}_deg"]) for r in airborne]
            # Every reading is one the FC went through (gusts move it; 4 s of 14 sampled).
            assert min(flown) - 1.0 <= min(shown) and max(shown) <= max(flown) + 1.0, (
                axis,
                shown,
                min(flown),
                max(flown),
            )
            leans.append(abs(statistics.fmean(shown)))
        assert max(leans) > 2.0, seen.attitudes  # leaning into the wind: idle reads level
        assert seen.rc and all(1400 < sample["Throttle"] < 1700 for sample in seen.rc), seen.rc
        assert shot.stat().st_size > 20_000
        if os.environ.get(SCREENSHOT_ENV) and name == "master":
            shutil.copy(shot, os.environ[SCREENSHOT_ENV])

    # What the script saw on UART2 is the flight bfsitl flew on UART1.
    assert api.api == API_OF[name]
    flown_max_m = max(float(r["fc_alt_m"]) for r in rows)
    assert max(seen_alt_m) == pytest.approx(flown_max_m, abs=0.3), (seen_alt_m, flown_max_m)
    # It saw the hold and the landing's descent, with the motors spinning.
    assert max(seen_alt_m) > 1.5 and min(seen_alt_m) < max(seen_alt_m) - 1.0, seen_alt_m
    assert max(seen_motors) > 1200

    # Foxglove: every channel advertised, poses stamped in simulation time (the flight's
    # rows are 10 ms apart at 100 Hz: lockstep paced to 1x, not the wall clock's jitter).
    assert {"/sim/pose", "/fc/pose", "/flight/altitude", "/rc", "/motors", "/events"} <= topics
    assert len(pose_times_ns) >= 5 and pose_times_ns == sorted(pose_times_ns)
    row_times_ns = {round(float(r["time_s"]) * 1e9) for r in rows}
    assert set(pose_times_ns) <= row_times_ns

    # The MCAP file: one message per CSV row on every per-row channel, at the rows' times.
    with (tmp_path / "watched.mcap").open("rb") as file:
        reader = make_reader(file)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        counts = {
            c.topic: summary.statistics.channel_message_counts.get(c.id, 0)
            for c in summary.channels.values()
        }
        stamped = [m.log_time for _s, c, m in reader.iter_messages(topics=["/fc/pose"])]
    for topic in (
        "/sim/pose",
        "/fc/pose",
        "/flight/altitude",
        "/flight/position",
        "/rc",
        "/motors",
        "/fc/state",
    ):
        assert counts[topic] == len(rows), (topic, counts[topic], len(rows))
    assert counts["/events"] >= 6  # armed, take-off, reached, hold, landing, disarmed...
    assert stamped == [round(float(r["time_s"]) * 1e9) for r in rows]

    # Watching does not change the flight: the same seed and wind, the same metrics.
    assert watched["hold"]["rms_error_m"] == pytest.approx(
        unwatched["hold"]["rms_error_m"], abs=0.02
    )
    assert watched["hold"]["rms_error_m"] < 0.15
    assert watched["landed_from_start_m"] == pytest.approx(
        unwatched["landed_from_start_m"], abs=0.3
    )
    assert math.isfinite(watched["landed_from_start_m"])
