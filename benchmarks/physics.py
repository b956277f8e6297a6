"""Cost of the embedded physics alone (no SITL, no sockets), per step and as a real-time factor.

Scenarios, each run ``--repeats`` times on a fresh :class:`bfsitl.physics.Simulator` (median
shown; this 2-core VM is noisy):

* ``airborne``: hovering with commands that change every step (motors, rotors, drag, rigid
  body; no contact);
* ``airborne + fdm``: the same plus what the bridge adds per step: ``read_sensors()``,
  the fdm packet (``FdmEncoder.pack``);
* ``parked``: resting on the skids with armed-idle motors (static friction: body frozen);
* ``contact``: upside down on the ground, where every step runs the sub-stepped spring-damper
  contact (the worst case: the cost during landings, crashes and take-offs).

The real-time factor is simulated time over wall time at the given step.  The model is C
(``bfsitl/kernel/physics.c``): each step here is one call through its Python face, what a
real-time or UDP lockstep run pays per step (the compiled lockstep loop, through shared
memory, pays far less: ``docs/lockstep.md``).  Target: >= 25x at 1 ms (<= 40 us per step),
leaving the bridge its budget.

Then, unless ``--no-bridge``, the bridge against the real SITL per exchange mode and speed
(``bridge_modes.py`` beside this file): firmware time / sim time, PID cycle, share of fdm
answered, achieved speed, and the fastest speed at which every target holds.

Run: ``python benchmarks/physics.py [--step-ms 1] [--seconds 2] [--repeats 5] [--json]
[--no-bridge] [--speeds 0.5,0.75,1.0,1.25] [--window 6]``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

from bfsitl.physics import IRIS, Simulator
from bfsitl.protocol.fdm_encoding import FdmEncoder
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE

SCENARIOS = ("airborne", "airborne + fdm", "parked", "contact")
TARGET_REAL_TIME_FACTOR = 25.0


def _prepare(sim: Simulator, scenario: str) -> list[tuple[float, float, float, float]]:
    """Put the vehicle in the scenario's situation; return a cycle of 8 motor commands."""
    hover = IRIS.hover_command
    if scenario in ("airborne", "airborne + fdm"):
        sim.reset((0.0, 0.0, -100.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
        # Small, balanced differential commands: the vehicle wobbles but stays up.
        return [
            (hover + 0.004 * s, hover - 0.004 * s, hover - 0.004 * s, hover + 0.004 * s)
            for s in (1, -1, 0.5, -0.5, 0.25, -0.25, 0, 0)
        ]
    if scenario == "parked":
        sim.reset()
        return [(0.055, 0.055, 0.055, 0.055)] * 8
    if scenario == "contact":
        sim.reset(roll_deg=180.0)
        for _ in range(300):  # settle onto its back first
            sim.step((0.0, 0.0, 0.0, 0.0), 0.001)
        return [(0.0, 0.0, 0.0, 0.0)] * 8
    raise ValueError(f"unknown scenario {scenario!r}; choose from {SCENARIOS}")


def _run_once(step_s: float, steps: int, scenario: str) -> float:
    """Wall seconds for ``steps`` steps of one scenario on a fresh simulator."""
    sim = Simulator()
    commands = _prepare(sim, scenario)
    step = sim.step
    if scenario == "airborne + fdm":
        read, pack = sim.read_sensors, FdmEncoder(DEFAULT_PROFILE, sim.home).pack
        start = time.perf_counter()
        for k in range(steps):
            step(commands[k & 7], step_s)
            pack(read(), 1024.0 + k * 0.0625)
        return time.perf_counter() - start
    start = time.perf_counter()
    for k in range(steps):
        step(commands[k & 7], step_s)
    return time.perf_counter() - start


def measure_physics(
    step_s: float = 0.001,
    sim_seconds: float = 2.0,
    *,
    repeats: int = 5,
    scenario: str = "airborne",
) -> dict[str, object]:
    """Median cost of one physics step, and the real-time factor it allows.

    Returns ``{"scenario", "step_s", "sim_seconds", "repeats", "step_us", "step_us_runs",
    "steps_per_s", "real_time_factor"}`` (``step_us`` is the median over ``repeats`` runs).
    """
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; choose from {SCENARIOS}")
    steps = max(1, round(sim_seconds / step_s))
    runs_us = [_run_once(step_s, steps, scenario) / steps * 1e6 for _ in range(repeats)]
    step_us = statistics.median(runs_us)
    return {
        "scenario": scenario,
        "step_s": step_s,
        "sim_seconds": steps * step_s,
        "repeats": repeats,
        "step_us": step_us,
        "step_us_runs": runs_us,
        "steps_per_s": 1e6 / step_us,
        "real_time_factor": step_s * 1e6 / step_us,
    }


def markdown_table(rows: list[dict[str, object]]) -> str:
    step_ms = float(rows[0]["step_s"]) * 1000  # type: ignore[arg-type]
    lines = [
        f"| scenario ({step_ms:g} ms step) | us per step (median) | steps/s | real-time factor |",
        "| --- | ---: | ---: | ---: |",
    ]
    for row in rows:
        lines.append(
            f"| {row['scenario']} | {row['step_us']:.1f} | {row['steps_per_s']:,.0f} | "
            f"{row['real_time_factor']:.0f}x |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step-ms", type=float, default=1.0)
    parser.add_argument("--seconds", type=float, default=2.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--json", action="store_true")
    parser.add_argument(
        "--no-bridge", action="store_true", help="physics only: skip the runs against the real SITL"
    )
    parser.add_argument(
        "--speeds",
        default="0.5,0.75,1.0,1.25",
        help="speeds to try with frozen timestamps (comma separated)",
    )
    parser.add_argument(
        "--window", type=float, default=6.0, help="seconds of measurement per bridge mode"
    )
    args = parser.parse_args(argv)
    rows = [
        measure_physics(args.step_ms / 1000, args.seconds, repeats=args.repeats, scenario=s)
        for s in SCENARIOS
    ]
    bridge_rows = []
    if not args.no_bridge:
        from bridge_modes import bridge_table, run_bridge_modes  # beside this script

        speeds = tuple(float(x) for x in args.speeds.split(","))
        bridge_rows = run_bridge_modes(speeds, args.window)
    if args.json:
        print(json.dumps({"physics": rows, "bridge": [vars(r) for r in bridge_rows]}, indent=2))
    else:
        print(markdown_table(rows))
        print(
            f"\nPython {sys.version.split()[0]}; target >= {TARGET_REAL_TIME_FACTOR:.0f}x "
            f"real time at 1 ms."
        )
        if bridge_rows:
            print()
            print(bridge_table(bridge_rows))
    airborne = rows[0]["real_time_factor"]
    return 0 if airborne >= TARGET_REAL_TIME_FACTOR else 1  # type: ignore[operator]


if __name__ == "__main__":
    sys.exit(main())
