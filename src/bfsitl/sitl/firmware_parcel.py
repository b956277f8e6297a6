"""A firmware build on its way to other machines: its bytes in Ray's object store, named by
their SHA-256, with the build record beside them; and a node's copy, kept by that hash.

Used by scenario runs on a Ray cluster (:mod:`bfsitl.scenario.ray_runs`) and by the learning
environment's Ray actors (:mod:`bfsitl.gym.ray_vector`): a node needs bfsitl, nothing else.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bfsitl.atomic_file import write_atomically
from bfsitl.build.metadata import METADATA_NAME
from bfsitl.cache_location import cache_root
from bfsitl.errors import SitlError
from bfsitl.sitl.firmware import find_firmware

#: Where a node keeps the builds it received (under its bfsitl cache).
RECEIVED_DIR = "received"


@dataclass(frozen=True, slots=True)
class FirmwareParcel:
    """One firmware build on its way to the nodes: its bytes are in the object store."""

    name: str  # as the runs name it (a cached build's name or a path)
    sha256: str
    file_name: str  # the binary's own name (the SITL's version is in it)
    size: int
    ref: Any  # ray.ObjectRef of the bytes
    #: The build record beside it (``build.json``: its options, GPS among them), if any.
    record: bytes | None = None


def pack_firmware(ray: Any, names: Sequence[str]) -> dict[str, FirmwareParcel]:
    """Each named build, read once on the driver and put in the object store."""
    parcels: dict[str, FirmwareParcel] = {}
    for name in dict.fromkeys(names):
        binary = find_firmware(name)
        data = binary.path.read_bytes()
        record = binary.path.parent / METADATA_NAME
        parcels[name] = FirmwareParcel(
            name,
            hashlib.sha256(data).hexdigest(),
            binary.path.name,
            len(data),
            ray.put(data),
            record.read_bytes() if record.is_file() else None,
        )
    return parcels


def received_path(parcel: FirmwareParcel, root: Path | None = None) -> Path:
    """Where a node keeps ``parcel``'s binary: content-addressed, so two builds of one name
    never mix and one build under two names is kept once."""
    return (root or cache_root()) / RECEIVED_DIR / parcel.sha256[:20] / parcel.file_name


def unpack_firmware(
    parcel: FirmwareParcel, fetch: Callable[[Any], bytes], root: Path | None = None
) -> Path:
    """The binary on this node: kept from an earlier run, or fetched (``fetch(ref)``),
    checked against its hash and written whole."""
    path = received_path(parcel, root)
    if parcel.record is not None:
        # The record first: a binary is only ever seen with the record that describes it.
        record = path.parent / METADATA_NAME
        if not record.is_file() or record.read_bytes() != parcel.record:
            write_atomically(record, parcel.record)
    if path.is_file() and path.stat().st_size == parcel.size:
        return path
    data = fetch(parcel.ref)
    if hashlib.sha256(data).hexdigest() != parcel.sha256:
        raise SitlError(
            f"the firmware {parcel.name} arrived damaged (its SHA-256 is not "
            f"{parcel.sha256[:12]}...)"
        )
    write_atomically(path, data)
    path.chmod(0o755)
    return path
