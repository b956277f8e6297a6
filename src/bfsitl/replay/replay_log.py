"""One replay from start to end: the log's sticks and settings, the flight through the
firmware, the comparison of the two logs (what ``bfsitl log replay`` and the fidelity
benchmark run)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.blackbox.decode import BlackboxLog, decode_blackbox
from bfsitl.errors import ReplayError
from bfsitl.physics.params import QuadParams
from bfsitl.replay.compare import ReplayComparison, compare_logs
from bfsitl.replay.flight import ReplayedFlight, fly_replay, replay_firmware
from bfsitl.replay.header_settings import HeaderSettings, header_settings
from bfsitl.replay.sticks import IDENTITY_RC_LINES, StickStream, stick_stream

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class Replay:
    """Everything one replay made: the log, what was sent, what flew, how it compared."""

    log: BlackboxLog
    vehicle: str
    settings: HeaderSettings
    stream: StickStream
    flight: ReplayedFlight
    comparison: ReplayComparison


def replay_log(
    log: BlackboxLog,
    *,
    firmware: str | Path | None,
    quad: QuadParams,
    out_dir: Path,
    extra_cli: tuple[str, ...] = (),
    progress: Progress = lambda _line: None,
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

    Raises:
        BlackboxError: The log has no sticks to send (:class:`ReplayError`), or the replay's
            own log cannot be read.
        SitlError, ArmingBlockedError: The SITL would not start, answer or arm.
    """
    stream = stick_stream(log)
    firmware_found = replay_firmware(firmware)
    settings = header_settings(log.headers, sitl_pid_rate_hz=firmware_found.pid_loop_hz)
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
    )
    replayed = decode_blackbox(flight.blackbox)
    if not replayed:
        raise ReplayError(f"the replay's blackbox file {flight.blackbox} holds no log")
    comparison = compare_logs(log, max(replayed, key=lambda one: len(one.frames)))
    return Replay(log, quad.name, settings, stream, flight, comparison)
