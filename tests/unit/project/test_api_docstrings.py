"""The public surface documents its parameters: every name in bfsitl.__all__ has Google-style
``Args:`` (and, for dataclass fields and enum members, ``Attributes:``) sections naming each
parameter, the sections the API reference (docs/api.md, mkdocstrings) renders as tables.

The sections are parsed, not searched: a parameter named only in the prose above them does
not count, because the reference would show no row for it.
"""

from __future__ import annotations

import dataclasses
import enum
import inspect
import re
from collections.abc import Callable, Iterator
from typing import Any

import pytest

import bfsitl

#: Plain values: nothing takes a parameter.
CONSTANTS = ("FLY_PROFILE", "__version__")

#: A section header on a line of its own: ``Args:``, ``Returns:``, ...
_HEADER = re.compile(r"^(?P<indent>\s*)(?P<title>[A-Z][A-Za-z]*):\s*$")
#: An entry of a section: ``name: text`` or ``name (type): text``.
_ENTRY = re.compile(r"^\*{0,2}(?P<name>\w+)\s*(\([^)]*\))?\s*:")


def section(docstring: str | None, title: str) -> list[str]:
    """The lines of one Google-style section (``Args``, ``Attributes``...), empty if absent.

    A section runs from its header to the first non-blank line indented no deeper than it.
    """
    lines = inspect.cleandoc(docstring or "").splitlines()
    for number, line in enumerate(lines):
        header = _HEADER.match(line)
        if header is None or header["title"] != title:
            continue
        depth = len(header["indent"])
        body = []
        for inner in lines[number + 1 :]:
            if inner.strip() and len(inner) - len(inner.lstrip()) <= depth:
                break
            body.append(inner)
        return body
    return []


def section_names(docstring: str | None, title: str) -> set[str]:
    """The names a section documents: its entries' names, at the entries' own indentation
    (deeper lines continue an entry's text)."""
    body = [line for line in section(docstring, title) if line.strip()]
    if not body:
        return set()
    depth = min(len(line) - len(line.lstrip()) for line in body)
    names = set()
    for line in body:
        if len(line) - len(line.lstrip()) == depth:
            entry = _ENTRY.match(line.strip())
            if entry is not None:
                names.add(entry["name"])
    return names


def parameter_names(function: Callable[..., Any]) -> list[str]:
    """What a caller passes by name: every parameter but self, cls, *args and **kwargs."""
    return [
        p.name
        for p in inspect.signature(function).parameters.values()
        if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]


def _returns_something(function: Callable[..., Any]) -> bool:
    annotation = inspect.signature(function).return_annotation
    return annotation not in (None, "None", inspect.Signature.empty)


def public_methods(cls: type) -> Iterator[tuple[str, Callable[..., Any]]]:
    """The class's public methods (its own and those it inherits from bfsitl), as functions;
    properties and what Python's own classes (Enum, Exception) bring are left out."""
    for name in sorted(dir(cls)):
        if name.startswith("_"):
            continue
        raw = inspect.getattr_static(cls, name)
        function = raw.__func__ if isinstance(raw, (classmethod, staticmethod)) else raw
        if inspect.isfunction(function) and function.__module__.startswith("bfsitl."):
            yield name, function


def _documented_names() -> list[str]:
    return sorted(set(bfsitl.__all__) - set(CONSTANTS))


def _problems_of_function(
    label: str, function: Callable[..., Any], also: str | None = None
) -> list[str]:
    """``also``: a second docstring whose Args count too (a class's, for its __init__; the
    API reference merges the two)."""
    names = parameter_names(function)
    if not names:
        return []
    documented = section_names(function.__doc__, "Args") | section_names(also, "Args")
    problems = [
        f"{label}: parameter {name!r} is not under Args:"
        for name in names
        if name not in documented
    ]
    every_name = set(inspect.signature(function).parameters)  # **fields may be documented
    problems += [
        f"{label}: Args: names {name!r}, which it does not take"
        for name in sorted(documented - every_name)
    ]
    if (
        label.rsplit(".", 1)[-1] != "__init__"
        and _returns_something(function)
        and not section(function.__doc__, "Returns")
    ):
        problems.append(f"{label}: returns a value but has no Returns: section")
    return problems


def docstring_problems(name: str) -> list[str]:
    """What the docstrings of public name ``name`` lack; empty when nothing."""
    obj = getattr(bfsitl, name)
    if not inspect.isclass(obj):
        if not obj.__doc__:
            return [f"{name}: no docstring"]
        return _problems_of_function(name, obj)
    if not obj.__doc__:
        return [f"{name}: no docstring"]
    problems: list[str] = []
    attributes = section_names(obj.__doc__, "Attributes")
    if dataclasses.is_dataclass(obj):
        problems += [
            f"{name}: field {field.name!r} is not under Attributes:"
            for field in dataclasses.fields(obj)
            if not field.name.startswith("_") and field.name not in attributes
        ]
    elif issubclass(obj, enum.Enum):
        problems += [
            f"{name}: member {member.name!r} is not under Attributes:"
            for member in obj
            if member.name not in attributes
        ]
    else:
        owner = next(c for c in obj.__mro__ if "__init__" in vars(c))
        if owner.__module__.startswith("bfsitl."):
            problems += _problems_of_function(
                f"{name}.__init__",
                owner.__init__,  # type: ignore[misc]
                also=obj.__doc__,
            )
    seen: set[str] = set()
    for method_name, function in public_methods(obj):
        if function.__qualname__ in seen:
            continue
        seen.add(function.__qualname__)
        problems += _problems_of_function(f"{name}.{method_name}", function)
    return problems


@pytest.mark.parametrize("name", _documented_names())
def test_every_parameter_of_the_public_surface_is_documented(name: str) -> None:
    problems = docstring_problems(name)
    assert not problems, "\n".join(problems)


def test_the_names_left_out_are_still_public() -> None:
    """The only names left out are plain values, and they are still exported."""
    assert set(CONSTANTS) <= set(bfsitl.__all__)


def test_the_section_is_parsed_not_searched() -> None:
    def fly(height_m: float, speed_m_s: float = 2.0) -> float:
        """Climb to ``height_m`` at ``speed_m_s``.

        Args:
            height_m: Metres above the take-off point.
                speed_m_s: continues the line above, so it documents nothing.

        Returns:
            Seconds it took.
        """
        return height_m / speed_m_s

    assert section_names(fly.__doc__, "Args") == {"height_m"}
    assert _problems_of_function("fly", fly) == ["fly: parameter 'speed_m_s' is not under Args:"]
