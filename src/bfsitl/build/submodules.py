"""Submodules a Betaflight tree's Makefile would fetch by itself, stamped in the build copy.

Master's Makefile "hydrates" every submodule of ``.gitmodules`` that is not marked
``update = none`` before any target: ``src/config`` (the boards' configurations) and
``lib/modules/dronecan/libcanard`` (DroneCAN) at the time of writing.  Its rule's target is
the submodule's ``.git`` pointer, so a tree without them (a source archive, a snapshot, a
clone without ``--recurse-submodules``) makes make run ``git submodule update --init``, which
fails outside a checkout and needs the network inside one.

``make TARGET=SITL`` compiles neither: libcanard only for MCUs that opt in
(``LIB_SUBMODULES``), the board configurations only for ``CONFIG=`` builds.  So the build copy
gets an empty ``.git`` stamp in each such directory that has none, and make goes on (a build
that did need one would fail to compile, saying which file is missing).  The user's tree is
never touched.  4.6.0's Makefile hydrates nothing and is left as it is.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

_SECTION = re.compile(r'^\s*\[\s*submodule\s+"(?P<name>[^"]*)"\s*\]\s*$')
_SETTING = re.compile(r"^\s*(?P<key>[A-Za-z][\w-]*)\s*=\s*(?P<value>.*?)\s*$")
#: What in a Makefile says it hydrates submodules on its own (master's stamp rule).
_HYDRATES = "git submodule update --init"


def auto_hydrated_submodules(gitmodules_text: str) -> list[str]:
    """The paths of ``.gitmodules`` entries not marked ``update = none``, in file order."""
    entries: list[dict[str, str]] = []
    for line in gitmodules_text.splitlines():
        if _SECTION.match(line):
            entries.append({})
            continue
        setting = _SETTING.match(line)
        if setting and entries:
            entries[-1][setting["key"].lower()] = setting["value"].strip('"')
    return [
        entry["path"]
        for entry in entries
        if entry.get("path") and entry.get("update", "").lower() != "none"
    ]


def stamp_missing_submodules(tree: Path, note: Callable[[str], None]) -> list[str]:
    """Give each submodule the tree's Makefile would fetch a ``.git`` stamp; the paths
    stamped.  Nothing happens for a Makefile that does not fetch submodules."""
    try:
        makefile = (tree / "Makefile").read_text(errors="replace")
        gitmodules = (tree / ".gitmodules").read_text(errors="replace")
    except OSError:
        return []
    if _HYDRATES not in makefile:
        return []
    stamped = []
    for relative in auto_hydrated_submodules(gitmodules):
        directory = tree / relative
        if not directory.resolve().is_relative_to(tree.resolve()):
            continue  # a path leading out of the tree is not a submodule we stamp
        if (directory / ".git").exists():
            continue  # a real checkout of it
        directory.mkdir(parents=True, exist_ok=True)
        (directory / ".git").write_text("")
        stamped.append(relative)
    if stamped:
        note(
            f"not fetching submodule{'s' if len(stamped) > 1 else ''} "
            f"{', '.join(stamped)}: the SITL build does not compile "
            f"{'them' if len(stamped) > 1 else 'it'}"
        )
    return stamped
