"""``bfsitl fly``: start a SITL with the embedded physics, fly a mission, land, report.

Progress goes to stderr: on a terminal one live line (phase, altitude vs target, throttle,
attitude, armed, blockers) between one-line events; otherwise the events only.  The summary
goes to stdout.  Exit code 0 only when the vehicle landed and disarmed.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path
from typing import TextIO

from bfsitl.cli.arg_types import number_in, port_number
from bfsitl.errors import BfsitlError
from bfsitl.physics.wind import MAX_GUST_STD_M_S, MAX_WIND_COMPONENT_M_S
from bfsitl.stop_signals import stop_signals_ignored

EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED = 0, 1, 130
DEFAULT_RATE_HZ = 50.0
#: Position control wants the faster loop (and gets the 1 kHz serial task with it).
POSITION_RATE_HZ = 100.0
#: Live-line redraws per second: readable, and cheap next to the 50 Hz control loop.
LIVE_REFRESH_HZ = 5.0
#: The Configurator's built-in "Betaflight SITL" connection and Foxglove's default port.
CONFIGURATOR_PORT = 6761
FOXGLOVE_PORT = 8765
#: Checked when the command line is read (the mission runner's own limits for the rate).
RATE_HZ = number_in(1, 200, "Hz")
ALTITUDE_M = number_in(0, 500, "m", above_low=True)
DURATION_S = number_in(0, 24 * 3600, "s")
WIND_M_S = number_in(0, MAX_WIND_COMPONENT_M_S, "m/s")
GUST_STD_M_S = number_in(0, MAX_GUST_STD_M_S, "m/s")



def parse_speed(text: str) -> float:
    """``--speed``: a positive number, or ``max`` (as fast as a lockstep build goes)."""
    if text.strip().lower() == "max":
        return math.inf
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or 'max'") from None
    if not (value > 0 and math.isfinite(value)):
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number or 'max'")
    return value

def add_fly_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    from bfsitl.control import CONTROLLERS, DEFAULT_CONTROLLER
    from bfsitl.mission.plan import MissionPlan

    fly = sub.add_parser(
        "fly", help="fly an autonomous mission on a SITL with the embedded physics",
        description="Start an isolated SITL with the embedded physics, provision it (ARM on "
                    "AUX1, ANGLE on AUX2), arm, take off to --target-alt, hold for --hold "
                    "seconds, land and disarm. Exit code 0 only if it landed.",
        epilog="Examples:\n"
               "  bfsitl fly --plot flight.png --summary flight.json\n"
               "  bfsitl fly --firmware 4.6.0-gps-lockstep --mission square --wind 3\n"
               "  bfsitl fly --controller tutorial-pid --gain kp=120 --log flight.csv\n"
               "  bfsitl fly --workdir ~/.cache/bfsitl/quad   (eeprom.bin kept between flights)\n"
               "  bfsitl fly --controller cascade --list-gains",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    mission = fly.add_argument_group("mission")
    mission.add_argument("--mission", metavar="FILE.toml|NAME",
                         help="fly a mission file: take-off altitude, [[waypoint]] tables "
                              "(north_m, east_m, alt_m, optional hold_s and heading_deg), "
                              "land = true (see docs/missions.md). Waypoints need a GPS "
                              "build; they are flown at 100 Hz unless --rate says otherwise")
    mission.add_argument("--no-position-hold", action="store_true",
                         help="on a GPS build, fly the altitude only (by default the take-off "
                              "point is held in the take-off, the hold and the landing)")
    mission.add_argument("--target-alt", type=ALTITUDE_M, default=None, metavar="M",
                         help="take-off altitude above the ground, metres (default 2.0)")
    mission.add_argument("--hold", type=DURATION_S, default=None, metavar="S",
                         help="seconds to hold the altitude before landing (default 10)")
    mission.add_argument("--controller", choices=sorted(CONTROLLERS),
                         default=DEFAULT_CONTROLLER,
                         help=f"altitude controller (default {DEFAULT_CONTROLLER}: barometer + "
                              "accelerometer; cascade: barometer only; tutorial-pid and "
                              "open-loop re-create the tutorial's scripts)")
    mission.add_argument("--ground", type=DURATION_S, default=None, metavar="S",
                         help="seconds armed at idle before the take-off, while the FC's "
                              "altitude settles and the fused controller learns the "
                              f"barometer's zero (default {MissionPlan().ground_s:g})")
    mission.add_argument("--gain", action="append", default=[], metavar="NAME=VALUE",
                         help="override a controller gain, repeatable (see --list-gains)")
    mission.add_argument("--list-gains", action="store_true",
                         help="print the chosen controller's gains and defaults, then exit")
    mission.add_argument("--rate", type=RATE_HZ, default=None, metavar="HZ",
                         help="control loop rate in simulation time (default 50, 100 for "
                              "missions with waypoints; above 50 the FC's serial task is set "
                              "to 1 kHz, which costs one reboot in a run directory that does "
                              "not hold it yet)")
    out = fly.add_argument_group("outputs")
    out.add_argument("--log", metavar="FILE.csv", help="one row per control step, flushed")
    out.add_argument("--plot", metavar="FILE.png", help="altitude, throttle and attitude plot")
    out.add_argument("--summary", metavar="FILE.json", help="outcome and metrics as JSON")
    out.add_argument("--json", action="store_true", help="print the summary as JSON")
    out.add_argument("--mcap", metavar="FILE.mcap",
                     help="record the flight for Foxglove: poses as transforms (3D panel), "
                          "altitude, position, RC, motors, FC state, events; simulation time "
                          "(needs the foxglove extra)")
    watch = fly.add_argument_group("watching the flight")
    watch.add_argument("--configurator", action="store_true",
                       help="let the Betaflight Configurator watch the flight: MSP on UART2 "
                            "(TCP 5762) too, relayed to a WebSocket on 127.0.0.1 "
                            f"(--configurator-port, default {CONFIGURATOR_PORT}); a lockstep "
                            "build then flies at 1x real time unless --speed says otherwise")
    watch.add_argument("--configurator-port", type=port_number, default=CONFIGURATOR_PORT,
                       metavar="PORT", help=f"its WebSocket port (default {CONFIGURATOR_PORT}: "
                                            "the Configurator's \"Betaflight SITL\" entry)")
    watch.add_argument("--foxglove", action="store_true",
                       help="serve the flight live to Foxglove (its SDK's WebSocket server on "
                            f"127.0.0.1, --foxglove-port, default {FOXGLOVE_PORT}); lockstep "
                            "flies at 1x real time unless --speed says otherwise")
    watch.add_argument("--foxglove-port", type=port_number, default=FOXGLOVE_PORT, metavar="PORT",
                       help=f"the Foxglove server's port (default {FOXGLOVE_PORT})")
    watch.add_argument("--allow-origin", action="append", default=[], metavar="ORIGIN",
                       help="also accept WebSocket clients from this web page origin "
                            "(scheme://host[:port], repeatable; '*' for any). By default only "
                            "the Configurator's and Foxglove's apps, pages on localhost or "
                            "127.0.0.1, and clients without an Origin (scripts) are served")
    sitl = fly.add_argument_group("SITL and physics")
    sitl.add_argument("--firmware", default=None,
                      help="SITL binary or cached build name (`bfsitl firmware list`; default: "
                           "$BFSITL_FIRMWARE, the betaflight package, PATH)")
    sitl.add_argument("--workdir", default=None,
                      help="run directory; its eeprom.bin persists between flights "
                           "(default: a fresh temporary directory)")
    sitl.add_argument("--no-isolate", action="store_true",
                      help="run the SITL in the host network (ports shared with other SITLs)")
    sitl.add_argument("--speed", type=parse_speed, default=None, metavar="X|max",
                      help="simulation speed x real time. Stock SITL: 0.05..4, default 1 (0.5 "
                           "is the faithful speed on a busy 2-core machine). Lockstep build "
                           "(`bfsitl firmware build --lockstep`): default max, any X paces it")
    sitl.add_argument("--lockstep", action=argparse.BooleanOptionalAction, default=None,
                      help="step the FC with the physics (default: when the firmware is a "
                           "lockstep build; --no-lockstep flies one on the wall clock)")
    sitl.add_argument("--lockstep-exchange", choices=("auto", "shm", "udp"), default="auto",
                      help="how lockstep packets pass: shared memory (shm, on builds made by "
                           "this bfsitl, x86-64 Linux) or UDP; both fly the same flight "
                           "(default auto: shm where it can)")
    sitl.add_argument("--baro-noise-pa", type=number_in(0, None, "Pa"), default=None, metavar="PA",
                      help="barometer noise std of the embedded physics (default 0.5: dithers "
                           "the SITL's whole-pascal pressure; 0 for a noiseless barometer)")
    sitl.add_argument("--accel-noise", type=number_in(0, None, "m/s^2"), default=None,
                      metavar="M_S2",
                      help="accelerometer noise std, m/s^2 (default 0.05: dithers the SITL's "
                           "truncated acceleration; 0 for a noiseless accelerometer)")
    sitl.add_argument("--wind", type=WIND_M_S, default=0.0, metavar="M_S",
                      help="steady horizontal wind of the embedded physics, m/s (default 0)")
    sitl.add_argument("--gusts", type=GUST_STD_M_S, default=0.0, metavar="M_S",
                      help="gust standard deviation per axis, m/s (default 0; correlated over "
                           "about 2 s)")
    sitl.add_argument("--wind-from", type=number_in(None, None, "deg"), default=0.0, metavar="DEG",
                      help="where the wind blows from, degrees clockwise from north "
                           "(default 0: from the north)")
    sitl.add_argument("--gps-noise", action="store_true",
                      help="give the GPS a typical receiver's errors (0.15 m of wander per "
                           "axis, 3 cm noise, 5 cm/s on the velocity; default: an exact GPS)")
    sitl.add_argument("--seed", type=int, default=0, metavar="N",
                      help="seed of the sensor noise and the gusts (default 0)")
    sitl.add_argument("--physics", choices=("embedded", "gazebo"), default="embedded",
                      help="embedded (default, nothing to install) or gazebo (needs `gz` of "
                           "Gazebo Harmonic and libBetaflightPlugin.so; see docs/gazebo.md)")
    sitl.add_argument("--gz-plugin-dir", metavar="DIR",
                      help="folder holding libBetaflightPlugin.so (default: "
                           "$GZ_SIM_SYSTEM_PLUGIN_PATH)")
    sitl.add_argument("--profile", metavar="FILE",
                      help="extra CLI lines to provision (one per line, '#' comments)")
    sitl.add_argument("--no-provision", action="store_true",
                      help="fly with the configuration the FC already holds")
    sitl.add_argument("--no-angle", action="store_true",
                      help="do not provision or switch on ANGLE (self-levelling) on AUX2")
    fly.set_defaults(func=cmd_fly)


def _plan_from_args(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """The mission file's plan, or the one --target-alt / --hold describe."""
    from dataclasses import replace

    from bfsitl.mission.plan import DEFAULT_HOLD_S, MissionPlan, load_mission

    if args.mission:
        given = [flag for flag, value in (("--target-alt", args.target_alt),
                                          ("--hold", args.hold)) if value is not None]
        if given:
            raise BfsitlError(f"{' and '.join(given)} cannot be combined with --mission: the "
                              f"mission file sets the take-off altitude and the holds")
        plan = load_mission(mission_path(args.mission))
    else:
        plan = MissionPlan(target_alt_m=2.0 if args.target_alt is None else args.target_alt,
                           hold_s=DEFAULT_HOLD_S if args.hold is None else args.hold)
    if args.ground is not None:
        plan = replace(plan, ground_s=args.ground)
    if args.no_position_hold:
        plan = replace(plan, hold_position=False)
    return plan


