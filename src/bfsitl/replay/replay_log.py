"""One replay from start to end: the log's sticks and settings, the flight through the
firmware, the comparison of the two logs (what ``bfsitl log replay`` and the fidelity
benchmark run)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.backend.options import Timing
from bfsitl.blackbox.decode import BlackboxLog, decode_blackbox
from bfsitl.build.binary_scan import names_missing
from bfsitl.errors import ReplayError
from bfsitl.physics.params import QuadParams
from bfsitl.physics.wind import Wind
from bfsitl.replay.compare import ReplayComparison, comparable_frames, compare_logs
from bfsitl.replay.flight import ReplayedFlight, fly_replay, replay_firmware
from bfsitl.replay.header_settings import HeaderSettings, NotCarried, header_settings
from bfsitl.replay.sticks import IDENTITY_RC_LINES, StickStream, stick_stream

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class Replay:
    """Everything one replay made: the log, what was sent, what flew, how it compared.

    Attributes:
        log: The real flight.
        vehicle: The simulated quad's name.
        settings: The log's header as the build's CLI lines, and what did not come across.
        stream: The receiver frames sent.
        flight: What the replay left behind (the replaying FC's log, the firmware, timing).
        comparison: The replaying FC's log against the real one, per axis.
        replayed: The replaying FC's log, decoded (an A/B compares two of them).
    """

    log: BlackboxLog
    vehicle: str
    settings: HeaderSettings
    stream: StickStream
    flight: ReplayedFlight
    comparison: ReplayComparison
    replayed: BlackboxLog


def replay_log(
    log: BlackboxLog,
    *,
    firmware: str | Path | None,
    quad: QuadParams,
    out_dir: Path,
    extra_cli: tuple[str, ...] = (),
    progress: Progress = lambda _line: None,
    seed: int = 0,
    wind: Wind | None = None,
    timing: Timing | None = None,
) -> Replay:
    """Fly ``log`` again with ``quad`` on ``firmware`` (a lockstep build) and compare.

    Args:
        log: The real flight.
        firmware: A lockstep SITL binary or cached build's name; None searches as
            ``bfsitl fly`` does.
        quad: The simulated quad.
        out_dir: Where the SITL runs and its log is kept.
        extra_cli: CLI lines applied after the log's settings.
        progress: Called with a line of text at each stage.
        seed: Seeds the simulated sensors' noise: the same seed, the same replay.
        wind: The air the replay flies through (None: still air; a log does not say).
        timing: How the clocks run (None: lockstep as fast as it goes).

    Returns:
        The replay: what was sent, what flew and how it compared.

    Raises:
        BlackboxError: The log has no sticks to send (:class:`ReplayError`), or the replay's
            own log cannot be read.
        SitlError, ArmingBlockedError: The SITL would not start, answer or arm.
    """
    stream = stick_stream(log)
    comparable_frames(log)  # what the comparison needs is there, before anything flies
    firmware_found = replay_firmware(firmware)
    settings = header_settings(log.headers, sitl_pid_rate_hz=firmware_found.pid_loop_hz)
    settings = known_to(settings, firmware_found.path)
    progress(
        f"{log.path.name} log {log.index} ({log.firmware_revision}, {log.duration_s:.1f} s): "
        f"{len(settings.carried)} settings carried over, {len(settings.not_carried)} not "
        f"(listed in the report); {len(stream)} receiver frames every "
        f"{stream.frame_interval_s * 1000:.1f} ms"
    )
    flight = fly_replay(
        stream,
        firmware=firmware_found,
        quad=quad,
        cli_lines=(*IDENTITY_RC_LINES, *settings.cli_lines, *extra_cli),
        out_dir=out_dir,
        progress=progress,
        seed=seed,
        wind=wind,
        timing=timing,
    )
    replayed = decode_blackbox(flight.blackbox)
    if not replayed:
        raise ReplayError(f"the replay's blackbox file {flight.blackbox} holds no log")
    longest = max(replayed, key=lambda one: len(one.frames))
    return Replay(log, quad.name, settings, stream, flight, compare_logs(log, longest), longest)


def line_name(line: str) -> str:
    """The setting or feature a CLI line sets: ``set p_roll = 45`` -> ``p_roll``,
    ``feature -AIRMODE`` -> ``AIRMODE``."""
    words = line.split()
    if words[0] == "feature":
        return words[1].lstrip("-")
    return words[1]


def known_to(settings: HeaderSettings, binary: Path) -> HeaderSettings:
    """``settings`` without the lines whose setting or feature the build at ``binary`` lacks
    (master dropped some of 4.6.0's, e.g. ``abs_control_gain``); each is listed as not
    carried, so the FC is never asked for a name it would refuse."""
    names = frozenset(line_name(line) for c in settings.carried for line in c.cli_lines)
    missing = names_missing(binary, names)
    if not missing:
        return settings
    carried, not_carried = [], list(settings.not_carried)
    for setting in settings.carried:
        kept = tuple(line for line in setting.cli_lines if line_name(line) not in missing)
        lacked = [line_name(line) for line in setting.cli_lines if line_name(line) in missing]
        if kept:
            carried.append(dataclasses.replace(setting, cli_lines=kept))
        if lacked:
            why = f"this build has no {', '.join(lacked)}"
            not_carried.append(NotCarried(setting.header, setting.value, why))
    return dataclasses.replace(settings, carried=tuple(carried), not_carried=tuple(not_carried))
