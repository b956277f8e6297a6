"""A frame's fields decoded straight from the log's bytes by a plan made once per frame type.

orangebox 0.4.0 decodes every field through two calls (its decoder reads the bytes one
``next()`` at a time, its predictor looks the past value up through the context), for some
30 fields a frame and hundreds of frames a second of flight: decoding was the largest cost
of a scenario run after the flight.  :class:`FramePlan` reads the same
encodings from the byte string by index and applies the common predictors inline, giving
the same numbers (``tests/unit/blackbox/test_frame_plan.py`` decodes every log at hand both
ways and compares them frame by frame).  What it does not know it leaves to orangebox: a
field whose encoding it does not read makes no plan (the caller keeps orangebox's own loop),
and a predictor it does not apply (the increment, motor[0], GPS home, the GPS time) is
orangebox's own function, called with the context as orangebox sets it.

The compiled kernel follows the same plans (:mod:`bfsitl.blackbox.compiled_frames`), for a
whole log at once; this module is its reference and the road for any log it leaves.

orangebox's behaviour is kept where it differs from the firmware's: its ``tag8_8svb`` group
ends one field early at the end of a frame (and a lone such field there reads nothing); a
frame type where that would happen makes no plan.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from orangebox.decoders import decoder_map
from orangebox.predictors import predictor_map
from orangebox.tools import sign_extend_14bit

# What a step reads.
_SIGNED_VB = 0
_UNSIGNED_VB = 1
_NEG_14BIT = 2
_TAG8_8SVB = 3  # a header byte, then a signed varint for each bit set, up to 8 fields
_TAG2_3S32 = 4  # three fields
_TAG8_4S16 = 5  # four fields (data version 2)
_NULL = 6

#: orangebox's decoder functions, by identity, and what each reads.  Its tag8_4s16 is made
#: per data version: version 2's is the one read here (version 1's is an orangebox TODO).
_ENCODINGS = {
    decoder_map[0]: _SIGNED_VB,
    decoder_map[1]: _UNSIGNED_VB,
    decoder_map[3]: _NEG_14BIT,
    decoder_map[6]: _TAG8_8SVB,
    decoder_map[7]: _TAG2_3S32,
    decoder_map[8](2): _TAG8_4S16,
    decoder_map[9]: _NULL,
}
_GROUP_SIZES = {_TAG2_3S32: 3, _TAG8_4S16: 4}

# How a value is predicted.
_NONE = 0
_PREVIOUS = 1  # plus the last frame's value (0 without one)
_STRAIGHT_LINE = 2  # plus 2 x the last minus the one before (the last without one)
_AVERAGE_2 = 3  # plus the truncated mean of the last two
_CONSTANT = 4  # plus a number from the headers (minthrottle, 1500, vbatref, minmotor)
_INCREMENT = 5  # the loop iteration: 1 + the last + the iterations not logged since
_CALL = 6  # orangebox's own predictor

_PREDICTORS = {
    predictor_map[0]: _NONE,
    predictor_map[1]: _PREVIOUS,
    predictor_map[2]: _STRAIGHT_LINE,
    predictor_map[3]: _AVERAGE_2,
    predictor_map[6]: _INCREMENT,
}
_CONSTANT_PREDICTORS = tuple(predictor_map[key] for key in (4, 8, 9, 11))


class FramePlan:
    """How one frame type's fields are read and predicted (module docstring)."""

    def __init__(
        self,
        steps: tuple[tuple[int, int], ...],
        runs: tuple[tuple[int, int, int, Any], ...],
    ) -> None:
        #: (what to read, how many fields), in the order of the frame; neighbouring signed
        #: varints are one step.
        self.steps = steps
        #: How the fields are predicted, as runs of neighbouring fields predicted alike:
        #: (how, first, end, with what: the constant, or orangebox's predictor to call),
        #: each run done at once where both past frames are whole (one call or
        #: orangebox-dependent predictor per run).
        self.runs = runs
        #: The iterations not logged after one, by its place in the I-frame interval:
        #: orangebox walks them one by one for every frame (16 calls at 1/16).
        self._skipped: dict[int, int] = {}

    @classmethod
    def of(cls, fdefs: Sequence[Any], ctx: Any) -> FramePlan | None:
        """The plan for a frame type's field definitions, or None where orangebox must
        decode it itself."""
        count = len(fdefs)
        steps: list[tuple[int, int]] = []
        index = 0
        while index < count:
            what = _ENCODINGS.get(fdefs[index].decoderfun)
            if what is None:
                return None
            if what == _TAG8_8SVB:
                run = 1
                while (
                    run < 8
                    and index + run < count
                    and fdefs[index + run].decoderfun is (fdefs[index].decoderfun)
                ):
                    run += 1
                if index + run == count:
                    return None  # orangebox's group ends early here (module docstring)
                if run == 1:
                    what = _SIGNED_VB
            else:
                run = _GROUP_SIZES.get(what, 1)
                if index + run > count:
                    return None
            if what == _SIGNED_VB and steps and steps[-1][0] == _SIGNED_VB:
                steps[-1] = (_SIGNED_VB, steps[-1][1] + 1)  # read in one inner loop
            else:
                steps.append((what, run))
            index += run
        predictors: list[tuple[int, Any]] = []
        for fdef in fdefs:
            how = _PREDICTORS.get(fdef.predictorfun)
            if how is not None:
                predictors.append((how, None))
            elif fdef.predictorfun in _CONSTANT_PREDICTORS:
                try:
                    constant = fdef.predictorfun(0, ctx)
                except (TypeError, ValueError, KeyError, IndexError):
                    return None
                if type(constant) is not int:
                    return None
                predictors.append((_CONSTANT, constant))
            else:
                predictors.append((_CALL, fdef.predictorfun))
        return cls(tuple(steps), _runs(tuple(predictors)))

    def decode(self, data: bytes, position: int, ctx: Any) -> tuple[list[Any], int]:
        """The frame's values from ``data`` at ``position``, and where the frame ends.  Raises
        IndexError where the data ends inside the frame (a log cut short)."""
        raw, position = _read(self.steps, data, position)
        values: list[Any] = []
        ctx.current_frame = values
        last = ctx.past_frames[0].data
        before = ctx.past_frames[1].data
        if len(last) < len(raw) or len(before) < len(raw):
            last, before = _with_defaults(last, before, len(raw))
        self._predict_runs(raw, last, before, values, ctx)
        return values, position

    def _predict_runs(
        self,
        raw: list[int],
        last: Sequence[Any],
        before: Sequence[Any],
        values: list[Any],
        ctx: Any,
    ) -> None:
        """:meth:`decode`'s predictions, a run of fields at a time."""
        for how, first, end, what in self.runs:
            if how == _AVERAGE_2:
                values.extend(
                    [
                        value + int((previous + earlier) / 2)
                        for value, previous, earlier in zip(
                            raw[first:end], last[first:end], before[first:end], strict=True
                        )
                    ]
                )
            elif how == _PREVIOUS:
                values.extend([a + b for a, b in zip(raw[first:end], last[first:end], strict=True)])
            elif how == _NONE:
                values.extend(raw[first:end])
            elif how == _STRAIGHT_LINE:
                values.extend(
                    [
                        value + 2 * previous - earlier
                        for value, previous, earlier in zip(
                            raw[first:end], last[first:end], before[first:end], strict=True
                        )
                    ]
                )
            elif how == _CONSTANT:
                values.extend([value + what for value in raw[first:end]])
            elif how == _INCREMENT:
                values.append(1 + last[first] + self._skip(ctx))
            else:
                ctx.field_index = first
                values.append(what(raw[first], ctx))
        ctx.field_index = len(values)

    def _skip(self, ctx: Any) -> int:
        """orangebox's ``Context.count_skipped_frames``: which iterations are logged
        depends only on the iteration's place in the I-frame interval."""
        if ctx.last_iter == -1:
            return 0
        place = ctx.last_iter % ctx.i_interval
        skipped = self._skipped.get(place)
        if skipped is None:
            skipped = self._skipped[place] = ctx.count_skipped_frames()
        return skipped


