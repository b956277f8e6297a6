"""Fly a log's sticks through a lockstep SITL and keep the replaying FC's own blackbox log.

The order: the SITL boots with the log's settings (:mod:`.header_settings`), the identity
stick path (:data:`.sticks.IDENTITY_RC_LINES`) and the blackbox on (read at boot, so
provisioning reboots it once); the quad arms on the ground, as the real one did when its log
began; then each receiver frame is sent when it is due on simulated time, one frame per
datagram (:attr:`~bfsitl.sim.lockstep.LockstepBridge.rc_frames_on_set`), with the
self-levelling switches as the pilot had them; at the log's end the quad is disarmed and the
log the FC wrote is copied out.  Lockstep only: in real time the frames would arrive when the
machine gets to them, not when they are due.
"""

from __future__ import annotations

import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.backend.options import Timing, World
from bfsitl.blackbox import collect_blackbox
from bfsitl.build.binary_scan import binary_traits
from bfsitl.errors import ReplayError
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.fc.provisioning import ANGLE_ON_AUX2, ARM_ON_AUX1, Profile
from bfsitl.fc.rc_link import RcCommand
from bfsitl.mission.session import FcSetup, FlightSession, SessionConfig, SitlLaunch
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US
from bfsitl.physics.params import QuadParams
from bfsitl.physics.wind import Wind
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import BoxId
from bfsitl.protocol.firmware_profile import FirmwareProfile, Generation
from bfsitl.replay.sticks import StickStream
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from bfsitl.sitl.firmware import find_firmware

Progress = Callable[[str], None]

HORIZON_ON_AUX3 = msg.ModeRange.from_us(BoxId.HORIZON, 2, 1700, 2100)
#: The replaying FC's log rate: about 1 kHz, what real logs of 1-4 kHz are compared at.
LOG_RATE_HZ = 1000.0
#: Marks a run folder a replay made (:func:`fresh_run_dir` empties no other).
RUN_MARKER = ".bfsitl-replay-run"
#: The lead-in before the log's first frame (:func:`lead_in_s`).
LEAD_IN_FRAMES = 40
LEAD_IN_MIN_S = 0.5
LEAD_IN_MAX_S = 2.0
#: How often the stream looks at the SITL's health and reports progress, simulated seconds.
_CHECK_EVERY_S = 1.0
_PROGRESS_EVERY_S = 10.0


@dataclass(frozen=True, slots=True)
class ReplayedFlight:
    """What a replay left behind.

    Attributes:
        blackbox: The replaying FC's log (copied out of its run directory).
        firmware: The firmware that flew, as it names itself (e.g. ``4.6.0``).
        frames_sent: Receiver frames streamed.
        flown_s: Simulated seconds from the first frame to the last.
        wall_s: Wall seconds the stream took.
        receiver_frames: The FC counted a receiver frame per frame sent (False: it counted
            one at every loop, as the 4.x SITL that wrote the log did, or an older 4.6.0
            lockstep build does).
        cli_lines: The CLI lines the FC was given, in order.
    """

    blackbox: Path
    firmware: str
    frames_sent: int
    flown_s: float
    wall_s: float
    receiver_frames: bool = True
    #: The CLI lines the replaying FC was given, in order (the log's, the stick path's, the
    #: extra lines, the blackbox's).
    cli_lines: tuple[str, ...] = ()


def pid_rate_hz(profile: FirmwareProfile) -> float:
    """The SITL's PID loop rate before ``pid_process_denom``: 4.6.0 loops at 8 kHz, master
    at 1 kHz (its header's looptime, measured)."""
    return 8000.0 if profile.generation is Generation.V4_6 else 1000.0


def blackbox_lines(pid_loop_hz: float) -> tuple[str, ...]:
    """The replaying FC's own log, at the power-of-two share of ``pid_loop_hz`` nearest
    :data:`LOG_RATE_HZ` (``blackbox_sample_rate`` takes 1/1 to 1/16 on 4.6.0 and master,
    ``[4.6] src/main/cli/settings.c:292``; a faster loop logs faster)."""
    denominator = 1
    while denominator < 16 and pid_loop_hz / (denominator * 2) >= LOG_RATE_HZ * 0.99:
        denominator *= 2
    return (
        "set blackbox_device = VIRTUAL",
        "set blackbox_mode = NORMAL",
        f"set blackbox_sample_rate = 1/{denominator}",
    )


