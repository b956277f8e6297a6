"""Compiles a message's wire fields into its decode and encode functions.

Fixed-size fields next to each other become one run, read and written by one precompiled
:class:`struct.Struct` (the telemetry messages are nothing else); variable fields (PStr, arrays
to the end or after a count, text to the end) are steps of their own. The functions keep the
rules of the hand-written codecs they replaced, messages included:

* a payload too short raises :class:`MspDecodeError` naming the first byte count that was
  missing, ``needs at least N bytes``, as reading the fields one by one would;
* trailing bytes are ignored; the optional tail is read while bytes remain (see
  :class:`.wire_types.Tail`) and written up to its first None;
* a value that does not fit its wire type raises :class:`MspRequestError`.
"""

from __future__ import annotations

import struct
from bisect import bisect_right
from collections.abc import Callable, Sequence
from functools import lru_cache
from itertools import chain
from operator import attrgetter, itemgetter
from typing import Any

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol.messages.wire_types import (
    Array,
    Counted,
    Int,
    Nested,
    PStr,
    Raw,
    RestArray,
    RestText,
    Tail,
    Text,
    WireField,
)

#: What a value that does not fit its wire type raises inside :mod:`struct` and ``str.encode``.
FIT_ERRORS = (struct.error, OverflowError, UnicodeEncodeError)


def short_payload(what: str, end: int, length: int) -> MspDecodeError:
    """The error of a payload that ends before byte ``end`` of the field being read."""
    return MspDecodeError(f"{what}: needs at least {end} bytes, got {length}")


def does_not_fit(msg: object, exc: Exception) -> MspRequestError:
    return MspRequestError(f"{type(msg).__name__}: a field does not fit its wire type ({exc})")


def text_from_wire(raw: bytes) -> str:
    """Latin-1 keeps every byte, so text fields always re-encode to the same bytes."""
    return raw.split(b"\0", 1)[0].decode("latin-1")


def text_to_wire(value: str, size: int | None = None) -> bytes:
    data = value.encode("latin-1")
    if size is not None and len(data) > size:
        raise MspRequestError(f"text {value!r} is longer than its {size}-byte field")
    return data


def _getter(names: Sequence[str]) -> Callable[[Any], tuple[Any, ...]]:
    """The values of the named attributes as a tuple, whatever their number."""
    if not names:
        return lambda obj: ()
    if len(names) == 1:
        name = names[0]
        return lambda obj: (getattr(obj, name),)
    return attrgetter(*names)


def _record_ints(record: Any) -> tuple[list[Int], list[str]]:
    """The integer fields of a record used inside a message (only those are allowed there)."""
    layout = getattr(record, "LAYOUT", None)
    if layout is None or not all(
        isinstance(f.wire, Int) and not f.pad_bytes and not f.in_tail for f in layout.fields
    ):
        raise TypeError(f"{record!r}: an item or nested record must be integers only")
    return [f.wire for f in layout.fields], [f.name for f in layout.fields]


@lru_cache(maxsize=256)
def _array_struct(body: str, count: int) -> struct.Struct:
    return struct.Struct("<" + (f"{count}{body}" if len(body) == 1 else body * count))


class IntRun:
    """Integers in a row read with one struct, for the hand-written codecs: a payload too short
    raises the error the derived ones raise. ``codes`` has one struct character per field."""

    __slots__ = ("struct", "size", "ends")

    def __init__(self, codes: str) -> None:
        self.struct = struct.Struct("<" + codes)
        self.size = self.struct.size
        self.ends = tuple(_cumulative(struct.calcsize("<" + code) for code in codes))

    def unpack(self, payload: Any, pos: int, what: str) -> tuple[int, ...]:
        length = len(payload)
        if length - pos < self.size:
            end = pos + self.ends[bisect_right(self.ends, length - pos)]
            raise short_payload(what, end, length)
        return self.struct.unpack_from(payload, pos)