def mission_path(given: str) -> Path:
    """``--mission``: a file, or the name of a mission shipped with bfsitl (``square``)."""
    path = Path(given)
    if not path.exists():
        from bfsitl.library import find_mission

        shipped = find_mission(given)
        if shipped is not None:
            return shipped
    return path


def parse_gains(items: list[str]) -> dict[str, float]:
    gains: dict[str, float] = {}
    for item in items:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise BfsitlError(f"--gain {item!r}: expected NAME=VALUE, e.g. kp=120")
        try:
            gains[name.strip()] = float(value)
        except ValueError:
            raise BfsitlError(f"--gain {item!r}: {value!r} is not a number") from None
    return gains


class LiveProgress:
    """One redrawn status line on a terminal; plain event lines otherwise."""

    def __init__(self, stream: TextIO = sys.stderr, live: bool | None = None) -> None:
        self.stream = stream
        self.live = stream.isatty() if live is None else live
        self._last_draw_s = 0.0
        self._line_shown = False

    def event(self, message: str) -> None:
        if self._line_shown:
            self.stream.write("\r\x1b[K")
            self._line_shown = False
        self.stream.write(f"bfsitl: {message}\n")
        self.stream.flush()

    def row(self, row, sample) -> None:  # type: ignore[no-untyped-def]
        if not self.live:
            return
        now_s = time.monotonic()
        if now_s - self._last_draw_s < 1.0 / LIVE_REFRESH_HZ:
            return
        self._last_draw_s = now_s
        blockers = ",".join(sample.arming_blockers) or "-"
        line = (f"{row.phase:<8} t={row.time_s:6.1f}s alt {row.fc_alt_m:5.2f}/"
                f"{row.target_alt_m:4.2f} m (true {row.sim_alt_m:5.2f}) "
                f"thr {row.rc_throttle_us:4d} roll {row.roll_deg:5.1f} pitch "
                f"{row.pitch_deg:5.1f} {'ARMED' if row.armed else 'disarmed'} "
                f"blockers {blockers}")
        self.stream.write("\r\x1b[K" + line)
        self.stream.flush()
        self._line_shown = True


