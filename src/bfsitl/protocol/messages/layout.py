"""Declaring a message: a frozen, slotted dataclass whose fields carry their wire types
(:mod:`.wire_types`) in wire order; the class decorator derives ``decode`` and ``encode``::

    @msp_message(MspCommand.ALTITUDE)
    @dataclass(frozen=True, slots=True)
    class Altitude(WireRecord):
        altitude_cm: S32
        vario_cm_s: S16

A class that writes ``decode`` or ``encode`` itself keeps its own, for the rules a layout cannot
say (an empty MSP_RTC means "not set"); it can still call the compiled layout for the fields
(:func:`declared_layout`). A class whose fields carry no wire types at all writes both: those
are the layouts that really vary (MSP_STATUS's flight-mode bytes in the middle).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Callable
from typing import Annotated, Any, ClassVar, Protocol, Self, TypeVar, get_args, get_origin

from bfsitl.protocol.messages.codec import Layout
from bfsitl.protocol.messages.wire_types import WIRE_TYPES, Nested, Pad, Tail, WireField


class MspMessage(Protocol):
    """What every message class here provides."""

    COMMAND: ClassVar[int]

    def encode(self) -> bytes: ...


class WireRecord:
    """Base of every message and record: declares the methods the decorators derive."""

    __slots__ = ()
    COMMAND: ClassVar[int]
    #: The compiled layout; None for a class that decodes and encodes by hand.
    LAYOUT: ClassVar[Layout | None] = None

    @classmethod
    def decode(cls, payload: bytes) -> Self:
        raise NotImplementedError(f"{cls.__name__} is not declared with @msp_message")

    def encode(self) -> bytes:
        raise NotImplementedError(f"{type(self).__name__} is not declared with @msp_message")


_R = TypeVar("_R", bound=WireRecord)

#: The functions the decorators made: a subclass gets its own (its name is in the errors, its
#: ``__post_init__`` may validate), while a hand-written one is inherited as it is.
_GENERATED: set[object] = set()


def msp_message(command: int) -> Callable[[type[_R]], type[_R]]:
    """Class decorator: the payload of MSP ``command``, decoded and encoded by its layout."""

    def declare(cls: type[_R]) -> type[_R]:
        cls.COMMAND = command
        return wire_record(cls)

    return declare


def wire_record(cls: type[_R]) -> type[_R]:
    """Class decorator for a record inside messages (a mode range, one motor's telemetry)."""
    params = getattr(cls, "__dataclass_params__", None)
    if params is None or not params.frozen or "__slots__" not in vars(cls):
        raise TypeError(f"{cls.__name__}: put @dataclass(frozen=True, slots=True) under it")
    own_decode, own_encode = _hand_written(cls, "decode"), _hand_written(cls, "encode")
    fields, tail, untyped = _wire_fields(cls)
    if untyped is not None:
        if not (own_decode and own_encode):
            raise TypeError(
                f"{cls.__name__}.{untyped} has no wire type: give it one, "
                f"or write both decode and encode by hand"
            )
        cls.LAYOUT = None
        return cls
    layout = Layout(cls.__name__, fields, tail)
    declared_size = vars(cls).get("SIZE")
    if declared_size is not None and declared_size != layout.size:
        raise TypeError(f"{cls.__name__}.SIZE is {declared_size}, its fields {layout.size}")
    cls.LAYOUT = layout
    # setattr: mypy refuses assigning to a method, and these replace WireRecord's.
    if not own_decode:
        decode = layout.decoder(validates=hasattr(cls, "__post_init__"))
        _GENERATED.add(decode)
        setattr(cls, "decode", classmethod(decode))  # noqa: B010
    if not own_encode:
        _GENERATED.add(layout.encode)
        setattr(cls, "encode", layout.encode)  # noqa: B010
    return cls


def declared_layout(cls: type[WireRecord]) -> Layout:
    """The compiled layout of a class, for a hand-written decode or encode that adds a rule."""
    if cls.LAYOUT is None:
        raise TypeError(f"{cls.__name__} declares no wire layout")
    return cls.LAYOUT


def _hand_written(cls: type, name: str) -> bool:
    """Whether the class, or the nearest base that defines ``name``, wrote it by hand."""
    for klass in cls.__mro__:
        if name in vars(klass):
            function = vars(klass)[name]
            function = getattr(function, "__func__", function)
            return klass is not WireRecord and function not in _GENERATED
    return False


def _wire_fields(cls: type) -> tuple[list[WireField], Tail | None, str | None]:
    """The fields with their wire types, the tail marker, and the first field without a wire
    type (None when every field has one)."""
    hints = typing.get_type_hints(cls, include_extras=True)
    fields: list[WireField] = []
    tail: Tail | None = None
    for field in dataclasses.fields(cls):
        extras, plain = _annotation_parts(hints[field.name])
        wires = [extra for extra in extras if isinstance(extra, WIRE_TYPES)]
        if not wires:  # a record class as the type: inline
            wires = [
                Nested(t)
                for t in plain
                if isinstance(t, type) and issubclass(t, WireRecord) and t.LAYOUT is not None
            ]
        if not wires:
            return fields, tail, field.name
        if len(wires) > 1:
            raise TypeError(f"{cls.__name__}.{field.name} has {len(wires)} wire types")
        marks = [extra for extra in extras if isinstance(extra, Tail)]
        if marks:
            if tail is not None:
                raise TypeError(f"{cls.__name__}.{field.name}: the tail was marked before")
            tail = marks[0]
        no_default = dataclasses.MISSING
        if tail is not None and field.default is no_default and field.default_factory is no_default:
            raise TypeError(f"{cls.__name__}.{field.name} is in the tail: it needs a default")
        pad = sum(extra.size for extra in extras if isinstance(extra, Pad))
        fields.append(WireField(field.name, wires[0], pad, tail is not None, field.default))
    return fields, tail, None


def _annotation_parts(hint: Any) -> tuple[list[Any], list[Any]]:
    """The ``Annotated`` extras anywhere in a field's type (``Annotated[U16 | None, TAIL]``
    has them at two depths) and the plain types in it."""
    extras: list[Any] = []
    plain: list[Any] = []
    pending = [hint]
    while pending:
        current = pending.pop(0)
        origin = get_origin(current)
        if origin is Annotated:
            inner, *more = get_args(current)
            extras.extend(more)
            pending.append(inner)
        elif origin is typing.Union or origin is types.UnionType:
            pending.extend(arg for arg in get_args(current) if arg is not type(None))
        else:
            plain.append(current)
    return extras, plain