class _Part:
    """One fixed-size field inside a run: its struct format, the ends of the elements the old
    readers took one at a time (for the short-payload message), and its conversions."""

    __slots__ = ("fmt", "ends", "size", "nvals", "sliced", "int_array", "from_wire", "to_flat")

    def __init__(self, field: WireField) -> None:
        wire = field.wire
        self.int_array = isinstance(wire, Array)
        self.from_wire: Callable[[Any], Any] | None = None
        self.to_flat: Callable[[Any], Sequence[Any]] | None = None
        self.sliced = False
        if isinstance(wire, Int):
            fmt, ends, self.nvals = wire.code, [wire.size], 1
        elif isinstance(wire, Text):
            fmt, ends, self.nvals = f"{wire.size}s", [wire.size], 1
            size = wire.size
            self.from_wire = text_from_wire
            self.to_flat = lambda value: (text_to_wire(value, size),)
        elif isinstance(wire, Raw):
            fmt, ends, self.nvals = f"{wire.size}s", [wire.size], 1
            self.to_flat = _raw_check(field.name, wire.size)
        elif isinstance(wire, Array):
            step = wire.item.size
            fmt, self.nvals, self.sliced = f"{wire.count}{wire.item.code}", wire.count, True
            ends = [step * (i + 1) for i in range(wire.count)]
            self.to_flat = _count_check(field.name, wire)
        elif isinstance(wire, Nested):
            ints, names = _record_ints(wire.record)
            fmt, self.nvals, self.sliced = "".join(i.code for i in ints), len(ints), True
            ends = _cumulative(i.size for i in ints)
            record = wire.record
            self.from_wire = lambda flat: record(*flat)
            self.to_flat = _getter(names)
        else:
            raise TypeError(f"field {field.name}: {wire!r} has no fixed size")
        pad = field.pad_bytes
        self.fmt = (f"{pad}x" if pad else "") + fmt
        self.ends = [*range(1, pad + 1), *(pad + end for end in ends)]
        self.size = self.ends[-1]


def _cumulative(sizes: Any) -> list[int]:
    ends, total = [], 0
    for size in sizes:
        total += size
        ends.append(total)
    return ends


def _raw_check(name: str, size: int) -> Callable[[bytes], Sequence[bytes]]:
    def to_flat(value: bytes) -> Sequence[bytes]:
        if len(value) != size:
            raise MspRequestError(f"{name} must be {size} bytes, got {len(value)}")
        return (value,)

    return to_flat


def _count_check(name: str, wire: Array) -> Callable[[Sequence[int]], Sequence[int]]:
    count, fill = wire.count, wire.fill
    message = wire.count_error or f"{name} holds {{count}} values, got {{got}}"

    def to_flat(values: Sequence[int]) -> Sequence[int]:
        got = len(values)
        if got == count:
            return values
        if fill is None or got > count:
            raise MspRequestError(message.format(count=count, got=got))
        return (*values, *(fill,) * (count - got))

    return to_flat


