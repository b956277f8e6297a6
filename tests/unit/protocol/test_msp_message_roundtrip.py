"""Every MSP message class, found by walking ``bfsitl.protocol.messages``, against its layout.

For a class with a declared layout the test builds random valid messages from the wire types of
its fields (within their ranges; the optional tail as a prefix of present fields; the values a
``__post_init__`` accepts) and, independently of the codec, the payload the firmware would send
for them, field by field. Then: ``decode(encode(x)) == x``, ``encode(x)`` is that payload,
``encode(decode(b)) == b``; a payload cut inside a field raises :class:`MspDecodeError`; bytes
after a complete payload are ignored; a value that does not fit its wire type raises
:class:`MspRequestError`. The classes that decode by hand get their cases written here.

A new declared message is covered without touching this file; a new hand-written one fails
until it gets a case below, and the count of messages is pinned so none goes missing.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import pkgutil
import struct
from collections.abc import Callable
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol import messages
from bfsitl.protocol import messages as m
from bfsitl.protocol.boxes import BOX_NAMES
from bfsitl.protocol.messages.wire_types import (
    Array,
    Counted,
    Int,
    Nested,
    PStr,
    Raw,
    RestArray,
    RestText,
    Text,
    WireField,
)


def _message_classes() -> list[Any]:
    """Every class in the package's modules that carries an MSP ``COMMAND``."""
    found: dict[str, Any] = {}
    for info in pkgutil.iter_modules(messages.__path__):
        module = importlib.import_module(f"{messages.__name__}.{info.name}")
        for _, obj in inspect.getmembers(module, inspect.isclass):
            if obj.__module__ == module.__name__ and isinstance(getattr(obj, "COMMAND", None), int):
                found[obj.__name__] = obj
    return sorted(found.values(), key=lambda cls: cls.__name__)


MESSAGES = _message_classes()
#: 40 registered classes and RawGps, which has never been in REPLY_TYPES.
MESSAGE_COUNT = 41
UNREGISTERED = {m.RawGps}


def _name(cls: Any) -> str:
    return getattr(cls, "__name__", "")


def test_every_message_is_found_and_registered() -> None:
    assert len(MESSAGES) == MESSAGE_COUNT, [cls.__name__ for cls in MESSAGES]
    registered = {*m.REPLY_TYPES.values(), *m.REQUEST_TYPES.values()}
    assert set(MESSAGES) - registered == UNREGISTERED
    assert registered <= set(MESSAGES)
    for cls in MESSAGES:
        assert getattr(m, cls.__name__) is cls  # the facade offers every one


# ---------------------------------------------------------------------------------------------
# one random case: a message, the firmware's payload for it, and what a cut or longer payload does


@dataclasses.dataclass(frozen=True)
class Case:
    msg: Any
    payload: bytes
    #: Lengths the payload may not be cut to (a field would be cut in half, or is required).
    bad_cuts: frozenset[int]
    #: Whether bytes appended to the payload are ignored (False where the layout reads to the
    #: end, or an absent optional field would read them).
    trailing_ignored: bool


#: Latin-1 without NUL: text fields stop at the first NUL, so a NUL would not come back.
TEXT = st.characters(min_codepoint=1, max_codepoint=255)
U8 = st.integers(0, 0xFF)
U16 = st.integers(0, 0xFFFF)
U32 = st.integers(0, 0xFFFFFFFF)

#: Values the __post_init__ checks (or the decoder) insist on, by (class, field).
FIELD_VALUES: dict[tuple[str, str], st.SearchStrategy[Any]] = {
    ("Rc", "channels_us"): st.one_of(
        st.just(()), st.lists(U16, min_size=4, max_size=18).map(tuple)
    ),
    ("SetRawRc", "channels_us"): st.lists(U16, min_size=1, max_size=18).map(tuple),
    ("SetRxMap", "rcmap"): st.permutations(range(8)).map(tuple),
    ("SetModeRange", "index"): st.integers(0, 19),
    ("SetModeRange", "mode_logic"): st.sampled_from((0, 1)),
    ("SetModeRange", "linked_to"): st.sampled_from(sorted(BOX_NAMES)),
    ("SetRtc", "unix_seconds"): st.integers(0, 2**31 - 1),
    ("SetRtc", "millis"): st.integers(0, 999),
    ("MultipleMspRequest", "commands"): st.lists(st.integers(0, 254), min_size=1, max_size=192).map(
        tuple
    ),
}


