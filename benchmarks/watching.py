"""What watching a flight costs: the output sinks per row, and whole flights with them on.

Two tables, each against a baseline measured in the same run:

1. Per row, no SITL: the CSV log (the baseline, what every `--log` flight already pays), the
   MCAP file through the Foxglove SDK, and MCAP plus the live server with one subscribed
   client.  Synthetic rows of a real flight's shape.
2. Whole flights on a lockstep build at full speed (`bfsitl fly ... --speed max`): nothing
   written (the baseline), `--log`, `--log --mcap`; wall time of the command, and the hold's
   RMS to show the flight itself is unchanged.  The watched flight with `--configurator` is
   paced to 1x real time (a person watches), so it is reported as that pacing, not as a cost.

Run: `python benchmarks/watching.py [--firmware master-lockstep] [--rows 20000] [--flights 3]`
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path

from bfsitl.mission.flight_row import FlightRow
from bfsitl.records.csv_log import CsvFlightLog
from bfsitl.records.foxglove import FoxgloveRecorder

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]


def sample_row(index: int) -> FlightRow:
    return FlightRow(
        time_s=index * 0.01,
        phase="hold",
        target_alt_m=2.0,
        sim_alt_m=1.98,
        fc_alt_m=2.01,
        climb_m_s=0.02,
        sim_climb_m_s=0.01,
        fc_accel_up_m_s2=0.05,
        roll_deg=1.5,
        pitch_deg=-3.2,
        yaw_deg=12.5,
        sim_tilt_deg=3.4,
        sim_roll_deg=1.4,
        sim_pitch_deg=-3.1,
        sim_yaw_deg=12.2,
        rc_roll_us=1492,
        rc_pitch_us=1530,
        rc_throttle_us=1544,
        rc_yaw_us=1500,
        rc_aux1_us=1800,
        rc_aux2_us=1800,
        motor1=0.52,
        motor2=0.55,
        motor3=0.5,
        motor4=0.51,
        armed=True,
        wall_s=index * 0.001,
        sim_north_m=0.1,
        sim_east_m=-0.2,
        fc_north_m=0.12,
        fc_east_m=-0.18,
        target_north_m=0.0,
        target_east_m=0.0,
        target_heading_deg=12.0,
        waypoint=1,
    )


def per_row_us(rows: int, write_one, close) -> float:  # type: ignore[no-untyped-def]
    template = sample_row(0)
    started = time.perf_counter()
    for index in range(rows):
        write_one(replace(template, time_s=index * 0.01, rc_throttle_us=1500 + index % 100))
    close()
    return (time.perf_counter() - started) / rows * 1e6


def subscribed_client(url: str, stop: threading.Event, received: list[int]) -> threading.Thread:
    """A Foxglove-protocol client subscribed to every channel, counting message frames."""
    from websockets.sync.client import connect

    def run() -> None:
        with connect(url, subprotocols=["foxglove.sdk.v1"]) as ws:
            ws.recv(timeout=5)  # serverInfo
            subscribed = 0
            while not stop.is_set():
                try:
                    data = ws.recv(timeout=0.2)
                except TimeoutError:
                    continue
                if isinstance(data, str):
                    message = json.loads(data)
                    if message["op"] == "advertise":
                        subs = [
                            {"id": subscribed + i, "channelId": c["id"]}
                            for i, c in enumerate(message["channels"])
                        ]
                        subscribed += len(subs)
                        ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                elif data[0] == 1:
                    received[0] += 1

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread


def sink_table(rows: int) -> str:
    results = []
    with tempfile.TemporaryDirectory() as directory:
        folder = Path(directory)
        csv_log = CsvFlightLog(folder / "rows.csv")
        csv_us = per_row_us(rows, csv_log.write, csv_log.close)
        results.append(("CSV log (baseline)", csv_us, (folder / "rows.csv").stat().st_size))
        recorder = FoxgloveRecorder(mcap_path=folder / "rows.mcap").start()
        mcap_us = per_row_us(rows, recorder.write, recorder.close)
        results.append(("MCAP (8 channels)", mcap_us, (folder / "rows.mcap").stat().st_size))
        live = FoxgloveRecorder(mcap_path=folder / "live.mcap", live_port=0).start()
        stop, received = threading.Event(), [0]
        assert live.live_url is not None
        client = subscribed_client(live.live_url, stop, received)
        time.sleep(1.0)  # subscribed before the rows come
        live_us = per_row_us(rows, live.write, lambda: None)
        time.sleep(1.0)
        stop.set()
        client.join(5)
        live.close()
        results.append(
            (
                f"MCAP + live, 1 client ({received[0]} frames received)",
                live_us,
                (folder / "live.mcap").stat().st_size,
            )
        )
    lines = [
        f"{rows} rows each",
        "",
        "| sink | us per row | x CSV | bytes per row |",
        "| --- | --- | --- | --- |",
    ]
    for name, us, size in results:
        lines.append(f"| {name} | {us:.1f} | {us / csv_us:.1f} | {size / rows:.0f} |")
    return "\n".join(lines)


def fly(firmware: str, *extra: str) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory() as directory:
        started = time.perf_counter()
        done = subprocess.run(
            [
                *BFSITL,
                "fly",
                "--firmware",
                firmware,
                "--wind",
                "2",
                "--seed",
                "1",
                "--hold",
                "10",
                "--json",
                *extra,
            ],
            capture_output=True,
            text=True,
            cwd=directory,
            timeout=300,
        )
        wall_s = time.perf_counter() - started
    if done.returncode != 0:
        sys.exit(f"the flight failed: {done.stderr[-2000:]}")
    return wall_s, json.loads(done.stdout)


def flight_table(firmware: str, flights: int) -> str:
    variants = [
        ("nothing written (baseline)", ()),
        ("--log", ("--log", "f.csv")),
        ("--log --mcap", ("--log", "f.csv", "--mcap", "f.mcap")),
    ]
    lines = [
        f"lockstep at full speed, {firmware}, wind 2 m/s, 10 s hold; median of {flights}",
        "",
        "| outputs | wall s | x baseline | hold RMS m |",
        "| --- | --- | --- | --- |",
    ]
    baseline_s = None
    for name, extra in variants:
        runs = [fly(firmware, *extra) for _ in range(flights)]
        wall_s = statistics.median(w for w, _ in runs)
        baseline_s = baseline_s or wall_s
        rms = statistics.median(s["hold"]["rms_error_m"] for _, s in runs)
        lines.append(f"| {name} | {wall_s:.2f} | {wall_s / baseline_s:.2f} | {rms:.3f} |")
    watched_s, watched = fly(
        firmware,
        "--configurator",
        "--configurator-port",
        "0",
        "--foxglove",
        "--foxglove-port",
        "0",
        "--mcap",
        "f.mcap",
    )
    lines.append(
        f"| --configurator --foxglove --mcap (paced to 1x) | {watched_s:.2f} | "
        f"{watched_s / baseline_s:.2f} | {watched['hold']['rms_error_m']:.3f} |"
    )
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--firmware", default="master-lockstep")
    parser.add_argument("--rows", type=int, default=20000)
    parser.add_argument("--flights", type=int, default=3)
    parser.add_argument("--no-flights", action="store_true", help="the sink table only")
    args = parser.parse_args()
    print(sink_table(args.rows))
    if not args.no_flights:
        print()
        print(flight_table(args.firmware, args.flights))


if __name__ == "__main__":
    main()
