"""Decode a blackbox file into typed frames and events with ``orangebox`` (the registry's
decoder) plus bfsitl's reading of the events (:mod:`bfsitl.blackbox.events`); a clean log's
frames are read by the compiled kernel instead (:mod:`bfsitl.blackbox.compiled_frames`: the
same numbers in a fraction of the time).

Why orangebox 0.4.0 (see docs/scenarios.md): pure Python with no dependencies, GPL-3.0 like
bfsitl, driven by the log's own header (so 4.6.0's and master's logs both decode), and it
appends the latest slow frame (failsafe phase, receiver state, switch mask) to every main
frame, so each frame carries them with its FC time.  0.5.0 cannot be installed by pip.

What a decoded log can be trusted for, measured on real SITL logs (tests/data/blackbox):

* the slow frame is written only when a value changed, at a logged iteration
  (``[4.6] src/main/blackbox/blackbox.c:1018-1042``), and the disarm closes the log in the
  same pass: a failsafe that ends in LANDED (DROP, or the end of an AUTO-LAND) disarms inside
  one ``failsafeUpdateState`` call (``[4.6] src/main/flight/failsafe.c:311-395``), so with
  ``blackbox_mode = NORMAL`` RX_LOSS_DETECTED and LANDED never reach the log; a phase that
  lasts does (LANDING, measured).  The DISARM event's reason is the evidence of how it ended;
* a log cut short (a SITL killed while armed, a file cut mid-frame) keeps the frames before
  the cut and is marked ``truncated``; 0.4.0 ends such a log with a TypeError or IndexError
  once the data runs out, and never yields the last complete frame before the cut (it peeks
  at the byte after a frame before yielding it).
"""

from __future__ import annotations

import itertools
import logging
import math
import operator
from collections.abc import Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from orangebox.errors import InvalidHeaderException
from orangebox.reader import Reader

from bfsitl.blackbox.compiled_frames import CompiledLog, compiled_log
from bfsitl.blackbox.events import DISARM_REASONS, EventKeepingParser, disarm_reason_name
from bfsitl.collector_paused import collector_paused
from bfsitl.errors import BlackboxError
from bfsitl.protocol.failsafe_phase import FailsafePhase

__all__ = [
    "DISARM_REASONS",
    "BlackboxEvent",
    "BlackboxFrame",
    "BlackboxLog",
    "decode_blackbox",
    "frames_to_rows",
]

#: Every log starts with this header line (``[4.6] src/main/blackbox/blackbox.c:131``);
#: orangebox splits a file into logs where it repeats.
_FIRST_HEADER = b"H Product:"


@dataclass(frozen=True, slots=True)
class BlackboxFrame:
    """One main frame, with the slow frame in force at its time
    (``loadSlowState``, ``[4.6] src/main/blackbox/blackbox.c:1003-1010``)."""

    time_s: float  # FC time (the log's µs since boot), seconds
    failsafe_phase: int | None  # None before the first slow frame
    rx_signal_received: bool | None
    rx_flight_channels_valid: bool | None
    #: ``flightModeFlags``: rcModeActivationMask, the mode *switches* on by internal box id
    #: (``boxId_e``), not the active flight modes; 0 before the first slow frame.
    mode_switch_mask: int
    state_flags: int  # bit 0 GPS_FIX_HOME, bit 1 GPS_FIX
    motors: tuple[int, ...]  # motor[0..], as logged
    rc_command: tuple[int, ...]  # rcCommand[0..3]
    setpoint: tuple[int, ...]  # setpoint[0..3] (deg/s, throttle)
    gyro_adc: tuple[int, ...]  # gyroADC[0..2], as logged
    debug: tuple[int, ...]  # debug[0..7] (what debug_mode puts there)
    #: accSmooth[0..2] (the accelerometer, ``acc_1G`` per g; empty when not logged).
    acc: tuple[int, ...] = ()
    #: imuQuaternion[0..2]: the attitude's x, y, z scaled by 0x7FFF, w >= 0 implied
    #: (``[4.6] src/main/blackbox/blackbox.c:1260-1269``); empty when not logged.
    quaternion_xyz: tuple[int, ...] = ()
    #: baroAlt: the barometer's altitude above where it was calibrated, cm (None: no baro).
    baro_alt_cm: int | None = None


@dataclass(frozen=True, slots=True)
class BlackboxEvent:
    """An event frame: ``kind`` is the firmware's name without FLIGHT_LOG_EVENT_ (DISARM,
    FLIGHTMODE, SYNC_BEEP, LOGGING_RESUME, INFLIGHT_ADJUSTMENT, LOG_END)."""

    #: FC time of the last main frame before it (events carry no time of their own); None
    #: when none came before.
    time_s: float | None
    kind: str
    data: dict[str, Any]


