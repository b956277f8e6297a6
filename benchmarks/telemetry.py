"""Full-state telemetry updates per second from a real Betaflight 4.6.0 SITL.

Compares, against the same firmware in the same run:

* ``tutorial``: the tutorial's reader: five sequential MSP v1 requests (ATTITUDE, ALTITUDE,
  STATUS, ANALOG, RC), each followed by a short sleep (20 ms) and a read.  One update = all five.
* ``bfsitl sequential``: ``MspClient.telemetry()`` in a loop: one MSP_MULTIPLE_MSP round trip
  (attitude, altitude, status, analog, RC, motors) per update.
* ``bfsitl pipelined``: ``TelemetryPoller(rate_hz=None)``: the same request, three (or eight)
  in flight; and once without the client's wake byte, to show what that byte does.

under three conditions, each on a fresh SITL in its own network namespace:

1. the SITL as people start it by hand (Linux's default 50 us timer slack),
2. as bfsitl starts it (1 ns timer slack, see ``bfsitl/sitl/timer_slack.py``),
3. as 2, with ``serial_update_rate_hz`` raised (CLI ``set``, ``save``, restart).

Beside each figure, the rate of the firmware's SERIAL task as its own ``tasks`` command reports
it: the FC serves one MSP packet per SERIAL run, so that is the ceiling.
Each row is measured ``--repeats`` times (median shown; this 2-core VM is noisy).
Run: ``python benchmarks/telemetry.py [--seconds 3] [--repeats 3] [--raised-rate 1000] [--json]``.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import sys
import time
from dataclasses import asdict, dataclass

from bfsitl.fc.cli_session import CliSession
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.telemetry_poller import TelemetryPoller
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame, MspParser, encode_request
from bfsitl.sitl.process import SitlProcess

TUTORIAL_COMMANDS = (
    MspCommand.ATTITUDE,
    MspCommand.ALTITUDE,
    MspCommand.STATUS,
    MspCommand.ANALOG,
    MspCommand.RC,
)
TUTORIAL_SLEEP_S = 0.02


@dataclass
class Row:
    condition: str
    method: str
    updates_per_s: float  # median of the repeats
    runs_per_s: list[float]
    timeouts: int  # replies the client gave up waiting for, over all repeats
    serial_task_hz: int | None
    gyro_task_hz: int | None
    ratio_to_tutorial: float = 0.0


def log(message: str) -> None:
    print(f"[telemetry bench] {message}", file=sys.stderr, flush=True)


def tutorial_reader(client: MspClient, seconds: float) -> float:
    """The tutorial's method, on the same socket: request, sleep, read, five times."""
    link = client.link
    parser = MspParser()
    updates = 0
    started = time.monotonic()
    while time.monotonic() - started < seconds:
        for command in TUTORIAL_COMMANDS:
            link.write(encode_request(command))
            time.sleep(TUTORIAL_SLEEP_S)
            frames: list[MspFrame] = []
            deadline = time.monotonic() + 1.0
            while not frames and time.monotonic() < deadline:
                frames = [f for f in parser.feed(link.read_some(0.05)) if isinstance(f, MspFrame)]
            msg.decode_reply(command, frames[0].payload)
        updates += 1
    return updates / (time.monotonic() - started)


def sequential(client: MspClient, seconds: float) -> float:
    updates = 0
    started = time.monotonic()
    while time.monotonic() - started < seconds:
        client.telemetry()
        updates += 1
    return updates / (time.monotonic() - started)


def pipelined(client: MspClient, seconds: float, depth: int = 3) -> float:
    with TelemetryPoller(client, rate_hz=None, depth=depth) as poller:
        first = poller.wait_next(0, 2.0)
        if first is None:
            raise RuntimeError("no telemetry from the poller")
        start_sequence, started = poller.sequence, time.monotonic()
        time.sleep(seconds)
        count, elapsed = poller.sequence - start_sequence, time.monotonic() - started
        stats = poller.stats()
        if stats.errors:
            raise RuntimeError(f"poller errors: {stats.last_error}")
        if stats.missed:
            log(f"  {stats.missed} requests got no intact reply (SITL TCP race); skipped")
    return count / elapsed


