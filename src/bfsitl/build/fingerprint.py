"""A content fingerprint of a Betaflight source tree: what the cache key is made of.

Only what a build reads counts: ``Makefile``, ``mk/``, ``make/``, ``src/`` and ``lib/`` (never
``obj/``, ``.git`` or ``docs/``).  Each file is hashed by its path and content, so a tree
copied elsewhere, or unpacked from a tarball, has the same fingerprint as the original.

Hashing 4.6.0's tree (6,300 files, 220 MB, most of it vendor libraries) takes about 2 s, too
slow for "a second build is instant".  So the digest of every file is remembered with its
``stat`` (size, mtime, ctime, inode) in a memo file per tree, the way git's index does: the
next time, files whose ``stat`` is unchanged are not read again (about 0.1 s for the whole
tree).  A file changed within the last few seconds is never remembered, since a second change
within the same timestamp tick would not show in its ``stat``.
"""

from __future__ import annotations

import hashlib
import json
import os
import stat
import time
from pathlib import Path

FINGERPRINT_PARTS = ("Makefile", "mk", "make", "src", "lib")
"""Top-level entries whose content decides the build."""

SKIPPED_NAMES = frozenset({".git"})
"""Names skipped anywhere below the parts (a submodule's git metadata is not source)."""

MEMO_VERSION = 1
_RACY_WINDOW_S = 3.0
_READ_CHUNK_BYTES = 1 << 20


def fingerprint_tree(root: Path, memo_dir: Path | None = None) -> str:
    """The hex fingerprint of the tree at ``root``; ``memo_dir`` (optional) speeds repeats."""
    memo_path = _memo_path(root, memo_dir) if memo_dir is not None else None
    memo = _load_memo(memo_path)
    fresh: dict[str, list[object]] = {}
    digests: list[tuple[str, str]] = []
    now_ns = time.time_ns()
    for rel, path in _files(root):
        try:
            info = os.lstat(path)
        except OSError:
            continue  # vanished while we walked: it is not part of the tree any more
        signature = [info.st_size, info.st_mtime_ns, info.st_ctime_ns, info.st_ino]
        known = memo.get(rel)
        if known is not None and known[:4] == signature:
            digest = str(known[4])
        else:
            digest = _digest(path, info)
        digests.append((rel, digest))
        if now_ns - max(info.st_mtime_ns, info.st_ctime_ns) > _RACY_WINDOW_S * 1e9:
            fresh[rel] = [*signature, digest]
    total = hashlib.blake2b(digest_size=20)
    for rel, digest in sorted(digests):
        total.update(f"{rel}\0{digest}\n".encode())
    if memo_path is not None and fresh != memo:
        _save_memo(memo_path, fresh)
    return total.hexdigest()


def _files(root: Path) -> list[tuple[str, str]]:
    """(path relative to root with ``/``, absolute path) of every file under the parts."""
    found: list[tuple[str, str]] = []
    for part in FINGERPRINT_PARTS:
        top = root / part
        if top.is_file() or top.is_symlink():
            found.append((part, str(top)))
            continue
        for directory, dirs, files in os.walk(top):
            dirs[:] = [d for d in dirs if d not in SKIPPED_NAMES]
            rel_dir = os.path.relpath(directory, root).replace(os.sep, "/")
            for name in files:
                if name not in SKIPPED_NAMES:
                    found.append((f"{rel_dir}/{name}", os.path.join(directory, name)))
            # Symbolic links to directories are listed in dirs but not walked into: hash the
            # link itself, as for a linked file.
            for name in dirs:
                full = os.path.join(directory, name)
                if os.path.islink(full):
                    found.append((f"{rel_dir}/{name}", full))
    return found


def _digest(path: str, info: os.stat_result) -> str:
    if stat.S_ISLNK(info.st_mode):
        return "link:" + hashlib.blake2b(os.readlink(path).encode(), digest_size=16).hexdigest()
    content = hashlib.blake2b(digest_size=16)
    try:
        with open(path, "rb") as handle:
            while chunk := handle.read(_READ_CHUNK_BYTES):
                content.update(chunk)
    except OSError as exc:
        return f"unreadable:{exc.errno}"
    return content.hexdigest()


def _memo_path(root: Path, memo_dir: Path) -> Path:
    name = hashlib.blake2b(str(root.absolute()).encode(), digest_size=10).hexdigest()
    return memo_dir / f"tree-{name}.json"


def _load_memo(path: Path | None) -> dict[str, list[object]]:
    if path is None:
        return {}
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    if not isinstance(data, dict) or data.get("version") != MEMO_VERSION:
        return {}
    files = data.get("files")
    return files if isinstance(files, dict) else {}


def _save_memo(path: Path, files: dict[str, list[object]]) -> None:
    """Written whole and renamed into place: a reader sees the old memo or the new one."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        temporary = path.with_name(f".{path.name}.{os.getpid()}")
        temporary.write_text(json.dumps({"version": MEMO_VERSION, "files": files}))
        os.replace(temporary, path)
    except OSError:
        pass  # a memo is only a speed-up; a read-only cache still fingerprints correctly
