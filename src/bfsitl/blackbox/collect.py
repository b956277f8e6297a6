"""Find the FC's blackbox files in a run directory and copy them somewhere that lasts."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

#: ``LOG00001.BFL`` (master, and what 4.6.0 meant) and ``LOG00001.BF`` (what 4.6.0 writes).
_LOG_NAME = re.compile(r"^LOG\d{5}\.BFL?$")


def find_blackbox_files(directory: str | Path) -> list[Path]:
    """The blackbox files in ``directory`` (not recursive), in the firmware's numbering."""
    directory = Path(directory)
    if not directory.is_dir():
        return []
    return sorted(p for p in directory.iterdir() if p.is_file() and _LOG_NAME.match(p.name))


def collect_blackbox(run_dir: str | Path, dest_dir: str | Path, *, prefix: str = "") -> list[Path]:
    """Copy the blackbox files of ``run_dir`` into ``dest_dir`` (created); returns the
    copies.  Copies, not moves: the run directory stays as the firmware left it.  A name
    already taken in ``dest_dir`` gets a number, so collecting after every flight of a
    4.6.0 SITL, which overwrites ``LOG00001.BF``, keeps each one."""
    found = find_blackbox_files(run_dir)
    if not found:
        return []
    dest = Path(dest_dir)
    dest.mkdir(parents=True, exist_ok=True)
    copies = []
    for source in found:
        target = dest / f"{prefix}{source.name}"
        number = 2
        while target.exists():
            target = dest / f"{prefix}{source.stem}-{number}{source.suffix}"
            number += 1
        shutil.copy2(source, target)
        copies.append(target)
    return copies