def wire_values(wire: Any) -> st.SearchStrategy[Any]:
    if isinstance(wire, Int):
        return st.integers(wire.min, wire.max)
    if isinstance(wire, Text):
        return st.text(TEXT, max_size=wire.size)
    if isinstance(wire, PStr | RestText):
        return st.text(TEXT, max_size=40)
    if isinstance(wire, Raw):
        return st.binary(min_size=wire.size, max_size=wire.size)
    if isinstance(wire, Array):
        return st.lists(wire_values(wire.item), min_size=wire.count, max_size=wire.count).map(tuple)
    if isinstance(wire, RestArray | Counted):
        return st.lists(item_values(wire.item), max_size=12).map(tuple)
    if isinstance(wire, Nested):
        return record_values(wire.record)
    raise AssertionError(f"no strategy for wire type {wire!r}")


def item_values(item: Any) -> st.SearchStrategy[Any]:
    return wire_values(item) if isinstance(item, Int) else record_values(item)


def record_values(record: Any) -> st.SearchStrategy[Any]:
    return st.builds(record, *(wire_values(f.wire) for f in record.LAYOUT.fields))


# The firmware's bytes for a value, written here field by field (not with the codec's structs).


def wire_bytes(wire: Any, value: Any) -> bytes:
    if isinstance(wire, Int):
        return struct.pack("<" + wire.code, value)
    if isinstance(wire, Text):
        return value.encode("latin-1").ljust(wire.size, b"\0")
    if isinstance(wire, PStr):
        return bytes([len(value)]) + value.encode("latin-1")
    if isinstance(wire, RestText):
        return value.encode("latin-1")
    if isinstance(wire, Raw):
        return bytes(value)
    if isinstance(wire, Array):
        return b"".join(wire_bytes(wire.item, v) for v in value)
    if isinstance(wire, RestArray):
        return b"".join(item_bytes(wire.item, v) for v in value)
    if isinstance(wire, Counted):
        return wire_bytes(wire.count, len(value)) + b"".join(
            item_bytes(wire.item, v) for v in value
        )
    if isinstance(wire, Nested):
        return item_bytes(wire.record, value)
    raise AssertionError(f"no bytes for wire type {wire!r}")


def item_bytes(item: Any, value: Any) -> bytes:
    if isinstance(item, Int):
        return wire_bytes(item, value)
    return b"".join(wire_bytes(f.wire, getattr(value, f.name)) for f in item.LAYOUT.fields)


def item_size(item: Any) -> int:
    return item.size if isinstance(item, Int) else int(item.LAYOUT.size)


def _bad_cuts(fields: list[WireField], values: list[Any], cut_is_absent: bool) -> set[int]:
    """Lengths inside (or before the end of) the required fields, inside a strict tail field,
    and inside an item of an array that runs to the end."""
    bad: set[int] = set()
    pos = 0
    for field, value in zip(fields, values, strict=True):
        size = field.pad_bytes + len(wire_bytes(field.wire, value))
        if isinstance(field.wire, RestArray):
            step = item_size(field.wire.item)
            bad.update(c for c in range(pos, pos + size) if (c - pos) % step)
        elif isinstance(field.wire, RestText):
            pass  # any prefix of the text is a shorter text
        elif not field.in_tail:
            bad.update(range(pos, pos + size))
        elif not cut_is_absent:
            bad.update(range(pos + 1, pos + size))  # at its start it is simply absent
        pos += size
    return bad


@st.composite
def layout_case(draw: st.DrawFn, cls: Any, whole_tail: bool = False) -> Case:
    layout = cls.LAYOUT
    head = [f for f in layout.fields if not f.in_tail]
    tail = [f for f in layout.fields if f.in_tail]
    # A tail field whose default is not None (MSP_REBOOT's mode) is always written.
    always = max((i + 1 for i, f in enumerate(tail) if f.absent is not None), default=0)
    present = len(tail) if whole_tail else draw(st.integers(always, len(tail)))
    fields = head + tail[:present]
    values = [draw(FIELD_VALUES.get((cls.__name__, f.name), wire_values(f.wire))) for f in fields]
    try:
        msg = cls(*values)
    except MspRequestError:
        assume(False)  # a combination __post_init__ refuses (mode_logic without linked_to)
    payload = b"".join(
        bytes(f.pad_bytes) + wire_bytes(f.wire, v) for f, v in zip(fields, values, strict=True)
    )
    cut_is_absent = layout.tail is not None and layout.tail.cut_is_absent
    bad = _bad_cuts(fields, values, cut_is_absent)
    if cls is m.Rtc:
        bad.discard(0)  # empty: the clock was never set
    reads_to_end = any(isinstance(f.wire, RestArray | RestText) for f in layout.fields)
    return Case(msg, payload, frozenset(bad), not reads_to_end and present == len(tail))