def _with_defaults(
    last: Sequence[Any], before: Sequence[Any], count: int
) -> tuple[list[Any], list[Any]]:
    """The two past frames as orangebox reads a field they do not have (the first frames of
    a log): the last one's value 0, the one before's the last one's."""
    last = [last[index] if index < len(last) else 0 for index in range(count)]
    before = [before[index] if index < len(before) else last[index] for index in range(count)]
    return last, before


def _runs(predictors: tuple[tuple[int, Any], ...]) -> tuple[tuple[int, int, int, Any], ...]:
    """Neighbouring fields predicted alike (the same constant) as one run; the increment and
    orangebox's own predictors one field each."""
    runs: list[tuple[int, int, int, Any]] = []
    for index, (how, what) in enumerate(predictors):
        if runs and how not in (_INCREMENT, _CALL):
            last_how, first, _end, last_what = runs[-1]
            if last_how == how and last_what == what:
                runs[-1] = (how, first, index + 1, what)
                continue
        runs.append((how, index, index + 1, what))
    return tuple(runs)


def _read(steps: tuple[tuple[int, int], ...], data: bytes, at: int) -> tuple[list[int], int]:
    """The raw (unpredicted) values of a frame's fields."""
    out: list[int] = []
    for what, count in steps:
        if what == _SIGNED_VB:  # ``count`` fields one after the other
            for _ in range(count):
                value = data[at]
                at += 1
                if value >= 0x80:
                    value, at = _varint_rest(value, data, at)
                    value %= 0x100000000
                out.append((value >> 1) ^ -(value & 1))  # zig-zag
        elif what == _TAG8_8SVB:
            header = data[at]
            at += 1
            for _ in range(count):
                if header & 1:
                    byte = data[at]
                    at += 1
                    if byte < 0x80:
                        value = byte
                    else:
                        value, at = _varint_rest(byte, data, at)
                    out.append(((value % 0x100000000) >> 1) ^ -(value & 1))
                else:
                    out.append(0)
                header >>= 1
        elif what == _UNSIGNED_VB:
            byte = data[at]
            at += 1
            if byte < 0x80:
                out.append(byte)
            else:
                value, at = _varint_rest(byte, data, at)
                out.append(value)
        elif what == _TAG8_4S16:
            at = _tag8_4s16(data, at, out)
        elif what == _TAG2_3S32:
            at = _tag2_3s32(data, at, out)
        elif what == _NEG_14BIT:
            byte = data[at]
            at += 1
            value, at = (byte, at) if byte < 0x80 else _varint_rest(byte, data, at)
            out.append(-sign_extend_14bit(value))
        else:  # _NULL: nothing written
            out.append(0)
    return out, at


