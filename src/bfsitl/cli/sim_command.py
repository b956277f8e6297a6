"""``bfsitl sim``: the embedded physics against a SITL, with live health figures."""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from collections.abc import Iterator

from bfsitl.cli.arg_types import add_vehicle_argument, number_in, port_number
from bfsitl.cli.bridge_commands import add_allow_origin_argument
from bfsitl.cli.target import add_target_arguments, progress
from bfsitl.fc.msp_client import MspClient
from bfsitl.link import DEFAULT_SITL_URI, open_link
from bfsitl.sim.bridge import DEFAULT_STEP_S, SitlBridge, bridged_sitl, wait_for_replies
from bfsitl.sim.health import HealthMonitor, HealthSample, lock_clock
from bfsitl.sitl.network import HostNetwork
from bfsitl.sitl.process import SitlProcess

#: Wall seconds between two printed samples.
REPORT_INTERVAL_S = 1.0


def add_sim_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    sim = sub.add_parser(
        "sim",
        help="run the embedded physics against a SITL, with health figures",
        description="Feed the SITL simulated sensors (fdm packets on UDP 9003) and fly the "
        "simulated quad with its motor commands (UDP 9002). The firmware's clock is "
        "kept equal to simulated time. Prints state and health once a second; "
        "with --json one JSON object per second (fc_clock_ratio, fc_cycle_us, "
        "answered_ratio, speed, ...).",
    )
    add_target_arguments(sim, start_flag=False)
    sim.add_argument(
        "--attach",
        action="store_true",
        help="use a SITL already running in the host network (at --uri) instead of starting one",
    )
    sim.add_argument(
        "--speed",
        type=number_in(0.01, 100, "x real time"),
        default=1.0,
        metavar="S",
        help="simulated seconds per wall second (default 1.0, real time; "
        "below 1 for slow machines; benchmarks/physics.py finds the fastest "
        "faithful speed)",
    )
    sim.add_argument(
        "--duration",
        type=number_in(0, None, "s", above_low=True),
        default=None,
        metavar="S",
        help="stop after S simulated seconds (default: until Ctrl-C)",
    )
    sim.add_argument(
        "--step-ms",
        type=number_in(0.1, 20, "ms"),
        default=DEFAULT_STEP_S * 1000,
        metavar="MS",
        help="physics step and fdm packet interval (default 1 ms, as Gazebo)",
    )
    sim.add_argument(
        "--timestamps",
        choices=("frozen", "sim"),
        default="frozen",
        help="fdm timestamps: 'frozen' keeps the firmware clock at sim time "
        "(default); 'sim' sends sim time like Gazebo (the clock drifts)",
    )
    sim.add_argument("--json", action="store_true", help="one JSON object per second")
    add_vehicle_argument(sim)
    sim.add_argument(
        "--configurator",
        action="store_true",
        help="let the Betaflight Configurator watch: MSP on UART2 (TCP 5762) too "
        "(one reboot the first time), relayed to a WebSocket on 127.0.0.1 at "
        "--configurator-port (default 6761); not with --attach",
    )
    sim.add_argument(
        "--configurator-port",
        type=port_number,
        default=6761,
        metavar="PORT",
        help='its WebSocket port (default 6761: the Configurator\'s "Betaflight SITL" entry)',
    )
    add_allow_origin_argument(sim)
    sim.set_defaults(func=cmd_sim)


@contextlib.contextmanager
def _sitl_and_bridge(args: argparse.Namespace) -> Iterator[tuple[SitlBridge, MspClient]]:
    from bfsitl.physics import Simulator  # the physics loads only for this command

    simulator = Simulator(args.vehicle)
    step_s = args.step_ms / 1000.0
    if args.attach:
        bridge = SitlBridge(
            simulator, HostNetwork(), speed=args.speed, step_s=step_s, timestamps=args.timestamps
        )
        bridge.bind()
        link = open_link(args.uri or DEFAULT_SITL_URI, timeout_s=args.timeout)
        with MspClient(link, timeout_s=args.timeout) as client:
            try:
                bridge.start()
                wait_for_replies(bridge)
                yield bridge, client
            finally:
                bridge.close()
        return
    if args.uri:
        raise SystemExit("bfsitl sim: --uri needs --attach (otherwise a SITL is started)")
    sitl = SitlProcess(
        args.firmware, workdir=args.workdir, isolate=not args.no_isolate, progress=progress
    )
    with (
        bridged_sitl(
            sitl, simulator, speed=args.speed, step_s=step_s, timestamps=args.timestamps
        ) as bridge,
        contextlib.ExitStack() as stack,
    ):
        if args.configurator:
            _serve_configurator(sitl, bridge, args, stack)
        assert sitl.client is not None
        yield bridge, sitl.client


