"""What ``--gps`` has to add to a given tree, decided by reading the tree.

The SITL target leaves GPS out in 4.6.0: ``common_pre.h`` defines USE_GPS, USE_ALTITUDE_HOLD
and USE_POSITION_HOLD only in its ``!defined(SITL)`` block, and the SITL ``target.h`` turns on
USE_VIRTUAL_GPS (the simulator's GPS provider) only ``#ifdef USE_GPS``.  So 4.6.0 needs
``-DUSE_GPS -DUSE_ALTITUDE_HOLD -DUSE_POSITION_HOLD``; USE_VIRTUAL_GPS and USE_GPS_RESCUE
then follow from USE_GPS, and defining either of them again breaks the build (-Werror,
"redefined").  Master's SITL ``target.h`` defines all of them itself, so there ``--gps`` adds
nothing.  Rather than keying this on a version string, each macro is checked in the tree:

* already defined unconditionally by the SITL ``target.h``: nothing to add;
* defined by the target headers whenever USE_GPS is (``#ifdef USE_GPS`` blocks in
  ``target.h``, ``common_pre.h``, ``common_post.h``): follows, nothing to add;
* used by the code (``#ifdef NAME`` somewhere in ``src/main``): added as ``-DNAME``;
* not in the code at all (an older tree without position hold): left out and reported.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path

USE_GPS = "USE_GPS"
GPS_FEATURE_MACROS = ("USE_GPS", "USE_ALTITUDE_HOLD", "USE_POSITION_HOLD")
"""What ``--gps`` asks for, in the order they are added."""
DEPENDENT_MACROS = ("USE_VIRTUAL_GPS", "USE_GPS_RESCUE")
"""Needed with GPS in a SITL, normally switched on by the headers once USE_GPS is defined."""
ALL_MACROS = GPS_FEATURE_MACROS + DEPENDENT_MACROS

COMMON_HEADERS = ("src/main/target/common_pre.h", "src/main/target/common_post.h")

_DIRECTIVE_RE = re.compile(r"^\s*#\s*(\w+)\s*(.*)$")
_DEFINED_RE = re.compile(r"^(!?)\s*defined\s*\(?\s*(\w+)\s*\)?$")

SITL_COMMAND_LINE_MACROS = frozenset({"SITL", "SIMULATOR", "SIMULATOR_BUILD"})
"""Defined by the Makefile for ``TARGET=SITL`` (``-D$(TARGET) -D$(TARGET_MCU_FAMILY)``,
``-DSIMULATOR_BUILD``), so known when the headers test them."""


@dataclass(frozen=True)
class HeaderDefines:
    """The macros a header defines at its top level, and those it defines when USE_GPS is."""

    unconditional: frozenset[str]
    under_gps: frozenset[str]


def header_defines(text: str, assumed: frozenset[str] = frozenset()) -> HeaderDefines:
    """Which definitions a header reaches without USE_GPS, and which only with it.

    Not a preprocessor: it follows ``#if`` nesting and evaluates conditions made of
    ``defined(X)``, ``!defined(X)`` and ``&&`` against ``assumed`` (the macros known to be
    defined; everything else is taken as undefined).  ``#if !defined(X)`` around
    ``#define X`` is a guard and counts as true.  Under any other condition (``||``,
    comparisons, an ``#else``) a definition is "unknown" and counted nowhere.
    """
    unconditional: set[str] = set()
    under_gps: set[str] = set()
    stack: list[str] = []  # each open block's condition; "?" once in its #else/#elif
    for raw in _strip_comments(text).splitlines():
        match = _DIRECTIVE_RE.match(raw)
        if match is None:
            continue
        directive, rest = match.group(1), " ".join(match.group(2).split())
        if directive == "ifdef":
            stack.append(f"defined({rest})")
        elif directive == "ifndef":
            stack.append(f"!defined({rest})")
        elif directive == "if":
            stack.append(rest)
        elif directive in ("elif", "else") and stack:
            stack[-1] = "?"
        elif directive == "endif" and stack:
            stack.pop()
        elif directive in ("define", "undef") and rest:
            name = re.split(r"[\s(]", rest, maxsplit=1)[0]
            without_gps = _all_true(stack, name, assumed - {USE_GPS})
            with_gps = _all_true(stack, name, assumed | {USE_GPS})
            if without_gps:
                target = unconditional
            elif with_gps:
                target = under_gps
            else:
                continue
            if directive == "define":
                target.add(name)
                if target is unconditional:
                    assumed = assumed | {name}
            else:
                target.discard(name)
    return HeaderDefines(frozenset(unconditional), frozenset(under_gps))


def _all_true(stack: list[str], name: str, defined: frozenset[str]) -> bool:
    return all(_condition(cond, name, defined) for cond in stack)


def _condition(condition: str, name: str, defined: frozenset[str]) -> bool:
    """True only when the condition surely holds; "unknown" counts as false."""
    if "||" in condition:
        return False
    for term in condition.split("&&"):
        match = _DEFINED_RE.match(term.strip().strip("()").strip())
        if match is None:
            return False
        negated, macro = bool(match.group(1)), match.group(2)
        if negated and macro == name:
            continue  # the include guard of the very definition: it is defined either way
        if (macro in defined) == negated:
            return False
    return True


def _strip_comments(text: str) -> str:
    text = re.sub(r"/\*.*?\*/", " ", text, flags=re.DOTALL)
    return re.sub(r"//[^\n]*", "", text)


@dataclass(frozen=True)
class TreeFeatures:
    """What the tree's SITL build has by itself and what its code can be switched to."""

    #: Defined at the top level of the SITL target.h.
    target_defines: tuple[str, ...]
    #: Defined by the target headers whenever USE_GPS is.
    gps_dependent: tuple[str, ...]
    #: Which of :data:`ALL_MACROS` the code tests (``#ifdef`` / ``defined()``) at all.
    in_code: tuple[str, ...]

    @property
    def has_gps_by_default(self) -> bool:
        return USE_GPS in self.target_defines


