"""From a source and the options asked for to the exact build: make arguments, key, name.

The cache key is a hash of everything that decides the binary: the source's content
fingerprint, every ``-D`` and make variable given to make, the key material of every tree hook,
the option fields that are not already expressed by those, and :data:`RECIPE_VERSION`.  It is
computed from the *effective* build, so two requests that build the same thing share an entry
(``--gps`` on master, whose SITL has GPS anyway, is master's plain build).

An option that changes the copied tree before make (``--lockstep`` applying its patch) adds a
:class:`TreeHook` in :func:`plan_build`; the hook's ``key_material()`` (the patch's hash)
enters the key, and ``description`` is printed.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

from bfsitl.build.features import GpsPlan, plan_gps
from bfsitl.build.options import Define, FirmwareBuildOptions
from bfsitl.build.source_facts import IdentifiedSource

RECIPE_VERSION = 1
"""Bump when the way bfsitl builds changes (make arguments, tree preparation): every earlier
cache entry then counts as a different build."""

KEY_LENGTH = 20


class TreeHook(Protocol):
    """A step that prepares the copied tree before make (never the user's source)."""

    @property
    def description(self) -> str:
        """A few words for the progress output ("apply the lockstep patch")."""
        ...

    def key_material(self) -> str:
        """Everything that decides what the hook does (e.g. a patch's hash)."""
        ...

    def __call__(self, tree: Path) -> None: ...


@dataclass(frozen=True)
class BuildPlan:
    """One build, decided: what make is given, what the tree gets first, its key and name."""

    source: IdentifiedSource
    options: FirmwareBuildOptions
    #: Every ``-D`` given to make (the user's and those the options need), sorted by name.
    make_defines: tuple[str, ...]
    #: Variables set on make's command line, e.g. ``REVISION`` when the revision is known.
    make_variables: tuple[tuple[str, str], ...]
    #: What ``--gps`` does to this tree (None without ``--gps``).
    gps: GpsPlan | None
    #: Whether the binary must turn out to have GPS (checked in its bytes after the build).
    expects_gps: bool
    tree_hooks: tuple[TreeHook, ...]
    key: str
    default_name: str

    @property
    def gps_changes_build(self) -> bool:
        """``--gps`` was given and adds defines (on master it changes nothing)."""
        return bool(self.gps and self.gps.add)

    def make_arguments(self, jobs: int, *, dry_run: bool = False) -> list[str]:
        """``make -jN TARGET=SITL EXTRA_FLAGS="-D..." REVISION=...``."""
        args = ["make", "-n" if dry_run else f"-j{jobs}", "TARGET=SITL"]
        if self.make_defines:
            flags = " ".join(Define.parse(text).flag for text in self.make_defines)
            args.append(f"EXTRA_FLAGS={flags}")
        args += [f"{name}={value}" for name, value in self.make_variables]
        return args

    def describe(self) -> str:
        """For the progress output: what is built and how."""
        parts = [
            f"{self.source.facts.firmware_version} (MSP API "
            f"{self.source.facts.msp_api_version}) from {self.source.spec.path}"
        ]
        if self.make_defines:
            parts.append(" ".join(Define.parse(d).flag for d in self.make_defines))
        parts += [hook.description for hook in self.tree_hooks]
        return "; ".join(parts)


def plan_build(source: IdentifiedSource, options: FirmwareBuildOptions) -> BuildPlan:
    facts = source.facts
    defines: dict[str, Define] = {d.name: d for d in options.parsed_defines}
    suffixes: list[str] = []
    gps: GpsPlan | None = None
    if options.gps:
        gps = plan_gps(facts.features)
        for name in gps.add:
            defines.setdefault(name, Define(name))
        if gps.add:
            suffixes.append("-gps")  # only when it changes the build: master has GPS anyway
    hooks: list[TreeHook] = []
    if options.lockstep:
        from bfsitl.build.lockstep import LockstepPatch

        hooks.append(LockstepPatch())
    make_defines = tuple(str(defines[name]) for name in sorted(defines))
    variables: tuple[tuple[str, str], ...] = ()
    if source.revision:
        # The firmware reports it in MSP_BUILD_INFO; a copy without .git would not know it.
        variables = (("REVISION", source.revision),)
    expects_gps = facts.features.has_gps_by_default or "USE_GPS" in defines
    key = _key(facts.fingerprint, make_defines, variables, hooks, options)
    return BuildPlan(
        source=source,
        options=options,
        make_defines=make_defines,
        make_variables=variables,
        gps=gps,
        expects_gps=expects_gps,
        tree_hooks=tuple(hooks),
        key=key,
        default_name=_default_name(source, suffixes, options),
    )


def _key(
    fingerprint: str,
    make_defines: tuple[str, ...],
    variables: tuple[tuple[str, str], ...],
    hooks: list[TreeHook],
    options: FirmwareBuildOptions,
) -> str:
    material = {
        "recipe": RECIPE_VERSION,
        "fingerprint": fingerprint,
        "make_defines": list(make_defines),
        "make_variables": [list(pair) for pair in variables],
        "hooks": [hook.key_material() for hook in hooks],
        "options": options.key_fields(),
    }
    text = json.dumps(material, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:KEY_LENGTH]


def _default_name(
    source: IdentifiedSource, suffixes: list[str], options: FirmwareBuildOptions
) -> str:
    """``4.6.0``, ``4.6.0-gps``, ``2026.12.0-alpha-301d01a``, ``4.6.0+USE_FOO+BAR-2``."""
    name = source.facts.firmware_version
    if source.revision:
        name += f"-{source.revision}"
    name += "".join(suffixes)
    for field_name, value in options.key_fields().items():
        if value:
            name += f"-{field_name}" if value is True else f"-{field_name}-{value}"
    for define in options.defines:
        name += "+" + define.replace("=", "-")
    return re.sub(r"[^A-Za-z0-9._+-]", "_", name)[:100]
