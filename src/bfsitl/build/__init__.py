"""Build Betaflight SITL binaries from source, out of tree, into a cache bfsitl knows.

The parts, each a module with one job:

* :mod:`~bfsitl.build.options`: the typed option set (:class:`FirmwareBuildOptions`);
* :mod:`~bfsitl.build.source_tree`: find, classify and unpack sources, read their version;
* :mod:`~bfsitl.build.fingerprint`: the content hash of a tree (fast when repeated);
* :mod:`~bfsitl.build.source_facts`: a source's facts, remembered between calls;
* :mod:`~bfsitl.build.features`: what ``--gps`` adds to a given tree;
* :mod:`~bfsitl.build.plan`: make arguments, tree hooks, cache key and default name;
* :mod:`~bfsitl.build.make_runner` and :mod:`~bfsitl.build.progress`: run make, show progress;
* :mod:`~bfsitl.build.cache`: entries, names, locks; :mod:`~bfsitl.build.metadata`: build.json;
* :mod:`~bfsitl.build.binary_scan`: what a binary is, from its bytes;
* :mod:`~bfsitl.build.builder`: :func:`build_firmware`, the whole build.

Of the rest of bfsitl this imports only what is below it in the layers: the firmware's
tables (:mod:`bfsitl.protocol`), the errors, the cache's place and the version; ``sitl/`` and
``fc/`` use it to resolve names and to tell what a binary is.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bfsitl.build.binary_scan import BinaryTraits, binary_traits
    from bfsitl.build.builder import BuildResult, build_firmware, default_jobs
    from bfsitl.build.cache import CacheEntry, FirmwareCache
    from bfsitl.build.metadata import (
        BuildMetadata,
        build_options_for_binary,
        metadata_for_binary,
    )
    from bfsitl.build.options import FirmwareBuildOptions
    from bfsitl.build.progress import BuildProgress

# Loaded on first use (PEP 562): finding a firmware (sitl/firmware.py) needs only the binary
# scan and the cache, not the builder with its subprocess and tarfile machinery.
_EXPORTS = {
    "BinaryTraits": "binary_scan",
    "binary_traits": "binary_scan",
    "BuildResult": "builder",
    "build_firmware": "builder",
    "default_jobs": "builder",
    "CacheEntry": "cache",
    "FirmwareCache": "cache",
    "BuildMetadata": "metadata",
    "build_options_for_binary": "metadata",
    "metadata_for_binary": "metadata",
    "FirmwareBuildOptions": "options",
    "BuildProgress": "progress",
}

__all__ = [
    "BinaryTraits",
    "BuildMetadata",
    "BuildProgress",
    "BuildResult",
    "CacheEntry",
    "FirmwareBuildOptions",
    "FirmwareCache",
    "binary_traits",
    "build_firmware",
    "build_options_for_binary",
    "default_jobs",
    "metadata_for_binary",
]


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'bfsitl.build' has no attribute {name!r}")
    return getattr(importlib.import_module(f"bfsitl.build.{module}"), name)
