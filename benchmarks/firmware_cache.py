"""The named firmware builds the benchmarks fly, from bfsitl's cache (built on request).

Master is the user's own: a build already in the cache under its name (``bfsitl firmware build
--git https://github.com/betaflight/betaflight --ref master --lockstep --name
master-lockstep``), or the tree or tarball ``BFSITL_MASTER_SOURCE`` names, built on ``--build``.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from bfsitl.build import BuildProgress, FirmwareBuildOptions, FirmwareCache, build_firmware

#: A build's source that is master: the tree or tarball named by this variable.
MASTER_SOURCE = "master"
MASTER_SOURCE_ENV_VAR = "BFSITL_MASTER_SOURCE"


def _source_path(source: Path | str | None, name: str) -> Path | None:
    if source != MASTER_SOURCE:
        return None if source is None else Path(source)
    named = os.environ.get(MASTER_SOURCE_ENV_VAR)
    if not named:
        sys.exit(
            f"{name} is built from master, which is not part of bfsitl: set "
            f"{MASTER_SOURCE_ENV_VAR} to your betaflight tree or a tarball of one, or "
            f"build it once with `bfsitl firmware build --git "
            f"https://github.com/betaflight/betaflight --ref master ... --name {name}`"
        )
    return Path(named).expanduser()


def cached_firmware(
    name: str, source: Path | str | None, options: FirmwareBuildOptions, build_missing: bool
) -> str:
    """The binary of the cached build ``name``; built from ``source`` (a path, None for the
    4.6.0 package, or :data:`MASTER_SOURCE`) with ``options`` when missing and
    ``build_missing``, else the benchmark exits saying how to get it."""
    cache = FirmwareCache()
    entry = cache.resolve(name)
    if entry is not None:
        return str(entry.binary_path)
    if not build_missing:
        sys.exit(
            f"no cached build named {name!r}: run with --build (or `bfsitl firmware "
            f"build ... --name {name}`)"
        )
    path = _source_path(source, name)
    print(f"building {name} ...", file=sys.stderr)
    result = build_firmware(
        path, options, name=name, cache=cache, progress=BuildProgress(live=False)
    )
    return str(result.binary_path)