def _varint_rest(first: int, data: bytes, at: int) -> tuple[int, int]:
    """An unsigned varint whose first byte (with its high bit set) was ``first``: 7 bits a
    byte, low first, at most 5 bytes; orangebox reads 5 bytes that never end as 0."""
    result = first & 0x7F
    shift = 7
    for _ in range(4):
        byte = data[at]
        at += 1
        result |= (byte & 0x7F) << shift
        if byte < 0x80:
            return result, at
        shift += 7
    return 0, at


def _signed(value: int, bits: int) -> int:
    """``value`` (``bits`` wide) as two's complement."""
    return value - (1 << bits) if value & (1 << (bits - 1)) else value


def _tag8_4s16(data: bytes, at: int, out: list[int]) -> int:
    """Four fields: a selector byte (2 bits each: zero, 4, 8 or 16 bits), then the fields
    packed in nibbles, high nibble first."""
    selector = data[at]
    at += 1
    nibble = False  # whether half of ``buffer`` is still unread
    buffer = 0
    for _ in range(4):
        kind = selector & 3
        if kind == 0:
            out.append(0)
        elif kind == 1:
            if nibble:
                out.append(_signed(buffer & 0x0F, 4))
            else:
                buffer = data[at]
                at += 1
                out.append(_signed(buffer >> 4, 4))
            nibble = not nibble
        elif kind == 2:
            if nibble:
                high = (buffer & 0x0F) << 4
                buffer = data[at]
                at += 1
                out.append(_signed(high | (buffer >> 4), 8))
            else:
                out.append(_signed(data[at], 8))
                at += 1
        else:
            first, second = data[at], data[at + 1]
            at += 2
            if nibble:
                out.append(_signed(((buffer & 0x0F) << 12) | (first << 4) | (second >> 4), 16))
                buffer = second
            else:
                out.append(_signed((first << 8) | second, 16))
        selector >>= 2
    return at


def _tag2_3s32(data: bytes, at: int, out: list[int]) -> int:
    """Three fields: the lead byte's top 2 bits say 2, 4 or 6 bits each, or a size per field
    (8, 16, 24 bits signed; 32 bits as it is)."""
    lead = data[at]
    at += 1
    width = lead >> 6
    if width == 0:
        out.extend((_signed((lead >> 4) & 3, 2), _signed((lead >> 2) & 3, 2), _signed(lead & 3, 2)))
    elif width == 1:
        second = data[at]
        at += 1
        out.extend((_signed(lead & 0x0F, 4), _signed(second >> 4, 4), _signed(second & 0x0F, 4)))
    elif width == 2:
        second, third = data[at], data[at + 1]
        at += 2
        out.extend((_signed(lead & 0x3F, 6), _signed(second & 0x3F, 6), _signed(third & 0x3F, 6)))
    else:
        for _ in range(3):
            size = lead & 3
            if size == 0:
                out.append(_signed(data[at], 8))
                at += 1
            elif size == 1:
                out.append(_signed(data[at] | (data[at + 1] << 8), 16))
                at += 2
            elif size == 2:
                out.append(_signed(data[at] | (data[at + 1] << 8) | (data[at + 2] << 16), 24))
                at += 3
            else:
                value = data[at] | (data[at + 1] << 8) | (data[at + 2] << 16)
                out.append(value | (data[at + 3] << 24))
                at += 4
            lead >>= 2
    return at