def _serve_configurator(
    sitl: SitlProcess, bridge: SitlBridge, args: argparse.Namespace, stack: contextlib.ExitStack
) -> None:
    """MSP on UART2 as well (a reboot the first time), and the WebSocket bridge to it."""
    from bfsitl.bridges import Upstream
    from bfsitl.bridges.origin_policy import OriginPolicy
    from bfsitl.bridges.websocket_relay import WebSocketRelay, connect_hint
    from bfsitl.fc.provisioning import Profile, provision
    from bfsitl.mission.session import SECOND_MSP_PORT
    from bfsitl.sitl.process import SITL_HOST

    def reboot() -> None:
        assert sitl.client is not None
        progress("MSP on UART2 needs a reboot; restarting the SITL")
        bridge.pause()
        sitl.client.reboot()
        sitl.restart_after_reboot()
        bridge.resume()
        wait_for_replies(bridge)

    assert sitl.client is not None and sitl.network is not None
    provision(
        sitl.client,
        Profile(mode_ranges=(), cli_lines=sitl.profile.second_msp_cli, reboot_when_changed=True),
        reboot=reboot,
    )
    relay = WebSocketRelay(
        Upstream(SITL_HOST, SECOND_MSP_PORT, socket_factory=sitl.network.socket),
        port=args.configurator_port,
        origins=OriginPolicy.with_extra(args.allow_origin),
        on_event=lambda line: progress(f"configurator: {line}"),
        port_option="--configurator-port",
    )
    url = stack.enter_context(relay.running())
    progress(
        f"the Configurator can watch at {url} (MSP on UART2, TCP {SECOND_MSP_PORT}); "
        f"{connect_hint(url)}"
    )


def _human_line(sample: HealthSample, bridge: SitlBridge) -> str:
    simulator = bridge.simulator
    altitude_m = getattr(simulator, "altitude_m", float("nan"))
    motors = " ".join(f"{m:.3f}" for m in bridge.motors)
    ratio = "  -  " if sample.fc_clock_ratio is None else f"{sample.fc_clock_ratio:.3f}"
    return (
        f"t={sample.sim_time_s:7.2f}s speed={sample.speed:.3f} alt={altitude_m:6.2f}m "
        f"motors=[{motors}] | fc_clock={ratio} cycle={sample.fc_cycle_us:.0f}us "
        f"answered={sample.answered_ratio * 100:.1f}% {'ok' if sample.faithful else 'CHECK'}"
    )


def cmd_sim(args: argparse.Namespace) -> int:
    with _sitl_and_bridge(args) as (bridge, client):
        monitor = HealthMonitor(bridge, client)
        if args.speed != 1.0 and args.timestamps == "frozen":
            progress(f"locking the firmware clock to {args.speed}x (a few seconds)")
            lock_clock(monitor)
        monitor.reset()
        started_sim_s = bridge.sim_time_s
        next_report_s = time.monotonic() + REPORT_INTERVAL_S
        while args.duration is None or bridge.sim_time_s - started_sim_s < args.duration:
            if bridge.error is not None:
                raise bridge.error
            time.sleep(max(0.0, min(0.05, next_report_s - time.monotonic())))
            if time.monotonic() < next_report_s:
                continue
            next_report_s += REPORT_INTERVAL_S
            sample = monitor.sample()
            if args.json:
                print(json.dumps(sample.as_dict()), flush=True)
            else:
                print(_human_line(sample, bridge), flush=True)
        stats = bridge.stats()
    progress(
        f"simulated {stats.sim_time_s:.1f} s in {stats.wall_time_s:.1f} s, "
        f"{stats.answered_ratio * 100:.1f} % of {stats.fdm_sent} fdm packets answered"
    )
    return 0