@dataclass(frozen=True, slots=True)
class BlackboxLog:
    """One log of a file (the FC starts one each time it arms)."""

    path: Path
    index: int  # 1-based, as the file holds them
    firmware_revision: str
    #: The ``H name:value`` lines as written (field definitions included).
    headers: dict[str, str] = field(repr=False)
    frames: tuple[BlackboxFrame, ...] = field(repr=False)
    events: tuple[BlackboxEvent, ...] = field(repr=False)
    disarm_reason: int | None  # the DISARM event's; None without one
    disarm_reason_name: str | None  # FAILSAFE, SWITCH, ... (``DISARM_REASONS``)
    #: The log ends without LOG_END: the SITL stopped while logging, or the file was cut.
    truncated: bool

    @property
    def value_scale(self) -> float:
        """What the rates and sticks were multiplied by when logged: 10 with 4.6's
        ``blackbox_high_resolution`` on (gyro, rcCommand, setpoint,
        ``[4.6] src/main/blackbox/blackbox.c:1251-1278,2307``), else 1."""
        return 10.0 if self.headers.get("blackbox_high_resolution", "0").strip() == "1" else 1.0

    @property
    def duration_s(self) -> float:
        return self.frames[-1].time_s - self.frames[0].time_s if self.frames else 0.0

    def phase_changes(self) -> list[tuple[float, FailsafePhase]]:
        """(FC time, phase) at the first frame that has one and at each change."""
        changes: list[tuple[float, FailsafePhase]] = []
        for frame in self.frames:
            if frame.failsafe_phase is None:
                continue
            try:
                phase = FailsafePhase(frame.failsafe_phase)
            except ValueError:
                continue  # a phase a newer firmware added: not a change this enum can name
            if not changes or changes[-1][1] is not phase:
                changes.append((frame.time_s, phase))
        return changes


