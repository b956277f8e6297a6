"""``bfsitl fly``: start a SITL with the embedded physics, fly a mission, land, report.

Progress goes to stderr: on a terminal one live line (phase, altitude vs target, throttle,
attitude, armed, blockers) between one-line events; otherwise the events only.  The summary
goes to stdout.  Exit code 0 only when the vehicle landed and disarmed.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import TextIO

from bfsitl.errors import BfsitlError
from bfsitl.stop_signals import stop_signals_ignored

EXIT_OK, EXIT_FAILED, EXIT_INTERRUPTED = 0, 1, 130
DEFAULT_RATE_HZ = 50.0
#: Position control wants the faster loop (and gets the 1 kHz serial task with it).
POSITION_RATE_HZ = 100.0
#: Live-line redraws per second: readable, and cheap next to the 50 Hz control loop.
LIVE_REFRESH_HZ = 5.0


def _plan_from_args(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """The mission file's plan, or the one --target-alt / --hold describe."""
    from dataclasses import replace

    from bfsitl.mission.plan import DEFAULT_HOLD_S, MissionPlan, load_mission

    if args.mission:
        given = [
            flag
            for flag, value in (("--target-alt", args.target_alt), ("--hold", args.hold))
            if value is not None
        ]
        if given:
            raise BfsitlError(
                f"{' and '.join(given)} cannot be combined with --mission: the "
                f"mission file sets the take-off altitude and the holds"
            )
        plan = load_mission(mission_path(args.mission))
    else:
        plan = MissionPlan(
            target_alt_m=2.0 if args.target_alt is None else args.target_alt,
            hold_s=DEFAULT_HOLD_S if args.hold is None else args.hold,
        )
    if args.ground is not None:
        plan = replace(plan, ground_s=args.ground)
    if args.no_position_hold:
        plan = replace(plan, hold_position=False)
    return plan