def pid_process_denom(cli_lines: tuple[str, ...]) -> int:
    """The last ``set pid_process_denom = N`` of ``cli_lines`` (1 when none)."""
    denominator = 1
    for line in cli_lines:
        words = line.replace("=", " = ").split()
        if words[:3] == ["set", "pid_process_denom", "="] and len(words) == 4:
            try:
                denominator = max(1, int(words[3]))
            except ValueError:
                pass
    return denominator


def replay_profile(cli_lines: tuple[str, ...]) -> Profile:
    """ARM on AUX1, ANGLE on AUX2, HORIZON on AUX3, and ``cli_lines``; rebooted when they
    change (the blackbox's settings are read at boot)."""
    return Profile(
        mode_ranges=(ARM_ON_AUX1, ANGLE_ON_AUX2, HORIZON_ON_AUX3),
        cli_lines=cli_lines,
        reboot_when_changed=True,
    )


@dataclass(frozen=True, slots=True)
class ReplayFirmware:
    """The SITL a replay runs.

    Attributes:
        path: The binary.
        pid_loop_hz: Its PID loop rate before ``pid_process_denom`` (what the log's own PID
            rate is matched against).
        receiver_frames: It counts a receiver frame per frame sent, as a real receiver's
            (master always; a 4.6.0 lockstep build when asked, since this came in).
    """

    path: Path
    pid_loop_hz: float
    receiver_frames: bool = True


def replay_firmware(firmware: str | Path | None) -> ReplayFirmware:
    """Find the SITL ``firmware`` names (None searches as ``bfsitl fly`` does); it must be a
    lockstep build, checked from its bytes before anything starts.

    Raises:
        FirmwareNotFoundError: No such binary or cached build.
        ReplayError: It is no lockstep build.
    """
    binary = find_firmware(firmware)
    traits = binary_traits(binary.path)
    if not traits.lockstep:
        raise ReplayError(
            f"log replay needs a lockstep build, so that each frame reaches the FC when it is "
            f"due; {binary.path} is not one: `bfsitl firmware build --lockstep`, then "
            f"--firmware with its name"
        )
    profile = profile_of_binary(binary.path)
    frames = traits.rx_frames or profile.generation is not Generation.V4_6
    return ReplayFirmware(Path(binary.path), pid_rate_hz(profile), frames)


def fly_replay(
    stream: StickStream,
    *,
    firmware: ReplayFirmware,
    quad: QuadParams,
    cli_lines: tuple[str, ...],
    out_dir: Path,
    progress: Progress = lambda _line: None,
    seed: int = 0,
    wind: Wind | None = None,
    timing: Timing | None = None,
    session_factory: Callable[..., FlightSession] = FlightSession,
) -> ReplayedFlight:
    """Fly ``stream`` (see the module docstring); the SITL runs in ``out_dir/sitl``.

    Args:
        stream: The frames to send.
        firmware: The lockstep SITL (:func:`replay_firmware`).
        quad: The simulated quad.
        cli_lines: The log's settings and the identity stick path; the blackbox's lines are
            added here.
        out_dir: Where the SITL runs and its log is copied to (``replay.BFL``).
        progress: Called with a line of text at each stage and every 10 s of flight.
        seed: Seeds the simulated sensors' noise (and the gusts): the same seed, the same
            replay.
        wind: The air the replay flies through (a log does not say; None: still air).
        timing: How the clocks run (None: lockstep as fast as it goes, spinning); a suite
            whose runs share the cores asks it not to spin.
        session_factory: Makes the session (a fake in unit tests).

    Raises:
        ReplayError: The firmware is no lockstep build, or it wrote no log.
        SitlError, ArmingBlockedError: The SITL would not start, answer or arm.
    """
    out_dir.mkdir(parents=True, exist_ok=True)
    fresh_run_dir(out_dir / "sitl")
    receiver_frames = firmware.receiver_frames and not stream.loop_frames
    if not firmware.receiver_frames and not stream.loop_frames:
        progress(
            "this lockstep build counts a receiver frame at every loop, not per frame sent: "
            "rebuild it (`bfsitl firmware build --lockstep`) for the receiver's own rate"
        )
    pid_hz = firmware.pid_loop_hz / pid_process_denom(cli_lines)
    lines = (*cli_lines, *blackbox_lines(pid_hz))
    config = SessionConfig(
        sitl=SitlLaunch(firmware=firmware.path, workdir=out_dir / "sitl"),
        timing=timing or Timing(),
        fc=FcSetup(
            profile=replay_profile(lines),
            angle_mode=bool(stream.angle[0]),
            # A log whose FC counted a frame at every loop is replayed on the same receiver;
            # with a rate, a 4.6.0 build counts a frame per trailer (the backend asks it).
            rc_rate_hz=None if stream.loop_frames else DEFAULT_RC_RATE_HZ,
        ),
        world=World(quad=quad, wind=wind, seed=seed),
    )
    with session_factory(config, progress=progress) as session:
        session.start()
        if not session.lockstep:
            raise ReplayError(
                "log replay needs the lockstep bridge, so that each frame reaches the FC when "
                "it is due; this session runs in real time"
            )
        assert session.firmware is not None
        session.arm()
        started_wall_s = time.monotonic()
        flown_s = _stream(session, stream, progress)
        wall_s = time.monotonic() - started_wall_s
        session.disarm()
        version = session.firmware.firmware_version or session.firmware.generation.value
    copies = collect_blackbox(out_dir / "sitl", out_dir, prefix="replay-")
    if not copies:
        raise ReplayError(
            f"the replaying FC wrote no blackbox log into {out_dir / 'sitl'}: was it armed?"
        )
    return ReplayedFlight(
        copies[-1], version, len(stream), flown_s, wall_s, receiver_frames, cli_lines=lines
    )