def decode_blackbox(path: str | Path) -> list[BlackboxLog]:
    """Every log in the file at ``path``, decoded.

    Args:
        path: A blackbox file the FC wrote (``LOG00001.BFL`` on master, ``LOG00001.BF`` on
            4.6.0); one file may hold several logs, one per armed flight.

    Returns:
        One decoded log per log in the file, in order: frames, events and headers.

    Raises:
        BlackboxError: The file cannot be read or does not start like a blackbox log.
            Damage further in ends that log early (``truncated``), never the call.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise BlackboxError(f"cannot read the blackbox file {path}: {exc.strerror or exc}") from exc
    if not data.startswith(_FIRST_HEADER):
        what = "is empty" if not data else "does not start with an 'H Product:' header"
        raise BlackboxError(
            f"{path} is not a blackbox log (it {what}); pass a LOG*.BFL or "
            f"LOG*.BF file the FC wrote (blackbox_device = VIRTUAL)"
        )
    with _orangebox_quiet(), collector_paused():
        try:
            starts = Reader(str(path)).log_pointers
        except (OSError, ValueError, RuntimeError, InvalidHeaderException) as exc:
            raise BlackboxError(f"{path}: orangebox cannot read the file: {exc}") from exc
        ends = [*starts[1:], len(data)]
        return [
            _decode_one(path, index, data[start:end])
            for index, (start, end) in enumerate(zip(starts, ends, strict=True), 1)
        ]


@contextmanager
def _orangebox_quiet() -> Iterator[None]:
    """orangebox warns about every optional header a SITL log lacks (minthrottle, vbatref) and
    every event it does not know: noise for a log bfsitl decodes anyway."""
    logger = logging.getLogger("orangebox")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _decode_one(path: Path, index: int, segment: bytes) -> BlackboxLog:
    headers = _raw_headers(segment)
    frames: list[BlackboxFrame] = []
    parser: EventKeepingParser | None = None
    compiled: CompiledLog | None = None
    cut = False
    try:
        parser = EventKeepingParser(Reader(str(path), log_index=index))
        layout = _FrameLayout.of(parser.field_names)
        compiled = compiled_log(parser)
        if compiled is not None:
            frames.extend(layout.compiled_frames(compiled))
        else:
            frames.extend(layout.frames(frame.data for frame in parser.frames()))
    except (
        TypeError,
        IndexError,
        ValueError,
        KeyError,
        RuntimeError,
        ZeroDivisionError,
        InvalidHeaderException,
    ):
        # 0.4.0 reads past the end of a cut log as None (TypeError) or peeks past it
        # (IndexError); a header cut short fails while building its field definitions.
        # Whatever came before the damage is kept.
        cut = True
    if compiled is not None:  # the kernel decodes only a log that ends with LOG_END
        kept, ended = compiled.kept, True
    elif parser is not None:
        kept, ended = parser.kept, parser.saw_log_end
    else:
        kept, ended = [], False
    events = tuple(
        BlackboxEvent(frames[before - 1].time_s if before else None, kind, data)
        for before, kind, data in kept
    )
    reason = next((e.data["reason"] for e in reversed(events) if e.kind == "DISARM"), None)
    return BlackboxLog(
        path=path,
        index=index,
        firmware_revision=headers.get("Firmware revision", ""),
        headers=headers,
        frames=tuple(frames),
        events=events,
        disarm_reason=reason,
        disarm_reason_name=None if reason is None else disarm_reason_name(reason),
        truncated=cut or not ended,
    )


def _raw_headers(segment: bytes) -> dict[str, str]:
    """The ``H name:value`` lines at the start of a log, as text.  orangebox's own headers
    are converted (numbers, lists) and leave out the field definitions."""
    headers: dict[str, str] = {}
    for line in segment.split(b"\n"):
        if not line.startswith(b"H "):
            break  # the first frame follows the last header line
        name, _, value = line[2:].decode("ascii", "replace").partition(":")
        headers[name.strip()] = value.strip()
    return headers


def _int(value: object) -> int | None:
    if isinstance(value, bool):
        return int(value)
    if isinstance(value, int):
        return value
    if isinstance(value, float) and math.isfinite(value):
        return int(value)
    return None  # orangebox fills slow fields with '' before the first slow frame


#: orangebox gives a field its encoding calls unsigned as an unsigned 32-bit number even when
#: its predictor took it below zero: 3.x logs throttle against ``minthrottle``, so a stick
#: below it reads 2**32 + 1000 (measured on the CS110 logs).  No flight value is that large.
_UINT32_WRAP = 1 << 32
_INT32_MAX = (1 << 31) - 1


def _ints(data: Sequence[object], indexes: tuple[int, ...]) -> tuple[int, ...]:
    """The values at ``indexes`` (a group: ``motor[0]``, ``motor[1]``, ...) up to the first
    that is missing or not a number, with a negative value orangebox wrapped to 32 bits
    unwrapped (the rows :meth:`_FrameLayout.frames` does not take the short way)."""
    values = []
    for index in indexes:
        value = data[index] if index < len(data) else None
        if type(value) is not int:  # the usual case is an int: the checks below are rare
            value = _int(value)
            if value is None:
                break
        values.append(value - _UINT32_WRAP if value > _INT32_MAX else value)
    return tuple(values)


def _one(data: Sequence[object], index: int | None) -> int | None:
    if index is None or index >= len(data):
        return None
    value = data[index]
    return value if type(value) is int else _int(value)


@dataclass(frozen=True, slots=True)
class _FrameLayout:
    """Where each of a frame's fields is in orangebox's row of values, found once per log
    from its field names (a frame read through a dict of names cost a quarter of the whole
    decode)."""

    time: int | None
    failsafe_phase: int | None
    rx_signal_received: int | None
    rx_flight_channels_valid: int | None
    mode_switch_mask: int | None
    state_flags: int | None
    baro_alt: int | None
    motors: tuple[int, ...]
    rc_command: tuple[int, ...]
    setpoint: tuple[int, ...]
    gyro_adc: tuple[int, ...]
    debug: tuple[int, ...]
    acc: tuple[int, ...]
    quaternion_xyz: tuple[int, ...]

    @property
    def _groups(self) -> tuple[tuple[int, ...], ...]:
        return (
            self.motors,
            self.rc_command,
            self.setpoint,
            self.gyro_adc,
            self.debug,
            self.acc,
            self.quaternion_xyz,
        )

    @classmethod
    def of(cls, names: Sequence[str]) -> _FrameLayout:
        where = {name: index for index, name in enumerate(names)}  # the last of a name wins

        def group(name: str, count: int) -> tuple[int, ...]:
            indexes = []
            for number in range(count):
                index = where.get(f"{name}[{number}]")
                if index is None:
                    break
                indexes.append(index)
            return tuple(indexes)

        return cls(
            time=where.get("time"),
            failsafe_phase=where.get("failsafePhase"),
            rx_signal_received=where.get("rxSignalReceived"),
            rx_flight_channels_valid=where.get("rxFlightChannelsValid"),
            mode_switch_mask=where.get("flightModeFlags"),
            state_flags=where.get("stateFlags"),
            baro_alt=where.get("baroAlt"),
            motors=group("motor", 8),
            rc_command=group("rcCommand", 4),
            setpoint=group("setpoint", 4),
            gyro_adc=group("gyroADC", 3),
            debug=group("debug", 8),
            acc=group("accSmooth", 3),
            quaternion_xyz=group("imuQuaternion", 3),
        )

    def frames(self, rows: Iterable[Sequence[object]]) -> Iterator[BlackboxFrame]:
        """:meth:`frame` for each row, the groups' values taken in one call per row: a
        row's values are ints but where a log is odd (a field missing, an encoding
        orangebox leaves a TODO, a wrapped negative), and those rows go the long way."""
        groups = self._groups
        flat = tuple(index for group in groups for index in group)
        if len(flat) < 2:
            yield from (self.frame(row) for row in rows)
            return
        take = operator.itemgetter(*flat)
        cuts = list(itertools.accumulate(len(group) for group in groups))
        bounds = list(zip([0, *cuts[:-1]], cuts, strict=True))
        for row in rows:
            try:
                values = take(row)
                plain = max(values) <= _INT32_MAX  # TypeError for a value not a number
            except (IndexError, TypeError):
                plain = False
            if not plain:
                yield self.frame(row)
                continue
            yield self._frame(row, *(values[start:end] for start, end in bounds))

    def compiled_frames(self, log: CompiledLog) -> list[BlackboxFrame]:
        """:meth:`frames` of ``log.rows()``, made a field at a time: every value the kernel
        gives is an int, so each row would take the short way but for the wrap of a negative
        value (undone here a group at a time, as :func:`_ints` does a value at a time)."""
        count = len(log.main)
        main_count = log.main.shape[1]
        if any(index >= main_count for group in self._groups for index in group):
            return list(self.frames(log.rows()))  # a group in a slow or GPS frame: not seen

        def group(indexes: tuple[int, ...]) -> list[tuple[int, ...]]:
            if not indexes:
                return [()] * count
            values = log.main[:, list(indexes)]
            values = np.where(values > _INT32_MAX, values - _UINT32_WRAP, values)
            return list(map(tuple, values.tolist()))

        def single(index: int | None) -> list[int | None]:
            return [None] * count if index is None else log.column(index)

        def flag(index: int | None) -> list[bool | None]:
            return [None if value is None else bool(value) for value in single(index)]

        def zero_for_none(index: int | None) -> list[int]:
            return [value or 0 for value in single(index)]

        times = np.array(zero_for_none(self.time), dtype=np.int64) / 1e6
        return list(
            map(
                BlackboxFrame,
                times.tolist(),
                single(self.failsafe_phase),
                flag(self.rx_signal_received),
                flag(self.rx_flight_channels_valid),
                zero_for_none(self.mode_switch_mask),
                zero_for_none(self.state_flags),
                *(group(indexes) for indexes in self._groups),
                single(self.baro_alt),
            )
        )

    def frame(self, data: Sequence[object]) -> BlackboxFrame:
        return self._frame(data, *(_ints(data, group) for group in self._groups))

    def _frame(
        self,
        data: Sequence[object],
        motors: tuple[int, ...],
        rc_command: tuple[int, ...],
        setpoint: tuple[int, ...],
        gyro_adc: tuple[int, ...],
        debug: tuple[int, ...],
        acc: tuple[int, ...],
        quaternion_xyz: tuple[int, ...],
    ) -> BlackboxFrame:
        rx_signal = _one(data, self.rx_signal_received)
        rx_valid = _one(data, self.rx_flight_channels_valid)
        return BlackboxFrame(
            time_s=(_one(data, self.time) or 0) / 1e6,
            failsafe_phase=_one(data, self.failsafe_phase),
            rx_signal_received=None if rx_signal is None else bool(rx_signal),
            rx_flight_channels_valid=None if rx_valid is None else bool(rx_valid),
            mode_switch_mask=_one(data, self.mode_switch_mask) or 0,
            state_flags=_one(data, self.state_flags) or 0,
            motors=motors,
            rc_command=rc_command,
            setpoint=setpoint,
            gyro_adc=gyro_adc,
            debug=debug,
            acc=acc,
            quaternion_xyz=quaternion_xyz,
            baro_alt_cm=_one(data, self.baro_alt),
        )


def frames_to_rows(log: BlackboxLog) -> list[dict[str, float | int | bool | None]]:
    """One flat dict per frame (``motor0``, ``gyro_adc2``, ...), e.g. for ``csv.DictWriter``
    or a DataFrame; ``time_from_start_s`` counts from the log's first frame."""
    start = log.frames[0].time_s if log.frames else 0.0
    rows: list[dict[str, float | int | bool | None]] = []
    for frame in log.frames:
        row: dict[str, float | int | bool | None] = {
            "time_s": frame.time_s,
            "time_from_start_s": round(frame.time_s - start, 6),
            "failsafe_phase": frame.failsafe_phase,
            "rx_signal_received": frame.rx_signal_received,
            "rx_flight_channels_valid": frame.rx_flight_channels_valid,
            "mode_switch_mask": frame.mode_switch_mask,
            "state_flags": frame.state_flags,
        }
        for name in ("motors", "rc_command", "setpoint", "gyro_adc", "debug"):
            prefix = "motor" if name == "motors" else name
            for index, value in enumerate(getattr(frame, name)):
                row[f"{prefix}{index}"] = value
        rows.append(row)
    return rows