def _policy_from_args(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    """``--policy``'s file, loaded and checked before anything starts (None without one);
    the loop's rate becomes the policy's."""
    if args.policy is None:
        if args.policy_target is not None:
            raise BfsitlError("--policy-target is where --policy flies to: give --policy FILE")
        return None
    from bfsitl.gym.onnx_policy import OnnxPolicy

    if args.mission:
        raise BfsitlError(
            "--policy flies the hold of --target-alt and --hold; it cannot be combined "
            "with --mission"
        )
    policy = OnnxPolicy(policy_path(args.policy))
    if args.rate is not None and not math.isclose(args.rate, policy.control_hz):
        raise BfsitlError(
            f"--rate {args.rate:g}: {args.policy} was trained at {policy.control_hz:g} Hz "
            f"and is flown at that rate (leave --rate out)"
        )
    if policy.mode == "angle" and args.no_angle:
        raise BfsitlError(
            f"--no-angle: {args.policy} was trained in ANGLE mode, which it switches on AUX2"
        )
    args.rate = policy.control_hz
    return policy


def _policy_pilot(session, policy, target, plan, say):  # type: ignore[no-untyped-def]
    from bfsitl.gym.policy_pilot import PolicyPilot

    north, east, up = target if target is not None else (0.0, 0.0, plan.target_alt_m)
    if not session.has_gps:
        say(
            "this firmware has no GPS: the policy sees no horizontal position (those "
            "observation slots are 0), so nothing holds it over the ground; fly a GPS build "
            "(`bfsitl firmware build --gps --lockstep`)"
        )
    if not session.lockstep:
        say(
            "this SITL runs in real time: its UDP receiver counts a frame at every check, "
            "which starves the FC's barometer and altitude tasks (the altitude lags twice as "
            "long as in lockstep or on a board), and a policy holds less well; docs/gym.md "
            "has the figures"
        )
    say(
        f"{policy.path.name}: trained at {policy.control_hz:g} Hz in {policy.mode.upper()}, "
        f"flies to {north:+.1f} m N {east:+.1f} m E {up:.1f} m up"
    )
    return PolicyPilot(session, policy, (north, east, up))


def _report_policy(result, pilot) -> None:  # type: ignore[no-untyped-def]
    """The policy's figures in the result's extras (nothing when it never flew)."""
    from bfsitl.errors import MissionError

    try:
        report = pilot.report(result.rows)
    except MissionError:
        return
    result.extra["policy"] = {"file": str(pilot.policy.path), **dataclasses.asdict(report)}


def policy_path(given: str) -> Path:
    """``--policy``: a file, or the name of a policy shipped with bfsitl (``hover-iris``)."""
    from bfsitl.library import find_policy

    return _file_or_shipped(given, find_policy)


def mission_path(given: str) -> Path:
    """``--mission``: a file, or the name of a mission shipped with bfsitl (``square``)."""
    from bfsitl.library import find_mission

    return _file_or_shipped(given, find_mission)


def _file_or_shipped(given: str, find_shipped: Callable[[str], Path | None]) -> Path:
    """``given`` when such a file exists, else the shipped one of that name, if any."""
    path = Path(given)
    if not path.exists():
        shipped = find_shipped(given)
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
        line = (
            f"{row.phase:<8} t={row.time_s:6.1f}s alt {row.fc_alt_m:5.2f}/"
            f"{row.target_alt_m:4.2f} m (true {row.sim_alt_m:5.2f}) "
            f"thr {row.rc_throttle_us:4d} roll {row.roll_deg:5.1f} pitch "
            f"{row.pitch_deg:5.1f} {'ARMED' if row.armed else 'disarmed'} "
            f"blockers {blockers}"
        )
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
    from bfsitl.mission.session import (
        ConfiguratorBridge,
        FcSetup,
        SitlLaunch,
        with_fast_serial,
    )
    from bfsitl.records.outputs import FlightOutputs, OutputOptions, plan_waypoints

    if args.list_gains:
        for name, default in gain_names(args.controller).items():
            print(f"{name} = {default:g}")
        return EXIT_OK
    if args.world is not None and args.physics != "gazebo":
        raise BfsitlError("--world is a Gazebo world file: give --physics gazebo with it")
    if args.physics == "gazebo" and args.vehicle.name != "iris":
        raise BfsitlError(
            "--vehicle is the embedded physics' quad; Gazebo flies its world's own model"
        )
    controller = make_controller(args.controller, parse_gains(args.gain), quad=args.vehicle)
    plan = _plan_from_args(args)
    policy = _policy_from_args(args)
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
        sitl=SitlLaunch(firmware=args.firmware, workdir=args.workdir, isolate=not args.no_isolate),
        timing=Timing(
            speed=speed, lockstep=args.lockstep, lockstep_exchange=args.lockstep_exchange
        ),
        fc=FcSetup(
            profile=profile,
            angle_mode=not args.no_angle,
            attachable=profile is not None and not args.no_attach,
            rc_rate_hz=args.rc_rate,
        ),
        world=World(
            physics=args.physics,
            gz_plugin_dir=args.gz_plugin_dir,
            gz_world=args.world,
            quad=args.vehicle,
            wind=wind,
            seed=args.seed,
            sensors=fly_sensors(
                baro_noise_std_pa=args.baro_noise_pa,
                accel_noise_std_m_s2=args.accel_noise,
                gps_noise=args.gps_noise,
            ),
        ),
        configurator=(
            ConfiguratorBridge(port=args.configurator_port, allow_origins=tuple(args.allow_origin))
            if args.configurator
            else None
        ),
    )
    if policy is not None and config.fc.profile is not None:
        # A policy is flown at its training rate or not at all: the serial task at 1 kHz
        # keeps the MSP round trip well inside its period on a SITL in real time too.
        config = dataclasses.replace(
            config, fc=dataclasses.replace(config.fc, profile=with_fast_serial(config.fc.profile))
        )
    outputs = FlightOutputs(
        OutputOptions(
            csv_path=args.log,
            plot_path=args.plot,
            summary_path=args.summary,
            mcap_path=args.mcap,
            foxglove_port=args.foxglove_port if args.foxglove else None,
            allow_origins=tuple(args.allow_origin),
            waypoints=plan_waypoints(plan),
        ),
        progress=live.event,
    )

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
            pilot = None
            if policy is not None:
                pilot = _policy_pilot(session, policy, args.policy_target, plan, live.event)
            result = fly(
                session,
                plan,
                controller,
                on_row=on_row,
                on_event=on_event,
                rate_hz=args.rate,
                pilot=pilot,
            )
            if pilot is not None:
                _report_policy(result, pilot)
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
    lines = [
        f"outcome        {summary['outcome']}: {summary['reason']}",
        f"controller     {summary['controller']}",
    ]
    if summary.get("blockers"):
        lines.append(f"blockers       {', '.join(summary['blockers'])}")
    if summary.get("command_to_armed_s") is not None:
        lines.append(
            f"armed after    {summary['command_to_armed_s']:.1f} s (wall time from the command)"
        )
    elif summary.get("armed_after_s") is not None:
        lines.append(f"armed after    {summary['armed_after_s']:.1f} s (wall time from start)")
    step = summary.get("step_response")
    if step:
        lines.append(
            "take-off       "
            + ", ".join(
                f"{key} {value:.3f}"
                for key, value in step.items()
                if isinstance(value, (int, float))
            )
        )
    hold = summary.get("hold")
    if hold:
        lines.append(
            f"hold           RMS {hold['rms_error_m'] * 100:.1f} cm, max "
            f"{hold['max_abs_error_m'] * 100:.1f} cm, mean "
            f"{hold['mean_error_m'] * 100:+.1f} cm (simulated truth vs target)"
        )
    attitude = summary.get("attitude")
    if attitude:
        lines.append(
            f"attitude       FC vs truth in the air: roll RMS "
            f"{attitude['roll_rms_error_deg']:.2f} deg, pitch RMS "
            f"{attitude['pitch_rms_error_deg']:.2f} deg, max "
            f"{attitude['max_abs_error_deg']:.2f} deg (true tilt up to "
            f"{attitude['max_true_tilt_deg']:.1f} deg)"
        )
    for leg in summary.get("waypoints") or ():
        lines.append(
            f"waypoint {leg['waypoint']:<5} reached after {leg['took_s']:.1f} s, "
            f"{leg['arrival_error_m'] * 100:.0f} cm off (height "
            f"{leg['arrival_alt_error_m'] * 100:+.0f} cm), cross-track RMS "
            f"{leg['cross_track_rms_m'] * 100:.0f} cm, max "
            f"{leg['cross_track_max_m'] * 100:.0f} cm"
        )
    if summary.get("cross_track_rms_m") is not None:
        lines.append(
            f"cross-track    RMS {summary['cross_track_rms_m'] * 100:.0f} cm over all "
            f"legs (simulated truth vs the straight lines)"
        )
    if summary.get("landed_from_start_m") is not None:
        lines.append(
            f"landed         {summary['landed_from_start_m'] * 100:.0f} cm from the take-off point"
        )
    policy = summary.get("policy")
    if policy:
        true_cm = (
            f"{policy['true_distance_rms_m'] * 100:.0f} cm RMS (truth), "
            if policy.get("true_distance_rms_m") is not None
            else ""
        )
        lines.append(
            f"policy         {Path(policy['file']).name}: {policy['steps']} steps at "
            f"{policy['rate_hz_kept']:.1f} Hz (asked {policy['rate_hz_asked']:g}), inference "
            f"{policy['inference_us_median']:.0f} us median, "
            f"{policy['inference_us_p99']:.0f} us p99; last {policy['judged_s']:g} s "
            f"{true_cm}{policy['fc_distance_rms_m'] * 100:.0f} cm RMS (FC) from the target"
        )
    firmware = summary.get("firmware")
    if firmware:
        lines.append(
            f"firmware       {firmware['version']} (MSP API {firmware['api']}, "
            f"{firmware['conventions']} conventions" + (", GPS" if firmware["gps"] else "") + ")"
        )
    rc = summary.get("rc_link")
    if rc:
        lines.append(
            f"RC link        {rc['packets']} packets, period mean "
            f"{rc['period_mean_ms']:.2f} ms, max {rc['period_max_ms']:.2f} ms"
        )
    physics = summary.get("physics")
    if physics:
        mode = ""
        if physics.get("lockstep"):
            through = {"shm": "shared memory", "udp": "UDP"}.get(physics.get("exchange"), "")
            mode = f"lockstep through {through}, " if through else "lockstep, "
        lines.append(
            f"physics        {mode}{physics['answered_ratio'] * 100:.1f} % of fdm "
            f"packets answered at {physics['speed']:.2f}x real time"
        )
    if "findings" in summary:
        findings = summary["findings"]
        watched = len((summary.get("analysers") or {}).get("watched") or ())
        if not findings:
            lines.append(f"findings       none ({watched} analysers watched)")
        for index, finding in enumerate(findings):
            head = "findings       " if index == 0 else " " * 15
            lines.append(
                f"{head}{finding['severity']:<8} {finding['analyser']}: "
                f"{finding['summary']} (t={finding['time_s']:.2f} s)"
            )
    return "\n".join(lines)
