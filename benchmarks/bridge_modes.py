"""The physics bridge against the real SITL, per exchange mode and speed.

For each mode a fresh SITL starts in its own network namespace, the embedded physics rests on
the ground, and after a warm-up the health figures are measured over a window:

* firmware time / sim time (MSP_SET_RTC, then MSP_RTC): target 1.00 +/- 0.02
* median PID cycle time (MSP_STATUS): target <= 150 us (125 us when the 8 kHz loop keeps up)
* share of fdm packets answered: target >= 99 %
* achieved speed (sim time / wall time)

Modes: ``frozen`` timestamps (bfsitl's default) at several speeds, and ``sim`` timestamps
(Gazebo parity: timestamp = sim time) at speed 1 for comparison.
"""

from __future__ import annotations

import statistics
import sys
import time
from dataclasses import dataclass

from bfsitl.physics import Simulator
from bfsitl.sim.bridge import bridged_sitl
from bfsitl.sim.health import HealthMonitor, lock_clock, meets_targets
from bfsitl.sitl.process import SitlProcess

WARMUP_S = 2.0


@dataclass
class BridgeRow:
    timestamps: str
    target_speed: float
    fc_clock_ratio: float | None
    fc_cycle_us: float
    answered_ratio: float
    speed: float

    @property
    def faithful(self) -> bool:
        return meets_targets(self.fc_clock_ratio, self.fc_cycle_us, self.answered_ratio)


def log(message: str) -> None:
    print(f"[bridge bench] {message}", file=sys.stderr, flush=True)


def measure_bridge(timestamps: str, speed: float, window_s: float) -> BridgeRow:
    sitl = SitlProcess(isolate=True)
    with bridged_sitl(sitl, Simulator(), speed=speed, timestamps=timestamps) as bridge:
        assert sitl.client is not None
        monitor = HealthMonitor(bridge, sitl.client)
        if timestamps == "frozen":
            lock_clock(monitor)
        time.sleep(WARMUP_S)
        monitor.reset()
        cycles = []
        end = time.monotonic() + window_s
        while time.monotonic() < end:
            cycles.append(monitor.fc_cycle_us(polls=3))
            time.sleep(0.3)
        sample = monitor.sample()  # answered/speed over the whole window
        return BridgeRow(
            timestamps,
            speed,
            sample.fc_clock_ratio,
            statistics.median(cycles),
            sample.answered_ratio,
            sample.speed,
        )


def run_bridge_modes(speeds: tuple[float, ...], window_s: float) -> list[BridgeRow]:
    rows = []
    for timestamps, speed in [("sim", 1.0)] + [("frozen", s) for s in speeds]:
        log(f"timestamps={timestamps} speed={speed}: {window_s:.0f} s window")
        rows.append(measure_bridge(timestamps, speed, window_s))
    return rows


def bridge_table(rows: list[BridgeRow]) -> str:
    lines = [
        "| fdm timestamps | target speed | FC time / sim time | PID cycle median (us) "
        "| fdm answered | achieved speed | all targets |",
        "| --- | ---: | ---: | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        ratio = "n/a" if r.fc_clock_ratio is None else f"{r.fc_clock_ratio:.3f}"
        lines.append(
            f"| {r.timestamps} | {r.target_speed:.2f} | {ratio} | {r.fc_cycle_us:.0f} | "
            f"{r.answered_ratio * 100:.1f} % | {r.speed:.3f} | "
            f"{'yes' if r.faithful else 'no'} |"
        )
    passing = [r.target_speed for r in rows if r.timestamps == "frozen" and r.faithful]
    fastest = f"{max(passing):.2f}" if passing else "none"
    lines.append("")
    lines.append(f"Fastest speed at which all targets hold: {fastest}")
    return "\n".join(lines)