def task_rates_hz(client: MspClient) -> tuple[int | None, int | None]:
    """SERIAL and GYRO task rates from the firmware's own `tasks` (non-interactive CLI)."""
    output = CliSession(client.link, timeout_s=3.0).batch(["tasks"], check=False)
    rates = []
    for task in ("SERIAL", "GYRO"):
        match = re.search(task + r"\)\s+(\d+)", output)
        rates.append(int(match.group(1)) if match else None)
    return rates[0], rates[1]


def pipelined_deep(client: MspClient, seconds: float) -> float:
    return pipelined(client, seconds, depth=8)


def pipelined_without_wake(client: MspClient, seconds: float) -> float:
    """As ``pipelined``, without the wake byte (see MspClient's module docstring)."""
    saved, client.wake_interval_s = client.wake_interval_s, None
    try:
        return pipelined(client, seconds)
    finally:
        client.wake_interval_s = saved


def measure(
    condition: str, sitl: SitlProcess, seconds: float, repeats: int, with_tutorial: bool
) -> list[Row]:
    client = sitl.client
    assert client is not None
    # Let boot-time calibration settle so every method sees the same steady firmware.
    time.sleep(1.0)
    rows = []
    methods = [
        ("bfsitl sequential", sequential),
        ("bfsitl pipelined, 3 in flight", pipelined),
        ("bfsitl pipelined, 8 in flight", pipelined_deep),
        ("bfsitl pipelined, 3 in flight, no wake byte", pipelined_without_wake),
    ]
    if with_tutorial:
        methods.insert(0, ("tutorial (5 requests + sleeps)", tutorial_reader))
    for name, method in methods:
        log(f"{condition}: {name}, {repeats} x {seconds:.0f} s")
        timeouts_before = client.stats.timeouts
        runs = [method(client, seconds) for _ in range(repeats)]
        rows.append(
            Row(
                condition,
                name,
                statistics.median(runs),
                [round(r, 1) for r in runs],
                client.stats.timeouts - timeouts_before,
                *task_rates_hz(client),
            )
        )
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--seconds", type=float, default=3.0, help="per measurement")
    parser.add_argument(
        "--repeats", type=int, default=3, help="measurements per row; the table shows the median"
    )
    parser.add_argument(
        "--raised-rate",
        type=int,
        default=1000,
        help="serial_update_rate_hz for condition 3 (100..2000)",
    )
    parser.add_argument("--json", action="store_true", help="print rows as JSON")
    args = parser.parse_args()

    rows: list[Row] = []
    log("condition 1: SITL with the OS default timer slack")
    with SitlProcess(isolate=True, timer_slack_ns=None) as sitl:
        rows += measure(
            "default SITL, 100 Hz serial", sitl, args.seconds, args.repeats, with_tutorial=True
        )
    log("condition 2: SITL as bfsitl starts it")
    with SitlProcess(isolate=True) as sitl:
        rows += measure(
            "bfsitl SITL, 100 Hz serial", sitl, args.seconds, args.repeats, with_tutorial=True
        )
        log(f"condition 3: serial_update_rate_hz = {args.raised_rate}")
        assert sitl.client is not None
        with CliSession(sitl.client.link) as cli:
            cli.set("serial_update_rate_hz", args.raised_rate)
            cli.save(restart=sitl.restart_after_reboot)
        rows += measure(
            f"bfsitl SITL, {args.raised_rate} Hz serial",
            sitl,
            args.seconds,
            args.repeats,
            with_tutorial=False,
        )

    baseline = rows[0].updates_per_s
    for row in rows:
        row.ratio_to_tutorial = row.updates_per_s / baseline
    if args.json:
        print(json.dumps([asdict(r) for r in rows], indent=2))
        return 0
    print(
        "| condition | method | updates/s (median) | x tutorial | runs | timeouts "
        "| FC SERIAL Hz | FC GYRO Hz |"
    )
    print("| --- | --- | ---: | ---: | --- | ---: | ---: | ---: |")
    for r in rows:
        runs = " / ".join(f"{x:.0f}" for x in r.runs_per_s)
        print(
            f"| {r.condition} | {r.method} | {r.updates_per_s:.1f} | "
            f"{r.ratio_to_tutorial:.1f}x | {runs} | {r.timeouts} | {r.serial_task_hz} | "
            f"{r.gyro_task_hz} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