class _Run:
    """Consecutive fixed-size fields, one struct for all of them."""

    __slots__ = (
        "struct",
        "size",
        "ends",
        "count",
        "regroup",
        "converters",
        "flatteners",
        "array_counts",
    )

    def __init__(self, parts: Sequence[_Part]) -> None:
        self.struct = struct.Struct("<" + "".join(p.fmt for p in parts))
        self.size = self.struct.size
        self.count = len(parts)
        ends: list[int] = []
        for part in parts:
            base = ends[-1] if ends else 0
            ends.extend(base + end for end in part.ends)
        self.ends = tuple(ends)
        # The struct yields one flat tuple; arrays and records take a slice of it.
        keys: list[int | slice] = []
        index = 0
        for part in parts:
            keys.append(slice(index, index + part.nvals) if part.sliced else index)
            index += part.nvals
        self.regroup: Callable[[tuple[Any, ...]], Sequence[Any]] | None = None
        if any(part.sliced for part in parts):
            if len(keys) == 1:
                only = keys[0]
                self.regroup = lambda flat: (flat[only],)
            else:
                self.regroup = itemgetter(*keys)
        self.converters = tuple(
            (i, part.from_wire) for i, part in enumerate(parts) if part.from_wire is not None
        )
        flatteners = tuple(part.to_flat for part in parts)
        self.flatteners = None if all(f is None for f in flatteners) else flatteners
        # Only integer arrays (MSP_RAW_IMU, MSP_MOTOR): when every length is right, the values
        # are simply chained, without a call per field.
        all_arrays = bool(parts) and all(part.int_array for part in parts)
        self.array_counts = tuple(part.nvals for part in parts) if all_arrays else None

    @property
    def plain(self) -> bool:
        """Every field is one integer: the struct's tuple is the field values."""
        return self.regroup is None and not self.converters and self.flatteners is None

    def values(self, payload: Any, pos: int, what: str) -> Sequence[Any]:
        length = len(payload)
        if length - pos < self.size:
            end = pos + self.ends[bisect_right(self.ends, length - pos)]
            raise short_payload(what, end, length)
        values: Sequence[Any] = self.struct.unpack_from(payload, pos)
        if self.regroup is not None:
            values = self.regroup(values)  # type: ignore[arg-type]
        if self.converters:
            values = list(values)
            for i, convert in self.converters:
                values[i] = convert(values[i])
        return values

    def read(self, payload: Any, pos: int, what: str, out: list[Any]) -> int:
        out.extend(self.values(payload, pos, what))
        return pos + self.size

    def write(self, values: Sequence[Any]) -> bytes:
        if self.flatteners is None:
            return self.struct.pack(*values)
        if self.array_counts is not None and tuple(map(len, values)) == self.array_counts:
            return self.struct.pack(*chain.from_iterable(values))
        flat: list[Any] = []
        for value, flatten in zip(values, self.flatteners, strict=True):
            if flatten is None:
                flat.append(value)
            else:
                flat.extend(flatten(value))
        return self.struct.pack(*flat)


class _Items:
    """The items of an array whose length is known only when decoding."""

    __slots__ = ("body", "ends", "size", "record", "get", "nvals")

    def __init__(self, item: Any) -> None:
        names: list[str] = []
        if isinstance(item, Int):
            ints, self.record = [item], None
        else:
            (ints, names), self.record = _record_ints(item), item
        self.body = "".join(i.code for i in ints)
        self.ends = tuple(_cumulative(i.size for i in ints))
        self.size = self.ends[-1]
        self.nvals = len(ints)
        self.get = _getter(names)

    def unpack(self, payload: Any, pos: int, count: int) -> tuple[Any, ...]:
        flat = _array_struct(self.body, count).unpack_from(payload, pos)
        if self.record is None:
            return flat
        k, record = self.nvals, self.record
        return tuple(record(*flat[i : i + k]) for i in range(0, len(flat), k))

    def pack(self, values: Sequence[Any]) -> bytes:
        packer = _array_struct(self.body, len(values))
        if self.record is None:
            return packer.pack(*values)
        flat: list[Any] = []
        for value in values:
            flat.extend(self.get(value))
        return packer.pack(*flat)


class _PStrStep:
    count, size = 1, None

    def read(self, payload: Any, pos: int, what: str, out: list[Any]) -> int:
        length = len(payload)
        if length <= pos:
            raise short_payload(what, pos + 1, length)
        end = pos + 1 + payload[pos]
        if end > length:
            raise short_payload(what, end, length)
        out.append(text_from_wire(payload[pos + 1 : end]))
        return end

    def write(self, values: Sequence[Any]) -> bytes:
        data = text_to_wire(values[0])
        if len(data) > 0xFF:
            raise MspRequestError(f"text {values[0]!r} is longer than a U8 count allows (255)")
        return bytes((len(data),)) + data


