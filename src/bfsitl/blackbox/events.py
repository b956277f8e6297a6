"""The blackbox's event frames, which orangebox 0.4.0 reads but does not keep.

Why this module exists: in 0.4.0 ``Parser._parse_event_frame`` appends each event to
``self.events``, a property that returns a *copy* of its list, so ``parser.events`` is always
empty; and it has no parser for DISARM (15): it logs "Unknown event type: 15", counts the frame
invalid and resynchronises past the reason byte, so the disarm reason is lost.  The DISARM
event is the FC's own word on why a flight ended (a failsafe, the switch, a crash...), so
:class:`EventKeepingParser` takes over event frames and reads every payload the firmware
writes.  The override is of a private method, which is why the dependency is pinned to 0.4.0;
the tests fail loudly if a new version stops calling it.  :class:`EventKeepingParser` also
replaces 0.4.0's loop over a frame's fields (``_parse_frame``): a frame type whose encodings
:class:`~bfsitl.blackbox.frame_plan.FramePlan` reads is decoded by it from the log's bytes
(the same frames, a third of the time), any other by 0.4.0's loop with the frame built in a
list.

Event payloads, the same in both trees (``[4.6] src/main/blackbox/blackbox.c:1888-1931``,
``[M] src/main/blackbox/blackbox.c:1882-1925``): after ``'E'`` and the event code,

=======================  ====  ==========================================================
event                    code  payload
=======================  ====  ==========================================================
SYNC_BEEP                0     unsigned varint: arming beep time, µs
INFLIGHT_ADJUSTMENT      13    one byte function (bit 7: float follows), then a signed
                               varint, or a float as 4 bytes little-endian
LOGGING_RESUME           14    unsigned varints: log iteration, FC time in µs
DISARM                   15    unsigned varint: ``flightLogDisarmReason_e``
FLIGHTMODE               30    unsigned varints: new and old switch mask (rcModeActivationMask)
LOG_END                  255   ``"End of log"`` and a NUL
=======================  ====  ==========================================================

The disarm path writes DISARM and then LOG_END when it closes the log
(``[4.6] src/main/fc/core.c:486-493``, ``[M] src/main/fc/core.c:531-538``).
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from typing import Any

from orangebox import Parser
from orangebox.types import Frame

from bfsitl.blackbox.frame_plan import FramePlan
from bfsitl.errors import BlackboxError

#: ``flightLogDisarmReason_e``: ``[4.6] src/main/fc/core.h:49-58``; master adds CRASHFLIP
#: (``[M] src/main/fc/core.h:49-59``).  255 (SYSTEM) exists only in the firmware's unit tests.
DISARM_REASONS = {
    0: "ARMING_DISABLED",
    1: "FAILSAFE",
    2: "THROTTLE_TIMEOUT",
    3: "STICKS",
    4: "SWITCH",
    5: "CRASH_PROTECTION",
    6: "RUNAWAY_TAKEOFF",
    7: "GPS_RESCUE",
    8: "SERIAL_COMMAND",
    9: "LANDING",
    10: "CRASHFLIP",
}

#: ``FlightLogEvent`` codes the firmware writes (``[4.6] src/main/blackbox/blackbox.h:50-60``;
#: 10-12 are declared UNUSED there and never written).
EVENT_KINDS = {
    0: "SYNC_BEEP",
    13: "INFLIGHT_ADJUSTMENT",
    14: "LOGGING_RESUME",
    15: "DISARM",
    30: "FLIGHTMODE",
    255: "LOG_END",
}

_LOG_END_TEXT = b"End of log\x00"
#: ``FLIGHT_LOG_EVENT_INFLIGHT_ADJUSTMENT_FUNCTION_FLOAT_VALUE_FLAG``
#: (``[4.6] src/main/blackbox/blackbox_fielddefs.h:184``).
_FLOAT_FLAG = 0x80


def _byte(stream: Iterator[int | None]) -> int:
    # orangebox's Reader yields None at the end of the data instead of stopping.
    value = next(stream, None)
    if value is None:
        raise BlackboxError("an event's payload runs past the end of the log")
    return value


def _unsigned(stream: Iterator[int | None]) -> int:
    """The firmware's unsigned varint: 7 bits a byte, low first, at most 5 bytes for 32."""
    value = 0
    for shift in range(0, 35, 7):
        byte = _byte(stream)
        value |= (byte & 0x7F) << shift
        if byte < 0x80:
            return value
    raise BlackboxError("an event's payload runs past the end of the log")


def _signed(stream: Iterator[int | None]) -> int:
    raw = _unsigned(stream)
    return (raw >> 1) ^ -(raw & 1)  # zig-zag


