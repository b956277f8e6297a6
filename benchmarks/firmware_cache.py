"""The named firmware builds the benchmarks fly, from bfsitl's cache (built on request)."""

from __future__ import annotations

import sys
from pathlib import Path

from bfsitl.build import BuildProgress, FirmwareBuildOptions, FirmwareCache, build_firmware

MASTER_TARBALL = (Path(__file__).resolve().parents[2] / "shared" / "firmware" /
                  "betaflight-2026.12.0-alpha-301d01a-sitl-src.tar.xz")


def cached_firmware(name: str, source: Path | None, options: FirmwareBuildOptions,
                    build_missing: bool) -> str:
    """The binary of the cached build ``name``; built from ``source`` with ``options`` when
    missing and ``build_missing``, else the benchmark exits saying how to get it."""
    cache = FirmwareCache()
    entry = cache.resolve(name)
    if entry is not None:
        return str(entry.binary_path)
    if not build_missing:
        sys.exit(f"no cached build named {name!r}: run with --build (or `bfsitl firmware "
                 f"build ... --name {name}`)")
    print(f"building {name} ...", file=sys.stderr)
    result = build_firmware(source, options, name=name, cache=cache,
                            progress=BuildProgress(live=False))
    return str(result.binary_path)
