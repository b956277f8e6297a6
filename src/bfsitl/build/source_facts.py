"""Everything a build plan needs to know about a source, read once and remembered.

The facts of a tree (fingerprint, version, MSP API, what its SITL target has) depend only on
its content, so they are remembered by fingerprint; a tarball's fingerprint is remembered by
the tarball's ``stat``.  So asking again about a known tarball unpacks nothing, and a known
directory costs one ``stat`` per file (:mod:`bfsitl.build.fingerprint`): that is what makes a
second ``bfsitl firmware build`` instant.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from bfsitl.build.features import TreeFeatures, read_tree_features
from bfsitl.build.fingerprint import fingerprint_tree
from bfsitl.build.source_tree import (
    SourceSpec,
    extract_tarball,
    read_version,
    revision_from_name,
    revision_of,
    sitl_target_header,
)
from bfsitl.errors import FirmwareSourceError

FACTS_VERSION = 1
"""Bump when what is read from a tree changes: remembered facts of older versions are ignored."""

SKIPPED_WHEN_COPYING = frozenset({"obj", ".git", "docs"})
"""Top-level entries of a tree that a build never reads and a copy leaves out."""


@dataclass(frozen=True)
class SourceFacts:
    fingerprint: str
    firmware_version: str
    msp_api_version: str
    #: The SITL target header, relative to the tree's root.
    sitl_target: str
    features: TreeFeatures


@dataclass(frozen=True)
class IdentifiedSource:
    """A source with its facts; ``tree`` is a readable tree when one is at hand."""

    spec: SourceSpec
    facts: SourceFacts
    revision: str | None
    #: The directory itself; for a tarball, where it was unpacked (None if it was not needed).
    tree: Path | None


def read_facts(root: Path, memo_dir: Path | None, *, fingerprint: str | None = None) -> SourceFacts:
    """The facts of the tree at ``root`` (from the memo when its fingerprint is known)."""
    if fingerprint is None:
        fingerprint = fingerprint_tree(root, memo_dir)
    remembered = _load_facts(memo_dir, fingerprint)
    if remembered is not None:
        return remembered
    target = sitl_target_header(root)
    if target is None:
        raise FirmwareSourceError(f"{root} has no SITL target header")
    version = read_version(root)
    facts = SourceFacts(
        fingerprint=fingerprint,
        firmware_version=version.firmware,
        msp_api_version=version.msp_api,
        sitl_target=target.relative_to(root).as_posix(),
        features=read_tree_features(root, target),
    )
    _save_json(
        _facts_path(memo_dir, fingerprint), {**asdict(facts), "facts_version": FACTS_VERSION}
    )
    return facts


def identify_source(
    spec: SourceSpec,
    memo_dir: Path | None,
    scratch: Callable[[], Path],
    on_unpack: Callable[[str], None] | None = None,
) -> IdentifiedSource:
    """Facts and revision of a source; a tarball is unpacked (into ``scratch()``) only when
    its facts are not remembered yet (``on_unpack`` hears about it: it takes a second)."""
    if not spec.is_tarball:
        facts = read_facts(spec.path, memo_dir)
        return IdentifiedSource(spec, facts, revision_of(spec.path), spec.path)
    stamp = _tarball_stamp(spec.path)
    remembered = _load_json(_tarball_path(memo_dir, spec.path))
    if remembered and remembered.get("stamp") == stamp:
        facts_known = _load_facts(memo_dir, str(remembered["fingerprint"]))
        if facts_known is not None:
            top = str(remembered.get("top_name", ""))
            return IdentifiedSource(spec, facts_known, revision_from_name(top), None)
    if on_unpack is not None:
        on_unpack(f"unpacking {spec.path.name}")
    root = unpack(spec.path, scratch())
    # The unpacked copy is temporary: no per-file memo for it, the tarball memo stands in.
    facts = read_facts(root, memo_dir, fingerprint=fingerprint_tree(root, None))
    _save_json(
        _tarball_path(memo_dir, spec.path),
        {"stamp": stamp, "fingerprint": facts.fingerprint, "top_name": root.name},
    )
    return IdentifiedSource(spec, facts, revision_of(root), root)


def unpack(tarball: Path, into: Path) -> Path:
    return extract_tarball(tarball, into, skip_dirs=SKIPPED_WHEN_COPYING)


# --- memo files ------------------------------------------------------------------------------


def _tarball_stamp(path: Path) -> list[int]:
    try:
        info = path.stat()
    except OSError as exc:
        raise FirmwareSourceError(f"cannot read tarball {path}: {exc}") from None
    return [info.st_size, info.st_mtime_ns, info.st_ctime_ns, info.st_ino]


def _tarball_path(memo_dir: Path | None, tarball: Path) -> Path | None:
    if memo_dir is None:
        return None
    name = hashlib.blake2b(str(tarball.absolute()).encode(), digest_size=10).hexdigest()
    return memo_dir / f"tarball-{name}.json"


def _facts_path(memo_dir: Path | None, fingerprint: str) -> Path | None:
    return None if memo_dir is None else memo_dir / f"facts-{fingerprint}.json"


def _load_facts(memo_dir: Path | None, fingerprint: str) -> SourceFacts | None:
    data = _load_json(_facts_path(memo_dir, fingerprint))
    if not data or data.get("facts_version") != FACTS_VERSION:
        return None
    try:
        features = TreeFeatures(**{k: tuple(v) for k, v in data["features"].items()})
        return SourceFacts(
            fingerprint=data["fingerprint"],
            firmware_version=data["firmware_version"],
            msp_api_version=data["msp_api_version"],
            sitl_target=data["sitl_target"],
            features=features,
        )
    except (KeyError, TypeError, AttributeError):
        return None


def _load_json(path: Path | None) -> dict[str, Any] | None:
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _save_json(path: Path | None, data: dict[str, object]) -> None:
    if path is None:
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.{os.getpid()}")
        temporary.write_text(json.dumps(data))
        os.replace(temporary, path)
    except OSError:
        pass  # only a speed-up