def read_tree_features(root: Path, target_header: Path) -> TreeFeatures:
    """Read the SITL target.h, the common target headers, and grep ``src/main`` once."""
    target = header_defines(_read(target_header), SITL_COMMAND_LINE_MACROS)
    # The common headers see what the target header defined.
    known = SITL_COMMAND_LINE_MACROS | target.unconditional
    dependent = set(target.under_gps)
    for rel in COMMON_HEADERS:
        dependent |= header_defines(_read(root / rel), known).under_gps
    return TreeFeatures(
        target_defines=tuple(sorted(target.unconditional & set(ALL_MACROS))),
        gps_dependent=tuple(sorted(dependent & set(ALL_MACROS))),
        in_code=_macros_in_code(root / "src" / "main", ALL_MACROS),
    )


def _read(path: Path) -> str:
    try:
        return path.read_text(errors="replace")
    except OSError:
        return ""


def _macros_in_code(directory: Path, names: tuple[str, ...]) -> tuple[str, ...]:
    """Which names appear in a .c or .h file under ``directory`` (bytes search, ~0.1 s)."""
    wanted = {name: name.encode() for name in names}
    found: set[str] = set()
    for current, _dirs, files in os.walk(directory):
        for file_name in files:
            if not file_name.endswith((".c", ".h")):
                continue
            try:
                with open(os.path.join(current, file_name), "rb") as handle:
                    content = handle.read()
            except OSError:
                continue
            for name, needle in wanted.items():
                if name not in found and needle in content:
                    found.add(name)
            if len(found) == len(wanted):
                return tuple(n for n in names if n in found)
    return tuple(n for n in names if n in found)


@dataclass(frozen=True)
class GpsPlan:
    """What ``--gps`` does to one tree."""

    #: ``-D`` names to add (empty when the tree's SITL has GPS anyway).
    add: tuple[str, ...]
    #: Already on in the SITL build, or switched on by the headers with USE_GPS.
    present: tuple[str, ...]
    #: Asked for but absent from this tree's code.
    unavailable: tuple[str, ...]


def plan_gps(features: TreeFeatures) -> GpsPlan:
    add: list[str] = []
    present: list[str] = []
    unavailable: list[str] = []
    for name in ALL_MACROS:
        if name in features.target_defines:
            present.append(name)
        elif name in DEPENDENT_MACROS and name in features.gps_dependent:
            present.append(name)
        elif name in features.in_code:
            add.append(name)
        elif name in GPS_FEATURE_MACROS:
            unavailable.append(name)
    return GpsPlan(tuple(add), tuple(present), tuple(unavailable))
