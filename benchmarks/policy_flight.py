"""A trained policy flown outside its training: the loop rate it keeps, its inference time and
how close it holds its target, on each way bfsitl reaches a flight controller.

For each ``--policy`` (a file, or a shipped name: ``hover-iris``), in one run on this machine,
the same flight: the autopilot takes off to 1.5 m, the policy has every stick for
``--seconds`` flying to 1 m north of the take-off point at 1.5 m, the autopilot lands.  On

* **lockstep**: the GPS lockstep SITL, as in training (``bfsitl fly --policy``);
* **real time**: the stock GPS SITL on the wall clock, RC over UDP at 100 Hz;
* **board**: the same SITL reached the way a board is, through a serial pseudo-terminal with
  RC by MSP (``bfsitl.connect``, 25 frames a second), the vehicle without any truth.

The simulated truth, which the policy never sees, judges it: the RMS and largest distance
from the target over the last 5 s.  The rate kept is steps per second of the vehicle's clock
over the policy's time; inference is onnxruntime's call, one thread.

What limits it: a policy trained in lockstep meets latency outside it (the RC rate, the FC's
RC smoothing, the barometer's lag on a SITL in real time); ``--latency-steps`` in
``examples/train_hover.py`` trains for it (docs/gym.md).  Run:
``python benchmarks/policy_flight.py --policy hover-iris [--policy other.onnx] [--seconds 10]
[--repeats 3]``.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from contextlib import ExitStack
from pathlib import Path

from bfsitl import (
    FcSetup,
    FlightSession,
    SessionConfig,
    SitlLaunch,
    Timing,
    World,
    connect,
    launch_sitl,
)
from bfsitl.bridges.pty_relay import PtyRelay
from bfsitl.cli.bridge_commands import sitl_upstream
from bfsitl.cli.fly_command import policy_path
from bfsitl.control import make_controller
from bfsitl.gym.policy_pilot import PolicyPilot, PolicyReport
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.phase import Phase
from bfsitl.mission.session import FLY_PROFILE, with_fast_serial
from bfsitl.mission.vehicle import Vehicle

TARGET = (1.0, 0.0, 1.5)
WAYS = ("lockstep", "real time", "board")


def fly(way: str, policy: Path, seconds: float, work: Path) -> tuple[PolicyReport, float, float]:
    """One flight; its report, and the truth's RMS and largest distance over the last 5 s."""
    truth: list[tuple[float, float]] = []  # (time, distance) from the simulator
    vehicle: Vehicle
    with ExitStack() as stack:
        if way == "board":
            config = SessionConfig(
                sitl=SitlLaunch(firmware="4.6.0-gps", workdir=work / "run"),
                timing=Timing(speed=1.0),
                world=World(seed=5),
                fc=FcSetup(profile=with_fast_serial(FLY_PROFILE), rc_link=False),
            )
            simulated = stack.enter_context(FlightSession(config))
            assert simulated.sitl is not None and simulated.sitl.client is not None
            simulated.sitl.client.close()  # UARTs serve one client: the relay takes it
            relay = PtyRelay(sitl_upstream(simulated.sitl), link_path=work / "ttyBF")
            stack.enter_context(relay.running())
            vehicle = stack.enter_context(connect(f"serial://{work / 'ttyBF'}?baud=115200"))
        else:
            firmware = "4.6.0-gps-lockstep" if way == "lockstep" else "4.6.0-gps"
            simulated = vehicle = stack.enter_context(launch_sitl(firmware, workdir=work / "run"))
        simulator = simulated.simulator
        assert simulator is not None
        pilot = PolicyPilot(vehicle, policy, TARGET)
        start_ned: list[tuple[float, float, float]] = []

        def watch(row: FlightRow, _sample: object) -> None:
            # The simulator's truth at each step: a board's own rows have none.
            north, east, down = simulator.state.position_ned_m
            if not start_ned:
                start_ned.append((north, east, down))
            if row.phase == Phase.POLICY:
                north0, east0, down0 = start_ned[0]
                where = (north - north0, east - east0, down0 - down)
                truth.append((row.time_s, math.dist(where, TARGET)))

        assert pilot.rate_hz is not None
        loop = FlightLoop(
            vehicle,
            make_controller("fused", quad=vehicle.quad),
            rate_hz=pilot.rate_hz,
            on_row=watch,
        )
        loop.arm()
        loop.wait_on_ground(2.0)
        loop.takeoff(TARGET[2], hold_position=True)
        loop.fly_sticks(seconds, pilot)
        loop.land()
        report = pilot.report(loop.rows)
    last = [d for t, d in truth if t >= truth[-1][0] - 5.0]
    rms = math.sqrt(sum(d * d for d in last) / len(last)) if last else math.nan
    return report, rms, max(last, default=math.nan)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--policy", action="append", default=None, metavar="FILE|NAME")
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--ways", nargs="+", choices=WAYS, default=list(WAYS))
    parser.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="flights per policy and way (on the wall clock no two are the same)",
    )
    args = parser.parse_args()
    policies = [policy_path(p) for p in (args.policy or ["hover-iris"])]
    print(
        "| policy | flown | rate kept (asked) | inference median / p99 | truth from the "
        "target, last 5 s: RMS / max | the FC's view: RMS |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: |")
    for policy in policies:
        for way in args.ways:
            for _ in range(args.repeats):
                with tempfile.TemporaryDirectory(prefix="bfsitl-policy-") as work:
                    report, rms, largest = fly(way, policy, args.seconds, Path(work))
                print(
                    f"| {policy.name} | {way} | {report.rate_hz_kept:.1f} Hz "
                    f"({report.rate_hz_asked:g}) | {report.inference_us_median:.0f} / "
                    f"{report.inference_us_p99:.0f} us | {rms * 100:.0f} / "
                    f"{largest * 100:.0f} cm | {report.fc_distance_rms_m * 100:.0f} cm |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