def fresh_run_dir(run_dir: Path) -> None:
    """Make ``run_dir`` empty but for :data:`RUN_MARKER`: an ``eeprom.bin`` left by an earlier
    replay (another log, another ``--cli``) would keep every setting this one does not write.
    Only a folder a replay made (it holds the marker) is emptied.

    Raises:
        ReplayError: ``run_dir`` exists and a replay did not make it.
    """
    if run_dir.exists():
        if not (run_dir / RUN_MARKER).exists():
            raise ReplayError(
                f"{run_dir} is not a folder a replay made (no {RUN_MARKER} in it), and a "
                f"replay would empty it: give another --out"
            )
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True)
    (run_dir / RUN_MARKER).write_text(
        "the run folder of a bfsitl log replay; emptied by the next\n"
    )


def lead_in_s(stream: StickStream) -> float:
    """How long the first frame's sticks are sent before the log's, at its receiver's rate:
    arming sent a frame every step, and the firmware's measure of the receiver's rate (a
    smoothed average, ``[4.6] src/main/fc/rc.c:461-479``) takes some 40 frames to settle."""
    return min(LEAD_IN_MAX_S, max(LEAD_IN_MIN_S, LEAD_IN_FRAMES * stream.frame_interval_s))


def _stream(session: FlightSession, stream: StickStream, progress: Progress) -> float:
    """Send the lead-in, then every frame when it is due; the simulated seconds from the
    log's first frame to its last."""
    bridge = session.bridge
    assert bridge is not None
    clock = session.clock
    next_check_s = next_report_s = 0.0
    bridge.rc_frames_on_set = True  # type: ignore[union-attr]
    try:
        for _ in range(max(1, round(lead_in_s(stream) / stream.frame_interval_s))):
            session.set_rc(_frame(stream, 0))
            clock.sleep_s(stream.frame_interval_s)
        start_s = session.time_s
        for index, due_s in enumerate(stream.time_s.tolist()):
            wait_s = start_s + due_s - session.time_s
            if wait_s > 0:
                clock.sleep_s(wait_s)
            session.set_rc(_frame(stream, index))
            if due_s >= next_check_s:
                session.check_alive()
                next_check_s = due_s + _CHECK_EVERY_S
            if due_s >= next_report_s:
                progress(f"replaying: {due_s:.0f} of {stream.time_s[-1]:.0f} s")
                next_report_s = due_s + _PROGRESS_EVERY_S
    finally:
        bridge.rc_frames_on_set = False  # type: ignore[union-attr]
    return session.time_s - start_s


def _frame(stream: StickStream, index: int) -> RcCommand:
    return RcCommand(
        roll_us=float(stream.roll_us[index]),
        pitch_us=float(stream.pitch_us[index]),
        throttle_us=float(stream.throttle_us[index]),
        yaw_us=float(stream.yaw_us[index]),
        aux_us=(
            SWITCH_ON_US,
            SWITCH_ON_US if stream.angle[index] else SWITCH_OFF_US,
            SWITCH_ON_US if stream.horizon[index] else SWITCH_OFF_US,
        ),
    )