def process_age_s() -> float | None:
    """Seconds since this process started (interpreter start-up and imports included)."""
    try:
        fields = Path("/proc/self/stat").read_text().rsplit(")", 1)[1].split()
        started_ticks = int(fields[19])  # field 22 of proc(5), counted after "pid (comm)"
        uptime_s = float(Path("/proc/uptime").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return None
    return max(0.0, uptime_s - started_ticks / os.sysconf("SC_CLK_TCK"))


def cmd_fly(args: argparse.Namespace) -> int:
    from bfsitl.backend.options import Timing, World, fly_sensors
    from bfsitl.control import gain_names, make_controller
    from bfsitl.fc.provisioning import ARM_ON_AUX1, Profile
    from bfsitl.mission import FLY_PROFILE, FlightSession, SessionConfig
    from bfsitl.mission.plan_driver import fly
    from bfsitl.mission.results import Outcome
    from bfsitl.mission.session import ConfiguratorBridge, FcSetup, SitlLaunch
    from bfsitl.records.outputs import FlightOutputs, OutputOptions, plan_waypoints

    if args.list_gains:
        for name, default in gain_names(args.controller).items():
            print(f"{name} = {default:g}")
        return EXIT_OK
    controller = make_controller(args.controller, parse_gains(args.gain))
    plan = _plan_from_args(args)
    if args.rate is None:
        args.rate = POSITION_RATE_HZ if plan.needs_position else DEFAULT_RATE_HZ
    if args.no_provision:
        profile = None
    else:
        profile = FLY_PROFILE if not args.no_angle else Profile(mode_ranges=(ARM_ON_AUX1,))
        if args.profile:
            profile = Profile.from_file(args.profile, mode_ranges=profile.mode_ranges)
    wind = None
    if args.wind or args.gusts:
        from bfsitl.physics.wind import Wind

        wind = Wind.from_direction(args.wind, args.wind_from, args.gusts)
    live = LiveProgress()
    speed = args.speed
    if speed is None and (args.configurator or args.foxglove):
        speed = 1.0  # someone watches: a lockstep build would otherwise fly at full speed
    # The flags, flat on the command line, map onto the session's groups here.
    config = SessionConfig.for_autopilot(
        control_rate_hz=args.rate,
        sitl=SitlLaunch(firmware=args.firmware, workdir=args.workdir,
                        isolate=not args.no_isolate),
        timing=Timing(speed=speed, lockstep=args.lockstep,
                      lockstep_exchange=args.lockstep_exchange),
        fc=FcSetup(profile=profile, angle_mode=not args.no_angle),
        world=World(physics=args.physics, gz_plugin_dir=args.gz_plugin_dir, wind=wind,
                    seed=args.seed,
                    sensors=fly_sensors(baro_noise_std_pa=args.baro_noise_pa,
                                        accel_noise_std_m_s2=args.accel_noise,
                                        gps_noise=args.gps_noise)),
        configurator=(ConfiguratorBridge(port=args.configurator_port,
                                         allow_origins=tuple(args.allow_origin))
                      if args.configurator else None))
    outputs = FlightOutputs(OutputOptions(
        csv_path=args.log, plot_path=args.plot, summary_path=args.summary,
        mcap_path=args.mcap, foxglove_port=args.foxglove_port if args.foxglove else None,
        allow_origins=tuple(args.allow_origin), waypoints=plan_waypoints(plan),
    ), progress=live.event)

    def on_row(row, sample) -> None:  # type: ignore[no-untyped-def]
        outputs.on_row(row, sample)
        live.row(row, sample)

    def on_event(text: str) -> None:
        outputs.on_event(text)
        live.event(text)

    startup_s = process_age_s()  # the command's own start-up, before the session's clock
    session = FlightSession(config, progress=live.event)
    try:
        try:
            outputs.start()
            session.start()
            result = fly(session, plan, controller, on_row=on_row,
                         on_event=on_event, rate_hz=args.rate)
        except KeyboardInterrupt:
            result = None
    finally:
        # A second Ctrl-C must not leave a SITL or a half-written file.
        with stop_signals_ignored():
            try:
                session.close()
            finally:
                outputs.close()
    if result is None:
        live.event("interrupted before the flight started; everything stopped")
        return EXIT_INTERRUPTED
    if startup_s is not None and result.armed_after_s is not None:
        result.extra["command_to_armed_s"] = startup_s + result.armed_after_s
    live.event(f"outcome: {result.outcome.value} ({result.reason})")
    summary = result.summary()
    written = outputs.finish(result, summary)
    if args.json:
        print(json.dumps(summary))
    else:
        print(render_summary(summary))
    if written:
        live.event("wrote " + ", ".join(written))
    if result.outcome is Outcome.INTERRUPTED:
        return EXIT_INTERRUPTED
    return EXIT_OK if result.succeeded else EXIT_FAILED


def render_summary(summary: dict) -> str:
    lines = [f"outcome        {summary['outcome']}: {summary['reason']}",
             f"controller     {summary['controller']}"]
    if summary.get("blockers"):
        lines.append(f"blockers       {', '.join(summary['blockers'])}")
    if summary.get("command_to_armed_s") is not None:
        lines.append(f"armed after    {summary['command_to_armed_s']:.1f} s (wall time from the "
                     f"command)")
    elif summary.get("armed_after_s") is not None:
        lines.append(f"armed after    {summary['armed_after_s']:.1f} s (wall time from start)")
    step = summary.get("step_response")
    if step:
        lines.append(
            "take-off       " + ", ".join(
                f"{key} {value:.3f}" for key, value in step.items()
                if isinstance(value, (int, float))))
    hold = summary.get("hold")
    if hold:
        lines.append(f"hold           RMS {hold['rms_error_m'] * 100:.1f} cm, max "
                     f"{hold['max_abs_error_m'] * 100:.1f} cm, mean "
                     f"{hold['mean_error_m'] * 100:+.1f} cm (simulated truth vs target)")
    attitude = summary.get("attitude")
    if attitude:
        lines.append(f"attitude       FC vs truth in the air: roll RMS "
                     f"{attitude['roll_rms_error_deg']:.2f} deg, pitch RMS "
                     f"{attitude['pitch_rms_error_deg']:.2f} deg, max "
                     f"{attitude['max_abs_error_deg']:.2f} deg (true tilt up to "
                     f"{attitude['max_true_tilt_deg']:.1f} deg)")
    for leg in summary.get("waypoints") or ():
        lines.append(f"waypoint {leg['waypoint']:<5} reached after {leg['took_s']:.1f} s, "
                     f"{leg['arrival_error_m'] * 100:.0f} cm off (height "
                     f"{leg['arrival_alt_error_m'] * 100:+.0f} cm), cross-track RMS "
                     f"{leg['cross_track_rms_m'] * 100:.0f} cm, max "
                     f"{leg['cross_track_max_m'] * 100:.0f} cm")
    if summary.get("cross_track_rms_m") is not None:
        lines.append(f"cross-track    RMS {summary['cross_track_rms_m'] * 100:.0f} cm over all "
                     f"legs (simulated truth vs the straight lines)")
    if summary.get("landed_from_start_m") is not None:
        lines.append(f"landed         {summary['landed_from_start_m'] * 100:.0f} cm from the "
                     f"take-off point")
    firmware = summary.get("firmware")
    if firmware:
        lines.append(f"firmware       {firmware['version']} (MSP API {firmware['api']}, "
                     f"{firmware['conventions']} conventions"
                     + (", GPS" if firmware["gps"] else "") + ")")
    rc = summary.get("rc_link")
    if rc:
        lines.append(f"RC link        {rc['packets']} packets, period mean "
                     f"{rc['period_mean_ms']:.2f} ms, max {rc['period_max_ms']:.2f} ms")
    physics = summary.get("physics")
    if physics:
        mode = ""
        if physics.get("lockstep"):
            through = {"shm": "shared memory", "udp": "UDP"}.get(physics.get("exchange"), "")
            mode = f"lockstep through {through}, " if through else "lockstep, "
        lines.append(f"physics        {mode}{physics['answered_ratio'] * 100:.1f} % of fdm "
                     f"packets answered at {physics['speed']:.2f}x real time")
    if "findings" in summary:
        findings = summary["findings"]
        watched = len((summary.get("analysers") or {}).get("watched") or ())
        if not findings:
            lines.append(f"findings       none ({watched} analysers watched)")
        for index, finding in enumerate(findings):
            head = "findings       " if index == 0 else " " * 15
            lines.append(f"{head}{finding['severity']:<8} {finding['analyser']}: "
                         f"{finding['summary']} (t={finding['time_s']:.2f} s)")
    return "\n".join(lines)
