"""The command line of ``bfsitl fly``: its options, groups and help (the command itself is
:mod:`bfsitl.cli.fly_command`)."""

from __future__ import annotations

import argparse

from bfsitl.cli.arg_types import (
    add_vehicle_argument,
    north_east_up,
    number_in,
    parse_speed,
    port_number,
    rc_rate,
)
from bfsitl.cli.fly_command import cmd_fly
from bfsitl.physics.wind import MAX_GUST_STD_M_S, MAX_WIND_COMPONENT_M_S
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ

#: The Configurator's built-in "Betaflight SITL" connection and Foxglove's default port.
CONFIGURATOR_PORT = 6761
FOXGLOVE_PORT = 8765
#: Checked when the command line is read (the mission runner's own limits for the rate).
RATE_HZ = number_in(1, 200, "Hz")
ALTITUDE_M = number_in(0, 500, "m", above_low=True)
DURATION_S = number_in(0, 24 * 3600, "s")
WIND_M_S = number_in(0, MAX_WIND_COMPONENT_M_S, "m/s")
GUST_STD_M_S = number_in(0, MAX_GUST_STD_M_S, "m/s")


def add_fly_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from bfsitl.control import CONTROLLERS, DEFAULT_CONTROLLER
    from bfsitl.mission.plan import MissionPlan

    fly = sub.add_parser(
        "fly",
        help="fly an autonomous mission on a SITL with the embedded physics",
        description="Start an isolated SITL with the embedded physics, provision it (ARM on "
        "AUX1, ANGLE on AUX2), arm, take off to --target-alt, hold for --hold "
        "seconds, land and disarm. Exit code 0 only if it landed.",
        epilog="Examples:\n"
        "  bfsitl fly --plot flight.png --summary flight.json\n"
        "  bfsitl fly --firmware 4.6.0-gps-lockstep --mission square --wind 3\n"
        "  bfsitl fly --controller tutorial-pid --gain kp=120 --log flight.csv\n"
        "  bfsitl fly --workdir ~/.cache/bfsitl/quad   (eeprom.bin kept between flights)\n"
        "  bfsitl fly --controller cascade --list-gains\n"
        "  bfsitl fly --firmware 4.6.0-gps-lockstep --policy hover-iris --policy-target 1,-1,2",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    mission = fly.add_argument_group("mission")
    mission.add_argument(
        "--mission",
        metavar="FILE.toml|NAME",
        help="fly a mission file: take-off altitude, [[waypoint]] tables "
        "(north_m, east_m, alt_m, optional hold_s and heading_deg), "
        "land = true (see docs/missions.md). Waypoints need a GPS "
        "build; they are flown at 100 Hz unless --rate says otherwise",
    )
    mission.add_argument(
        "--no-position-hold",
        action="store_true",
        help="on a GPS build, fly the altitude only (by default the take-off "
        "point is held in the take-off, the hold and the landing)",
    )
    mission.add_argument(
        "--target-alt",
        type=ALTITUDE_M,
        default=None,
        metavar="M",
        help="take-off altitude above the ground, metres (default 2.0)",
    )
    mission.add_argument(
        "--hold",
        type=DURATION_S,
        default=None,
        metavar="S",
        help="seconds to hold the altitude before landing (default 10)",
    )
    mission.add_argument(
        "--controller",
        choices=sorted(CONTROLLERS),
        default=DEFAULT_CONTROLLER,
        help=f"altitude controller (default {DEFAULT_CONTROLLER}: barometer + "
        "accelerometer; cascade: barometer only; tutorial-pid and "
        "open-loop re-create the tutorial's scripts)",
    )
    mission.add_argument(
        "--ground",
        type=DURATION_S,
        default=None,
        metavar="S",
        help="seconds armed at idle before the take-off, while the FC's "
        "altitude settles and the fused controller learns the "
        f"barometer's zero (default {MissionPlan().ground_s:g})",
    )
    mission.add_argument(
        "--gain",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="override a controller gain, repeatable (see --list-gains)",
    )
    mission.add_argument(
        "--list-gains",
        action="store_true",
        help="print the chosen controller's gains and defaults, then exit",
    )
    mission.add_argument(
        "--rate",
        type=RATE_HZ,
        default=None,
        metavar="HZ",
        help="control loop rate in simulation time (default 50, 100 for "
        "missions with waypoints; above 50 the FC's serial task is set "
        "to 1 kHz, which costs one reboot in a run directory that does "
        "not hold it yet)",
    )
    mission.add_argument(
        "--policy",
        metavar="FILE.onnx|NAME",
        help="let a trained policy fly the hold (an ONNX file of bfsitl.gym.policy_export, "
        "such as examples/train_hover.py's policy.onnx, or a shipped one: hover-iris, a "
        "hover of the IRIS trained in 5 minutes): arm, take off to --target-alt, "
        "every stick to the policy for --hold seconds from the FC's own readings, land "
        "where it left the vehicle. The loop runs at the policy's rate. Needs onnxruntime "
        "(pip install 'bfsitl[policy]'); see docs/gym.md",
    )
    mission.add_argument(
        "--policy-target",
        type=north_east_up,
        default=None,
        metavar="N,E,UP",
        help="where the policy flies to: metres north, east and up from the take-off "
        "point (default 0,0,--target-alt: hold the take-off point). North and east need "
        "a GPS build",
    )
    out = fly.add_argument_group("outputs")
    out.add_argument("--log", metavar="FILE.csv", help="one row per control step, flushed")
    out.add_argument("--plot", metavar="FILE.png", help="altitude, throttle and attitude plot")
    out.add_argument("--summary", metavar="FILE.json", help="outcome and metrics as JSON")
    out.add_argument("--json", action="store_true", help="print the summary as JSON")
    out.add_argument(
        "--mcap",
        metavar="FILE.mcap",
        help="record the flight for Foxglove: poses as transforms (3D panel), "
        "altitude, position, RC, motors, FC state, events; simulation time "
        "(needs the foxglove extra)",
    )
    watch = fly.add_argument_group("watching the flight")
    watch.add_argument(
        "--configurator",
        action="store_true",
        help="let the Betaflight Configurator watch the flight: MSP on UART2 "
        "(TCP 5762) too, relayed to a WebSocket on 127.0.0.1 "
        f"(--configurator-port, default {CONFIGURATOR_PORT}); a lockstep "
        "build then flies at 1x real time unless --speed says otherwise",
    )
    watch.add_argument(
        "--configurator-port",
        type=port_number,
        default=CONFIGURATOR_PORT,
        metavar="PORT",
        help=f"its WebSocket port (default {CONFIGURATOR_PORT}: "
        'the Configurator\'s "Betaflight SITL" entry)',
    )
    watch.add_argument(
        "--foxglove",
        action="store_true",
        help="serve the flight live to Foxglove (its SDK's WebSocket server on "
        f"127.0.0.1, --foxglove-port, default {FOXGLOVE_PORT}); lockstep "
        "flies at 1x real time unless --speed says otherwise",
    )
    watch.add_argument(
        "--foxglove-port",
        type=port_number,
        default=FOXGLOVE_PORT,
        metavar="PORT",
        help=f"the Foxglove server's port (default {FOXGLOVE_PORT})",
    )
    watch.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="also accept WebSocket clients from this web page origin "
        "(scheme://host[:port], repeatable; '*' for any). By default only "
        "the Configurator's and Foxglove's apps, pages on localhost or "
        "127.0.0.1, and clients without an Origin (scripts) are served",
    )
    watch.add_argument(
        "--no-attach",
        action="store_true",
        help="do not let `bfsitl top` attach. By default the FC serves MSP on UART2 (TCP "
        "5762) too and the flight is advertised in bfsitl's cache, so `bfsitl top` finds "
        "it; that costs one reboot (about 2 s on a stock SITL) in a run directory that "
        "does not hold it yet",
    )
    sitl = fly.add_argument_group("SITL and physics")
    sitl.add_argument(
        "--firmware",
        default=None,
        help="SITL binary or cached build name (`bfsitl firmware list`; default: "
        "$BFSITL_FIRMWARE, the betaflight package, PATH)",
    )
    sitl.add_argument(
        "--workdir",
        default=None,
        help="run directory; its eeprom.bin persists between flights "
        "(default: a fresh temporary directory)",
    )
    sitl.add_argument(
        "--no-isolate",
        action="store_true",
        help="run the SITL in the host network (ports shared with other SITLs)",
    )
    sitl.add_argument(
        "--speed",
        type=parse_speed,
        default=None,
        metavar="X|max",
        help="simulation speed x real time. Stock SITL: 0.05..4, default 1 (0.5 "
        "is the faithful speed on a busy 2-core machine). Lockstep build "
        "(`bfsitl firmware build --lockstep`): default max, any X paces it",
    )
    sitl.add_argument(
        "--lockstep",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="step the FC with the physics (default: when the firmware is a "
        "lockstep build; --no-lockstep flies one on the wall clock)",
    )
    sitl.add_argument(
        "--lockstep-exchange",
        choices=("auto", "shm", "udp"),
        default="auto",
        help="how lockstep packets pass: shared memory (shm, on builds made by "
        "this bfsitl, x86-64 Linux) or UDP; both fly the same flight "
        "(default auto: shm where it can)",
    )
    sitl.add_argument(
        "--rc-rate",
        type=rc_rate,
        default=DEFAULT_RC_RATE_HZ,
        metavar="HZ|packet",
        help="lockstep: the RC link's frame rate, as a real receiver's (16..1000; "
        "4.6.0 and master size RC smoothing and feedforward by it and lose the "
        "link when frames stop). 'packet': a frame in every fdm packet, and "
        "4.6.0's stock SITL receiver (default %(default)g, an ELRS link's)",
    )
    sitl.add_argument(
        "--baro-noise-pa",
        type=number_in(0, None, "Pa"),
        default=None,
        metavar="PA",
        help="barometer noise std of the embedded physics (default 0.5: dithers "
        "the SITL's whole-pascal pressure; 0 for a noiseless barometer)",
    )
    sitl.add_argument(
        "--accel-noise",
        type=number_in(0, None, "m/s^2"),
        default=None,
        metavar="M_S2",
        help="accelerometer noise std, m/s^2 (default 0.05: dithers the SITL's "
        "truncated acceleration; 0 for a noiseless accelerometer)",
    )
    add_vehicle_argument(sitl)
    sitl.add_argument(
        "--wind",
        type=WIND_M_S,
        default=0.0,
        metavar="M_S",
        help="steady horizontal wind of the embedded physics, m/s (default 0)",
    )
    sitl.add_argument(
        "--gusts",
        type=GUST_STD_M_S,
        default=0.0,
        metavar="M_S",
        help="gust standard deviation per axis, m/s (default 0; correlated over about 2 s)",
    )
    sitl.add_argument(
        "--wind-from",
        type=number_in(None, None, "deg"),
        default=0.0,
        metavar="DEG",
        help="where the wind blows from, degrees clockwise from north (default 0: from the north)",
    )
    sitl.add_argument(
        "--gps-noise",
        action="store_true",
        help="give the GPS a typical receiver's errors (0.15 m of wander per "
        "axis, 3 cm noise, 5 cm/s on the velocity; default: an exact GPS)",
    )
    sitl.add_argument(
        "--seed",
        type=int,
        default=0,
        metavar="N",
        help="seed of the sensor noise and the gusts (default 0)",
    )
    sitl.add_argument(
        "--physics",
        choices=("embedded", "gazebo"),
        default="embedded",
        help="embedded (default, nothing to install) or gazebo (needs `gz` of "
        "Gazebo Harmonic and libBetaflightPlugin.so; see docs/gazebo.md)",
    )
    sitl.add_argument(
        "--gz-plugin-dir",
        metavar="DIR",
        help="folder holding libBetaflightPlugin.so (default: $GZ_SIM_SYSTEM_PLUGIN_PATH)",
    )
    sitl.add_argument(
        "--world",
        metavar="FILE.sdf",
        help="with --physics gazebo: a world file of your own with the BetaflightPlugin "
        "(its model and names as in bfsitl's world, docs/gazebo.md; default: bfsitl's)",
    )
    sitl.add_argument(
        "--profile",
        metavar="FILE",
        help="extra CLI lines to provision (one per line, '#' comments)",
    )
    sitl.add_argument(
        "--no-provision",
        action="store_true",
        help="fly with the configuration the FC already holds",
    )
    sitl.add_argument(
        "--no-angle",
        action="store_true",
        help="do not provision or switch on ANGLE (self-levelling) on AUX2",
    )
    fly.set_defaults(func=cmd_fly)