# The classes that decode and encode by hand: the firmware layout written out once more here.


@st.composite
def status_case(draw: st.DrawFn, cls: Any) -> Case:
    extra = draw(st.integers(0, 15))
    flags = draw(st.integers(0, 2 ** (32 + 8 * extra) - 1))
    cycle, i2c, sensors, cpu = (draw(U16) for _ in range(4))
    pid, count, config = draw(U8), draw(U8), draw(U8)
    arming = draw(U32)
    tail = draw(st.tuples(st.integers(-32768, 32767), U8))[: draw(st.integers(0, 2))]
    head = struct.pack("<HHHIBH", cycle, i2c, sensors, flags & 0xFFFFFFFF, pid, cpu)
    middle_values: tuple[int, ...] = ()
    if cls is m.StatusEx:
        middle_values = (draw(U8), draw(U8))
        head += struct.pack("<BB", *middle_values)
    else:
        head += struct.pack("<H", 0)
    body = head + bytes([extra]) + (flags >> 32).to_bytes(extra, "little")
    body += struct.pack("<BIB", count, arming, config)
    payload = body + struct.pack("<hB"[: 1 + len(tail)], *tail)
    msg = cls(
        cycle,
        i2c,
        sensors,
        flags,
        pid,
        cpu,
        *middle_values,
        count,
        arming,
        config,
        *tail,
        *(None,) * (2 - len(tail)),
        flight_mode_extra_bytes=extra,
    )
    bad = set(range(len(body))) | ({len(body) + 1} if tail else set())
    return Case(msg, payload, frozenset(bad), len(tail) == 2)


@st.composite
def pid_advanced_case(draw: st.DrawFn, cls: Any) -> Case:
    payload = draw(st.binary(min_size=18, max_size=70))
    return Case(cls(payload[17], payload), payload, frozenset(range(18)), False)


@st.composite
def box_names_case(draw: st.DrawFn, cls: Any) -> Case:
    name = st.text(st.characters(max_codepoint=255, exclude_characters=";"), max_size=12)
    names = tuple(draw(st.lists(name, max_size=8)))
    return Case(cls(names), "".join(f"{n};" for n in names).encode("latin-1"), frozenset(), False)


@st.composite
def multiple_reply_case(draw: st.DrawFn, cls: Any) -> Case:
    parts = tuple(draw(st.lists(st.binary(max_size=40), max_size=8)))
    payload, bad = b"", set[int]()
    for part in parts:
        bad.update(range(len(payload) + 1, len(payload) + 1 + len(part)))
        payload += bytes([len(part)]) + part
    return Case(cls(parts), payload, frozenset(bad), False)


HAND_WRITTEN: dict[str, Callable[[Any], st.SearchStrategy[Case]]] = {
    "Status": status_case,
    "StatusEx": status_case,
    "PidAdvanced": pid_advanced_case,
    "BoxNames": box_names_case,
    "MultipleMspReply": multiple_reply_case,
}


def cases(cls: Any) -> st.SearchStrategy[Case]:
    if cls.LAYOUT is not None:
        return layout_case(cls)
    assert cls.__name__ in HAND_WRITTEN, f"{cls.__name__} decodes by hand: give it a case here"
    return HAND_WRITTEN[cls.__name__](cls)


def test_the_hand_written_classes_are_the_expected_few() -> None:
    """Everything else is declared; a layout that really varies is the exception."""
    assert {cls.__name__ for cls in MESSAGES if cls.LAYOUT is None} == set(HAND_WRITTEN)


EXAMPLES = settings(
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.filter_too_much, HealthCheck.too_slow],
)


@pytest.mark.parametrize("cls", MESSAGES, ids=_name)
@EXAMPLES
@given(data=st.data())
def test_encode_and_decode_invert_each_other(cls: Any, data: st.DataObject) -> None:
    case = data.draw(cases(cls))
    assert cls.decode(case.msg.encode()) == case.msg
    assert case.msg.encode() == case.payload
    decoded = cls.decode(case.payload)
    assert decoded == case.msg
    assert decoded.encode() == case.payload