def read_event(code: int, stream: Iterator[int | None]) -> tuple[str, dict[str, Any]] | None:
    """(kind, data) of the event with ``code`` whose payload ``stream`` holds; None for a code
    the firmware does not write or a payload cut short (the caller then resynchronises)."""
    kind = EVENT_KINDS.get(code)
    if kind is None:
        return None
    try:
        if kind == "SYNC_BEEP":
            return kind, {"time_us": _unsigned(stream)}
        if kind == "INFLIGHT_ADJUSTMENT":
            function = _byte(stream)
            if function & _FLOAT_FLAG:
                raw = bytes(_byte(stream) for _ in range(4))
                value: float = struct.unpack("<f", raw)[0]
                return kind, {"function": function & ~_FLOAT_FLAG, "value": value}
            return kind, {"function": function, "value": _signed(stream)}
        if kind == "LOGGING_RESUME":
            return kind, {"log_iteration": _unsigned(stream), "time_us": _unsigned(stream)}
        if kind == "DISARM":
            reason = _unsigned(stream)
            return kind, {"reason": reason, "reason_name": disarm_reason_name(reason)}
        if kind == "FLIGHTMODE":
            return kind, {
                "mode_switch_mask": _unsigned(stream),
                "previous_mode_switch_mask": _unsigned(stream),
            }
        # LOG_END: only with its text, else it is an 0xFF after an 'E' in damaged data.
        text = bytes(_byte(stream) for _ in range(len(_LOG_END_TEXT)))
        return (kind, {}) if text == _LOG_END_TEXT else None
    except BlackboxError:  # cut short: the caller resynchronises
        return None


def disarm_reason_name(reason: int) -> str:
    return DISARM_REASONS.get(reason, f"REASON_{reason}")


class EventKeepingParser(Parser):
    """orangebox's parser, keeping every event with the number of main frames before it."""

    def __init__(self, *args: Any, planned: bool = True, **kwargs: Any) -> None:
        #: (main frames yielded before it, kind, data), in the order of the log.
        self.kept: list[tuple[int, str, dict[str, Any]]] = []
        self.saw_log_end = False
        self._yielded = 0
        #: Each frame type's :class:`FramePlan` (None: orangebox's own loop), made at its
        #: first frame; ``planned=False`` decodes every frame with orangebox's loop.
        self._plans: dict[Any, FramePlan | None] = {}
        self._planned = planned
        super().__init__(*args, **kwargs)

    def frames(self) -> Iterator[Any]:
        # orangebox parses the event after frame N while the consumer holds frame N (it
        # yields a frame before reading on), so the count below is the frames before it.
        for frame in super().frames():
            self._yielded += 1
            yield frame

    def _parse_frame(self, fdefs: Any, reader: Any) -> Any:
        """The frame type's plan where it has one; else 0.4.0's loop over a frame's fields,
        with the frame built in a list: 0.4.0 grows a
        tuple one field at a time, copying it each time, a fifth of a SITL log's decode.  The
        decoders and predictors are 0.4.0's own; a predictor reads the fields so far by
        index (``Context.get_current_value_by_name``), which a list answers as a tuple did."""
        ctx = self._ctx
        frame_type = ctx.frame_type
        if frame_type in self._plans:
            plan = self._plans[frame_type]
        else:
            plan = self._plans[frame_type] = FramePlan.of(fdefs, ctx) if self._planned else None
        if plan is not None:
            # orangebox's Reader holds the log's bytes and its position (0.4.0 is pinned).
            planned, reader._frame_data_ptr = plan.decode(
                reader._frame_data, reader._frame_data_ptr, ctx
            )
            return Frame(frame_type, tuple(planned))
        ctx.field_index = 0
        count = ctx.field_def_counts[ctx.frame_type]
        values: list[Any] = []
        ctx.current_frame = values
        while ctx.field_index < count:
            fdef = fdefs[ctx.field_index]
            raw = fdef.decoderfun(reader, ctx)
            if isinstance(raw, tuple):  # an encoding that packs several fields
                for value in raw:
                    values.append(fdefs[ctx.field_index].predictorfun(value, ctx))
                    ctx.field_index += 1
            else:
                values.append(fdef.predictorfun(raw, ctx))
                ctx.field_index += 1
        return Frame(ctx.frame_type, tuple(values))

    def _parse_event_frame(self, reader: Any) -> bool:
        code = next(reader)
        if code is None:
            return False  # 'E' was the last byte: the caller ends on the missing data
        after_code = reader.tell()
        event = read_event(code, reader)
        if event is None:
            # Unknown or damaged: back to where 0.4.0 itself would be, and let it resync.
            reader.seek(after_code)
            return False
        self.kept.append((self._yielded, *event))
        if event[0] == "LOG_END":
            self.saw_log_end = True
            self._end_of_log = True  # what 0.4.0's own LOG_END handling sets to stop
        return True
