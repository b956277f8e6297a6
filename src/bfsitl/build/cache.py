"""The firmware cache: finished builds, their names, and the locks that keep builds apart.

Layout under :func:`~bfsitl.cache_location.cache_root` (``$BFSITL_CACHE_DIR``, else
``$XDG_CACHE_HOME/bfsitl/firmware``, else ``~/.cache/bfsitl/firmware``)::

    builds/<key>/      one finished build: the binary and build.json, nothing else
    names/<name>       a symlink to ../builds/<key>: the name pointer
    locks/<key>.lock   held (fcntl) while a build of <key> is checked for, made and committed
    tmp/               builds in progress and unpacked tarballs (deleted when done)
    memo/              fingerprints and source facts remembered between calls

A build is made in ``tmp/`` and renamed into ``builds/`` as a whole: an entry either exists
complete or not at all, whatever happens to the process.  Names are unique: building another
key under a name that is taken moves the name to the new build (the newest build of "4.6.0"
is what "4.6.0" means); the older build stays in the cache, listed and reachable by its key.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import re
import secrets
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from bfsitl.build.metadata import BuildMetadata
from bfsitl.cache_location import cache_root
from bfsitl.errors import FirmwareBuildError

MIN_KEY_PREFIX = 6
"""A key may be abbreviated to this many hex digits when it stays unambiguous."""

STALE_SCRATCH_S = 6 * 3600.0
"""Age after which a scratch directory in ``tmp/`` counts as abandoned."""

_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._+-]{0,99}$")


def is_valid_name(name: str) -> bool:
    """Letters, digits and ``. _ + -``, not starting with a dot or dash: safe as a file name
    and never mistaken for a path (no ``/``)."""
    return bool(_NAME_RE.match(name))


def check_name(name: str) -> str:
    if not is_valid_name(name):
        raise FirmwareBuildError(
            f"bad build name {name!r}: use up to 100 letters, digits and . _ + -, starting "
            f"with a letter or digit"
        )
    return name


@dataclass(frozen=True)
class CacheEntry:
    """A finished build in the cache."""

    key: str
    directory: Path
    metadata: BuildMetadata
    #: Every name that points here (usually one; none once a newer build took its name).
    names: tuple[str, ...]

    @property
    def binary_path(self) -> Path:
        return self.directory / self.metadata.binary_name

    @property
    def label(self) -> str:
        """Its first name, else its key abbreviated (how to refer to it on a command line)."""
        return self.names[0] if self.names else self.key[:12]


class FirmwareCache:
    """One cache directory.  Cheap to create; nothing is written until a build needs it."""

    def __init__(self, root: Path | None = None, *, environ: Mapping[str, str] | None = None):
        self.root = (root if root is not None else cache_root(environ)).absolute()
        self.builds_dir = self.root / "builds"
        self.names_dir = self.root / "names"
        self.locks_dir = self.root / "locks"
        self.tmp_dir = self.root / "tmp"
        self.memo_dir = self.root / "memo"

    # -- reading ------------------------------------------------------------------------
    def name_map(self) -> dict[str, str]:
        """Name -> key, for every name pointer that leads to an existing build."""
        names: dict[str, str] = {}
        try:
            pointers = sorted(self.names_dir.iterdir())
        except OSError:
            return names
        for pointer in pointers:
            try:
                key = Path(os.readlink(pointer)).name
            except OSError:
                continue
            if (self.builds_dir / key).is_dir():
                names[pointer.name] = key
        return names

    def entry(self, key: str, names: Mapping[str, str] | None = None) -> CacheEntry | None:
        directory = self.builds_dir / key
        try:
            metadata = BuildMetadata.read(directory)
        except (OSError, ValueError):
            return None
        if not (directory / metadata.binary_name).is_file():
            return None
        name_map = self.name_map() if names is None else names
        own = tuple(sorted(n for n, k in name_map.items() if k == key))
        return CacheEntry(key, directory, metadata, own)

    def entries(self) -> list[CacheEntry]:
        """Every finished build, oldest first."""
        names = self.name_map()
        try:
            keys = sorted(p.name for p in self.builds_dir.iterdir())
        except OSError:
            return []
        found = [e for e in (self.entry(k, names) for k in keys) if e is not None]
        return sorted(found, key=lambda e: (e.metadata.built_at, e.key))

    def resolve(self, text: str) -> CacheEntry | None:
        """A build by name, or by its key or an unambiguous prefix of it (6+ hex digits)."""
        if not is_valid_name(text):
            return None
        names = self.name_map()
        if text in names:
            return self.entry(names[text], names)
        if len(text) >= MIN_KEY_PREFIX and re.fullmatch(r"[0-9a-f]+", text):
            try:
                keys = [p.name for p in self.builds_dir.iterdir() if p.name.startswith(text)]
            except OSError:
                return None
            if len(keys) == 1:
                return self.entry(keys[0], names)
        return None

    def labels(self) -> list[str]:
        """How each build can be named on a command line (for error messages)."""
        return [entry.label for entry in self.entries()]

    # -- writing ------------------------------------------------------------------------
    def set_name(self, name: str, key: str) -> str | None:
        """Point ``name`` at build ``key``; returns the key it pointed to before, if other.

        A new symlink renamed over the old one: the name is never missing or half-written.
        """
        check_name(name)
        self.names_dir.mkdir(parents=True, exist_ok=True)
        pointer = self.names_dir / name
        try:
            previous: str | None = Path(os.readlink(pointer)).name
        except OSError:
            previous = None
        if previous == key:
            return None
        temporary = self.names_dir / f".{name}.{os.getpid()}.{secrets.token_hex(4)}"
        temporary.symlink_to(Path("..") / "builds" / key)
        os.replace(temporary, pointer)
        if previous is not None and not (self.builds_dir / previous).is_dir():
            return None  # it pointed at a build that is gone: nothing was displaced
        return previous

    @contextlib.contextmanager
    def lock(self, key: str, on_wait: Callable[[str], None] | None = None) -> Iterator[None]:
        """Hold the lock of ``key``: one process at a time checks for, builds and commits it.

        ``flock`` is released by the kernel when the process dies, so a crashed build never
        leaves a stale lock behind.
        """
        self.locks_dir.mkdir(parents=True, exist_ok=True)
        with open(self.locks_dir / f"{key}.lock", "a+") as handle:
            try:
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if on_wait is not None:
                    handle.seek(0)
                    holder = handle.read().strip() or "another process"
                    on_wait(f"{holder} is building the same firmware; waiting for it")
                fcntl.flock(handle.fileno(), fcntl.LOCK_EX)
            try:
                handle.seek(0)
                handle.truncate()
                handle.write(f"pid {os.getpid()}")
                handle.flush()
                yield
            finally:
                fcntl.flock(handle.fileno(), fcntl.LOCK_UN)

    def work_dir(self, key: str) -> Path:
        """A fresh directory in ``tmp/`` for one attempt at building ``key`` (hold its lock).

        Leftovers of earlier attempts at the same key (a process killed with SIGKILL) are
        removed first: holding the lock proves nobody is using them.
        """
        self.tmp_dir.mkdir(parents=True, exist_ok=True)
        for stale in self.tmp_dir.glob(f"{key}.*"):
            shutil.rmtree(stale, ignore_errors=True)
        path = self.tmp_dir / f"{key}.{os.getpid()}"
        path.mkdir()
        return path

    def scratch_dir(self, prefix: str) -> Path:
        """A fresh directory in ``tmp/`` not tied to a key (unpacking a tarball).

        Ones left by a process killed outright are deleted once they are hours old: no build
        keeps its scratch directory that long (it lives from unpacking to the end of make).
        """
        self.tmp_dir.mkdir(parents=True, exist_ok=True)
        cutoff_s = time.time() - STALE_SCRATCH_S
        for stale in self.tmp_dir.glob(f"{prefix}*"):
            with contextlib.suppress(OSError):
                if stale.stat().st_mtime < cutoff_s:
                    shutil.rmtree(stale, ignore_errors=True)
        return Path(tempfile.mkdtemp(prefix=prefix, dir=self.tmp_dir))

    def commit(self, staging: Path, key: str) -> Path:
        """Move a complete entry into ``builds/<key>`` in one rename (hold the key's lock).

        An existing entry of the same key (``--force``) is first renamed aside, then deleted.
        """
        self.builds_dir.mkdir(parents=True, exist_ok=True)
        final = self.builds_dir / key
        if final.exists():
            aside = self.tmp_dir / f"{key}.{os.getpid()}.replaced"
            os.replace(final, aside)
            shutil.rmtree(aside, ignore_errors=True)
        os.replace(staging, final)
        return final

    def remove(self, key: str) -> list[str]:
        """Delete a build and the names pointing at it; returns those names."""
        names = [n for n, k in self.name_map().items() if k == key]
        with self.lock(key):
            for name in names:
                with contextlib.suppress(FileNotFoundError):
                    (self.names_dir / name).unlink()
            final = self.builds_dir / key
            if final.exists():
                self.tmp_dir.mkdir(parents=True, exist_ok=True)
                aside = self.tmp_dir / f"{key}.{os.getpid()}.removed"
                os.replace(final, aside)  # gone from builds/ at once, deleted at leisure
                shutil.rmtree(aside, ignore_errors=True)
        # The lock file stays: unlinking it under a waiting process would let a third one
        # lock a new file of the same name while the waiter holds the old one.
        return names

    def clear(self) -> None:
        """Delete the whole cache."""
        shutil.rmtree(self.root, ignore_errors=True)
