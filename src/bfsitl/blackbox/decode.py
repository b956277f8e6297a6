"""Decode a blackbox file into typed frames with ``orangebox`` (the registry's decoder).

Why orangebox 0.4.0 (see docs/scenarios.md): pure Python with no dependencies, GPL-3.0 like
bfsitl, driven by the log's own header (so 4.6.0's and master's logs both decode), and it
appends the latest slow frame (failsafe phase, receiver state, switch mask) to every main
frame, so each frame carries them with its FC time.  0.5.0 cannot be installed by pip.

Two things 0.4.0 does not give, read here from the log's bytes instead:

* events: its parser appends them to a copy of its list, so none survive; bfsitl needs only
  the last two, which the firmware writes in a fixed order when it disarms
  (``fc/core.c``: the DISARM event, then ``blackboxFinish`` writes LOG_END):
  ``'E' 0x0F <reason as an unsigned varint> 'E' 0xFF "End of log" 0x00``;
* a log cut short (a SITL killed while armed): the frames before the cut are kept and the log
  is marked ``truncated``.
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path

from bfsitl.errors import BlackboxError

#: Disarm reasons (``flightLogDisarmReason_e``, fc/core.h; 10 is master's).
DISARM_REASONS = {0: "ARMING_DISABLED", 1: "FAILSAFE", 2: "THROTTLE_TIMEOUT", 3: "STICKS",
                  4: "SWITCH", 5: "CRASH_PROTECTION", 6: "RUNAWAY_TAKEOFF", 7: "GPS_RESCUE",
                  8: "SERIAL_COMMAND", 9: "LANDING", 10: "CRASHFLIP"}
_LOG_END = b"E\xffEnd of log\x00"
_DISARM = b"E\x0f"
#: How far before LOG_END the DISARM event may start (its varint is 1-5 bytes).
_DISARM_WINDOW = 8


class FailsafePhase(enum.IntEnum):
    """``failsafePhase_e`` (flight/failsafe.h); AUTOPILOT is master's."""

    IDLE = 0
    RX_LOSS_DETECTED = 1
    LANDING = 2
    LANDED = 3
    RX_LOSS_MONITORING = 4
    RX_LOSS_RECOVERED = 5
    GPS_RESCUE = 6
    AUTOPILOT = 7


@dataclass(frozen=True, slots=True)
class BlackboxFrame:
    """One main frame, with the slow frame in force at its time."""

    time_s: float                      # FC time (µs since boot in the log), seconds
    failsafe_phase: int | None         # None before the first slow frame
    rx_signal_received: bool | None
    rx_flight_channels_valid: bool | None
    #: ``flightModeFlags``: the mode *switches* on, by internal box id (not active modes).
    mode_switch_mask: int
    state_flags: int                   # bit 0 GPS_FIX_HOME, bit 1 GPS_FIX
    motors: tuple[int, ...]
    rc_command: tuple[int, ...]
    setpoint: tuple[int, ...]
    gyro_adc: tuple[int, ...]
    debug: tuple[int, ...]


@dataclass(frozen=True, slots=True)
class BlackboxLog:
    """One log of a file (the FC starts one each time it arms)."""

    path: Path
    index: int                         # 1-based, as the file holds them
    firmware_revision: str
    headers: dict[str, object] = field(repr=False)
    frames: tuple[BlackboxFrame, ...] = field(repr=False)
    disarm_reason: int | None
    #: The log ends without LOG_END (the SITL stopped while logging) or mid-frame.
    truncated: bool

    @property
    def disarm_reason_name(self) -> str | None:
        if self.disarm_reason is None:
            return None
        return DISARM_REASONS.get(self.disarm_reason, f"reason {self.disarm_reason}")

    @property
    def duration_s(self) -> float:
        return self.frames[-1].time_s - self.frames[0].time_s if self.frames else 0.0

    def phase_changes(self) -> list[tuple[float, FailsafePhase]]:
        """(FC time, phase) at the first frame and at each change of the failsafe phase."""
        changes: list[tuple[float, FailsafePhase]] = []
        for frame in self.frames:
            if frame.failsafe_phase is None:
                continue
            try:
                phase = FailsafePhase(frame.failsafe_phase)
            except ValueError:
                continue
            if not changes or changes[-1][1] is not phase:
                changes.append((frame.time_s, phase))
        return changes


