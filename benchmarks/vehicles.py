"""Each vehicle through the real firmware: how it flies and what it costs, IRIS the baseline.

For each vehicle (IRIS and the shipped profiles) on each lockstep build (4.6.0 with GPS;
master when ``BFSITL_MASTER_SOURCE`` names a tree or the cache has ``master-lockstep``) and
each seed, with the fused altitude controller at 100 Hz, the default flight in 2.5 m/s wind
with 0.5 m/s gusts: take-off to 2 m holding the take-off point, a 10 s position hold, a 10 m
leg north, landing.

* **take-off**: rise time and overshoot of the simulated truth (the controller's defaults
  carried over to the vehicle, bfsitl.control.vehicle_gains);
* **hold**: the mean throttle against the vehicle's predicted hover throttle
  (bfsitl.vehicles.throttle), height RMS and position RMS of the truth;
* **leg**: how long the 10 m took and where it ended;
* **speed**: simulated seconds per wall second, and its ratio to IRIS's in the same run (the
  physics' cost is the same for every vehicle; what differs is how the firmware and the loop
  spend the flight).

Run: ``python benchmarks/vehicles.py [--seeds 2] [--build]``.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from dataclasses import dataclass

from firmware_cache import MASTER_SOURCE, MASTER_SOURCE_ENV_VAR, cached_firmware

from bfsitl.backend.options import World
from bfsitl.build import FirmwareBuildOptions, FirmwareCache
from bfsitl.control import make_controller
from bfsitl.control.metrics import step_response
from bfsitl.mission import FlightLoop, FlightSession, SessionConfig
from bfsitl.mission.session import FLY_PROFILE, FcSetup, SitlLaunch, with_fast_serial
from bfsitl.physics.wind import Wind
from bfsitl.vehicles import hover_throttle_us, load_vehicle, vehicle_names

BUILDS = {
    "4.6.0-gps-lockstep": (None, FirmwareBuildOptions(gps=True, lockstep=True)),
    "master-lockstep": (MASTER_SOURCE, FirmwareBuildOptions(lockstep=True)),
}
WIND = Wind.from_direction(2.5, 60.0, 0.5)
HOLD_S = 10.0
LEG_M = 10.0


@dataclass
class Flight:
    vehicle: str
    firmware: str
    seed: int
    rise_s: float
    overshoot_pct: float
    hold_us: float
    predicted_us: float
    height_rms_m: float
    position_rms_m: float
    leg_s: float
    leg_end_m: float
    sim_s: float
    wall_s: float


def fly(vehicle: str, firmware: str, path: str, seed: int) -> Flight:
    quad = load_vehicle(vehicle)
    config = SessionConfig(
        sitl=SitlLaunch(firmware=path),
        world=World(quad=quad, wind=WIND, seed=seed),
        fc=FcSetup(profile=with_fast_serial(FLY_PROFILE)),
    )
    started = time.monotonic()
    with FlightSession(config) as session:
        loop = FlightLoop(session, make_controller("fused", quad=quad), rate_hz=100)
        loop.arm()
        loop.wait_on_ground(2.0)
        takeoff_from = len(loop.rows)
        loop.takeoff(2.0, hold_position=True)
        held_from = len(loop.rows)
        loop.hold_position(HOLD_S)
        held = loop.rows[held_from:]
        leg_s = loop.fly_to(LEG_M, 0.0)
        end = loop.rows[-1]
        loop.land()
        sim_s = loop.rows[-1].time_s
    wall_s = time.monotonic() - started
    climb = loop.rows[takeoff_from:held_from] + held
    metrics = step_response([r.time_s for r in climb], [r.sim_alt_m for r in climb], target_m=2.0)
    return Flight(
        vehicle=vehicle,
        firmware=firmware,
        seed=seed,
        rise_s=metrics.rise_time_s,
        overshoot_pct=metrics.overshoot_pct,
        hold_us=statistics.fmean(r.rc_throttle_us for r in held),
        predicted_us=hover_throttle_us(quad),
        height_rms_m=_rms([r.sim_alt_m - 2.0 for r in held]),
        position_rms_m=_rms([math.hypot(r.sim_north_m, r.sim_east_m) for r in held]),
        leg_s=leg_s,
        leg_end_m=math.hypot(end.sim_north_m - LEG_M, end.sim_east_m),
        sim_s=sim_s,
        wall_s=wall_s,
    )


def _rms(values: list[float]) -> float:
    return math.sqrt(statistics.fmean(v * v for v in values))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--build", action="store_true", help="build the firmware if missing")
    parser.add_argument("--vehicle", action="append", default=[], help="only these vehicles")
    args = parser.parse_args()
    firmwares = {
        "4.6.0-gps-lockstep": cached_firmware(
            "4.6.0-gps-lockstep", *BUILDS["4.6.0-gps-lockstep"], args.build
        )
    }
    if os.environ.get(MASTER_SOURCE_ENV_VAR) or FirmwareCache().resolve("master-lockstep"):
        firmwares["master-lockstep"] = cached_firmware(
            "master-lockstep", *BUILDS["master-lockstep"], args.build
        )
    vehicles = args.vehicle or list(vehicle_names())
    flights: list[Flight] = []
    for firmware, path in firmwares.items():
        for seed in range(1, args.seeds + 1):
            # Interleaved, so a slower spell of the machine falls on every vehicle alike.
            for vehicle in vehicles:
                flights.append(fly(vehicle, firmware, path, seed))
    print(
        f"{'firmware':20} {'vehicle':16} {'rise s':>6} {'over %':>6} {'hold us':>7} "
        f"{'pred us':>7} {'alt cm':>6} {'pos cm':>6} {'leg s':>5} {'end cm':>6} "
        f"{'x real':>6} {'vs IRIS':>7}"
    )
    for firmware in firmwares:
        iris = [f for f in flights if f.firmware == firmware and f.vehicle == "iris"]
        iris_speed = statistics.median(f.sim_s / f.wall_s for f in iris) if iris else math.nan
        for vehicle in vehicles:
            mine = [f for f in flights if f.firmware == firmware and f.vehicle == vehicle]
            speed = statistics.median(f.sim_s / f.wall_s for f in mine)

            def med(name: str, scale: float = 1.0, mine: list[Flight] = mine) -> float:
                return statistics.median(getattr(f, name) for f in mine) * scale

            print(
                f"{firmware:20} {vehicle:16} {med('rise_s'):6.2f} {med('overshoot_pct'):6.1f} "
                f"{med('hold_us'):7.0f} {med('predicted_us'):7.0f} "
                f"{med('height_rms_m', 100):6.1f} {med('position_rms_m', 100):6.1f} "
                f"{med('leg_s'):5.1f} {med('leg_end_m', 100):6.1f} {speed:6.1f} "
                f"{speed / iris_speed:7.2f}"
            )
    print(f"\nmedians of {args.seeds} seeds; wind 2.5 m/s from 60 deg, gusts 0.5 m/s")


if __name__ == "__main__":
    main()