class _RestTextStep:
    count, size = 1, None

    def read(self, payload: Any, pos: int, what: str, out: list[Any]) -> int:
        out.append(text_from_wire(payload[pos:]))
        return len(payload)

    def write(self, values: Sequence[Any]) -> bytes:
        return text_to_wire(values[0])


class _RestArrayStep:
    count, size = 1, None

    def __init__(self, wire: RestArray) -> None:
        self.items = _Items(wire.item)
        self.label = wire.label

    def read(self, payload: Any, pos: int, what: str, out: list[Any]) -> int:
        left, size = len(payload) - pos, self.items.size
        if left % size:
            label = f"{what} {self.label}" if self.label else what
            raise MspDecodeError(
                f"{label}: {left} bytes is not a whole number of {size}-byte items"
            )
        out.append(self.items.unpack(payload, pos, left // size))
        return len(payload)

    def write(self, values: Sequence[Any]) -> bytes:
        return self.items.pack(values[0])


class _CountedStep:
    count, size = 1, None

    def __init__(self, wire: Counted) -> None:
        self.counter = struct.Struct("<" + wire.count.code)
        self.items = _Items(wire.item)

    def read(self, payload: Any, pos: int, what: str, out: list[Any]) -> int:
        length, items = len(payload), self.items
        start = pos + self.counter.size
        if length < start:
            raise short_payload(what, start, length)
        (count,) = self.counter.unpack_from(payload, pos)
        if length - start < count * items.size:
            whole, cut = divmod(length - start, items.size)
            end = start + whole * items.size + items.ends[bisect_right(items.ends, cut)]
            raise short_payload(what, end, length)
        out.append(items.unpack(payload, start, count))
        return start + count * items.size

    def write(self, values: Sequence[Any]) -> bytes:
        return self.counter.pack(len(values[0])) + self.items.pack(values[0])


_Step = _Run | _PStrStep | _RestTextStep | _RestArrayStep | _CountedStep


def _variable_step(field: WireField) -> _Step:
    if field.pad_bytes:
        raise TypeError(f"field {field.name}: padding only goes before fixed-size fields")
    wire = field.wire
    if isinstance(wire, PStr):
        return _PStrStep()
    if isinstance(wire, RestText):
        return _RestTextStep()
    if isinstance(wire, RestArray):
        return _RestArrayStep(wire)
    if isinstance(wire, Counted):
        return _CountedStep(wire)
    raise TypeError(f"field {field.name}: unknown wire type {wire!r}")


def _steps(fields: Sequence[WireField]) -> list[_Step]:
    """Runs of fixed-size fields, and a step of its own for each variable one."""
    steps: list[_Step] = []
    pending: list[_Part] = []
    for field in fields:
        if field.fixed_size is not None:
            pending.append(_Part(field))
            continue
        if pending:
            steps.append(_Run(pending))
            pending = []
        steps.append(_variable_step(field))
    if pending or not steps:
        steps.append(_Run(pending))
    return steps


class Layout:
    """One record's fields in wire order, compiled.

    ``decode_values(payload)`` gives the field values present (a prefix when the optional tail
    is cut short), ``encode(record)`` the payload; :func:`.layout.msp_message` installs the
    ``decoder``/``encoder`` as the class's ``decode``/``encode``, and hand-written overrides
    call these for the fixed parts.
    """

    def __init__(self, record_name: str, fields: Sequence[WireField], tail: Tail | None) -> None:
        self.record_name = record_name
        self.fields = tuple(fields)
        self.tail = tail
        self._what = f"MSP {record_name}"
        for field in self.fields[:-1]:
            if isinstance(field.wire, RestArray | RestText):
                raise TypeError(f"{record_name}.{field.name} runs to the end: it must be last")
        head = [f for f in self.fields if not f.in_tail]
        tail_fields = [f for f in self.fields if f.in_tail]
        if (
            tail is not None
            and tail.cut_is_absent
            and any(f.fixed_size is None for f in tail_fields)
        ):
            raise TypeError(f"{record_name}: a tail read only when whole needs fixed sizes")
        self._head_steps = _steps(head)
        self._tail_steps = [_steps([f])[0] for f in tail_fields]
        self._head_count, self._tail_count = len(head), len(tail_fields)
        # Encoding stops at the first None of a tail field whose absent value is None; a field
        # with another default (MSP_REBOOT's mode) is always written, and None does not fit it.
        self._none_is_absent = tuple(f.absent is None for f in tail_fields)
        all_fixed = all(f.fixed_size is not None for f in self.fields)
        # Head and complete tail in one struct: the payload of the firmware the code is for.
        self._full = _Run([_Part(f) for f in self.fields]) if all_fixed else None
        #: Bytes on the wire when that never varies, else None.
        self.size = self._full.size if self._full is not None and not tail_fields else None
        self._get = _getter([f.name for f in self.fields])
        self.encode: Callable[[Any], bytes] = self.encoder()

    def decode_values(self, payload: Any) -> Sequence[Any]:
        full, what = self._full, self._what
        if full is not None and len(payload) >= full.size:
            return full.values(payload, 0, what)
        out: list[Any] = []
        pos = 0
        for step in self._head_steps:
            pos = step.read(payload, pos, what, out)
        length = len(payload)
        cut_is_absent = self.tail is not None and self.tail.cut_is_absent
        for step in self._tail_steps:
            left = length - pos
            if left <= 0 or (cut_is_absent and left < (step.size or 0)):
                break
            pos = step.read(payload, pos, what, out)
        return out

    def encode_values(self, values: Sequence[Any]) -> bytes:
        present = self._tail_count
        for i in range(self._tail_count):
            if values[self._head_count + i] is None and self._none_is_absent[i]:
                present = i
                break
        if self._full is not None and present == self._tail_count:
            return self._full.write(values)
        parts: list[bytes] = []
        i = 0
        for step in self._head_steps:
            parts.append(step.write(values[i : i + step.count]))
            i += step.count
        for step in self._tail_steps[:present]:
            parts.append(step.write(values[i : i + 1]))
            i += 1
        return b"".join(parts)

    def decoder(self, validates: bool) -> Callable[[Any, Any], Any]:
        """``decode(cls, payload)``. ``validates``: the class checks its values in
        ``__post_init__``; a payload it refuses is a :class:`MspDecodeError` here."""
        full, what = self._full, self._what
        if full is not None and full.plain and not self._tail_count and not validates:
            unpack, size, ends = full.struct.unpack_from, full.size, full.ends

            def decode_plain(cls: Any, payload: Any) -> Any:
                if len(payload) < size:
                    end = ends[bisect_right(ends, len(payload))]
                    raise short_payload(what, end, len(payload))
                return cls(*unpack(payload))

            return decode_plain
        decode_values = self.decode_values
        if not validates:
            return lambda cls, payload: cls(*decode_values(payload))

        def decode_validated(cls: Any, payload: Any) -> Any:
            values = decode_values(payload)
            try:
                return cls(*values)
            except MspRequestError as exc:
                raise MspDecodeError(str(exc)) from exc

        return decode_validated

    def encoder(self) -> Callable[[Any], bytes]:
        """``encode(record)``; a value that does not fit raises :class:`MspRequestError`."""
        get, full = self._get, self._full
        if full is not None and full.flatteners is None and not self._tail_count:
            pack = full.struct.pack

            def encode_plain(record: Any) -> bytes:
                try:
                    return pack(*get(record))
                except FIT_ERRORS as exc:
                    raise does_not_fit(record, exc) from exc

            return encode_plain
        # Fixed size or a single variable field, without a tail: straight to that one step.
        encode_values = self.encode_values
        if not self._tail_count and (full is not None or len(self._head_steps) == 1):
            encode_values = full.write if full is not None else self._head_steps[0].write

        def encode(record: Any) -> bytes:
            try:
                return encode_values(get(record))
            except FIT_ERRORS as exc:
                raise does_not_fit(record, exc) from exc

        return encode