def _int(value: object) -> int | None:
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value
    if isinstance(value, float) and math.isfinite(value):
        return int(value)
    return None  # '' before the first slow frame


def _group(row: dict[str, object], name: str, count: int) -> tuple[int, ...]:
    values = []
    for index in range(count):
        value = _int(row.get(f"{name}[{index}]"))
        if value is None:
            break
        values.append(value)
    return tuple(values)


def _frame(row: dict[str, object]) -> BlackboxFrame:
    phase = _int(row.get("failsafePhase"))
    signal = _int(row.get("rxSignalReceived"))
    channels = _int(row.get("rxFlightChannelsValid"))
    return BlackboxFrame(
        time_s=(_int(row.get("time")) or 0) / 1e6, failsafe_phase=phase,
        rx_signal_received=None if signal is None else bool(signal),
        rx_flight_channels_valid=None if channels is None else bool(channels),
        mode_switch_mask=_int(row.get("flightModeFlags")) or 0,
        state_flags=_int(row.get("stateFlags")) or 0,
        motors=_group(row, "motor", 8), rc_command=_group(row, "rcCommand", 4),
        setpoint=_group(row, "setpoint", 4), gyro_adc=_group(row, "gyroADC", 3),
        debug=_group(row, "debug", 8))


def _unsigned_varint(data: bytes, start: int) -> int | None:
    value = shift = 0
    for offset in range(start, min(start + 5, len(data))):
        byte = data[offset]
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value
        shift += 7
    return None


def _tail_events(segment: bytes) -> tuple[int | None, bool]:
    """(disarm reason, whether LOG_END is there) from a log's last bytes."""
    end = segment.rfind(_LOG_END)
    if end < 0:
        return None, False
    window = segment[max(0, end - _DISARM_WINDOW):end]
    at = window.rfind(_DISARM)
    if at < 0:
        return None, True
    start = max(0, end - _DISARM_WINDOW) + at + len(_DISARM)
    reason = _unsigned_varint(segment, start)
    return (reason if reason is not None and reason < 256 else None), True


def decode_blackbox(path: str | Path) -> list[BlackboxLog]:
    """Every log in the file at ``path``, decoded; raises :class:`BlackboxError` for a file
    that is missing or holds no blackbox log."""
    from orangebox import Parser

    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BlackboxError(f"cannot read the blackbox file {path}: {exc.strerror or exc}") \
            from exc
    if not data.startswith(b"H Product:"):
        raise BlackboxError(f"{path} is not a blackbox log (no 'H Product:' header); is it "
                            f"a LOG*.BFL file the FC wrote?")
    # orangebox logs every missing optional header and unknown event at WARNING: noise here.
    quiet = logging.getLogger("orangebox")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        parser = Parser.load(str(path))
        pointers = [*parser.reader.log_pointers, len(data)]
        logs = []
        for index in range(1, parser.reader.log_count + 1):
            if index > 1:
                parser.set_log_index(index)
            logs.append(_decode_one(parser, path, index,
                                    data[pointers[index - 1]:pointers[index]]))
    except (RuntimeError, ValueError, IndexError, KeyError) as exc:
        raise BlackboxError(f"{path}: the blackbox log cannot be decoded: {exc!r}") from exc
    finally:
        quiet.setLevel(level)
    return logs


def _decode_one(parser: object, path: Path, index: int, segment: bytes) -> BlackboxLog:
    names = parser.field_names  # type: ignore[attr-defined]
    frames: list[BlackboxFrame] = []
    cut = False
    try:
        for frame in parser.frames():  # type: ignore[attr-defined]
            frames.append(_frame(dict(zip(names, frame.data, strict=False))))
    except (TypeError, ValueError, IndexError, RuntimeError, StopIteration):
        cut = True  # 0.4.0 ends a file cut mid-frame with an error: keep what came before
    reason, ended = _tail_events(segment)
    headers = parser.headers  # type: ignore[attr-defined]
    return BlackboxLog(path=path, index=index,
                       firmware_revision=str(headers.get("Firmware revision", "")),
                       headers=headers, frames=tuple(frames), disarm_reason=reason,
                       truncated=cut or not ended)