@pytest.mark.parametrize("cls", MESSAGES, ids=_name)
@EXAMPLES
@given(data=st.data())
def test_a_payload_cut_inside_a_field_raises_decode_error(cls: Any, data: st.DataObject) -> None:
    case = data.draw(cases(cls))
    if not case.bad_cuts:
        return
    cut = data.draw(st.sampled_from(sorted(case.bad_cuts)))
    with pytest.raises(MspDecodeError):
        cls.decode(case.payload[:cut])


@pytest.mark.parametrize("cls", MESSAGES, ids=_name)
@EXAMPLES
@given(data=st.data(), junk=st.binary(min_size=1, max_size=8))
def test_bytes_after_a_complete_payload_are_ignored(
    cls: Any, data: st.DataObject, junk: bytes
) -> None:
    case = data.draw(cases(cls))
    if case.trailing_ignored:
        assert cls.decode(case.payload + junk) == case.msg


def _too_big(wire: Any, draw: Callable[[st.SearchStrategy[Any]], Any]) -> Any:
    """A value of the field's Python type that its wire type cannot carry."""
    if isinstance(wire, Int):
        return draw(
            st.one_of(
                st.integers(wire.max + 1, wire.max + 2**40),
                st.integers(wire.min - 2**40, wire.min - 1),
            )
        )
    if isinstance(wire, Text):
        return "x" * (wire.size + 1)
    if isinstance(wire, PStr):
        return "x" * 256
    if isinstance(wire, RestText):
        return "\u2708"  # not latin-1
    if isinstance(wire, Raw):
        return bytes(wire.size + draw(st.sampled_from((-1, 1))))
    if isinstance(wire, Array):
        values = list(draw(wire_values(wire)))
        values[draw(st.integers(0, wire.count - 1))] = _too_big(wire.item, draw)
        return tuple(values)
    if isinstance(wire, RestArray):
        return (_bad_item(wire.item, draw),)
    if isinstance(wire, Counted):
        if draw(st.booleans()):
            return (draw(item_values(wire.item)),) * (wire.count.max + 1)
        return (_bad_item(wire.item, draw),)
    if isinstance(wire, Nested):
        return _bad_item(wire.record, draw)
    raise AssertionError(f"no bad value for {wire!r}")


def _bad_item(item: Any, draw: Callable[[st.SearchStrategy[Any]], Any]) -> Any:
    if isinstance(item, Int):
        return _too_big(item, draw)
    fields = item.LAYOUT.fields
    values = [draw(wire_values(f.wire)) for f in fields]
    broken = draw(st.integers(0, len(fields) - 1))
    values[broken] = _too_big(fields[broken].wire, draw)
    return item(*values)


DECLARED = [cls for cls in MESSAGES if cls.LAYOUT is not None and cls.LAYOUT.fields]


@pytest.mark.parametrize("cls", DECLARED, ids=_name)
@EXAMPLES
@given(data=st.data())
def test_a_value_that_does_not_fit_raises_request_error(cls: Any, data: st.DataObject) -> None:
    case = data.draw(layout_case(cls, whole_tail=True))
    for field in cls.LAYOUT.fields:
        bad = _too_big(field.wire, data.draw)
        with pytest.raises(MspRequestError):  # from __post_init__ or from encode
            dataclasses.replace(case.msg, **{field.name: bad}).encode()


def test_hand_written_values_that_do_not_fit_raise_request_error() -> None:
    status = m.Status(125, 0, 0x21, 0, 0, 0, 29, 0, 0)
    for bad in (
        {"cycle_time_us": 70000},
        {"arming_disable_flags": -1},
        {"flight_mode_flags": 1 << 160},
        {"cpu_temp_c": 40000, "rate_profile_count": 1},
    ):
        with pytest.raises(MspRequestError):
            dataclasses.replace(status, **bad).encode()
    ex = m.StatusEx(125, 0, 0x21, 0, 0, 0, 4, 0, 29, 0, 0)
    with pytest.raises(MspRequestError):
        dataclasses.replace(ex, pid_profile_count=256).encode()
    with pytest.raises(MspRequestError):
        m.PidAdvanced(256).encode()
    with pytest.raises(MspRequestError):
        m.BoxNames(("\u2708",)).encode()
    with pytest.raises(MspRequestError):
        m.MultipleMspReply((bytes(256),)).encode()
