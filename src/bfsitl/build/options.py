"""What a SITL build is asked for: the typed option set and the ``-D`` defines it may carry.

The options are the *request*; :mod:`bfsitl.build.plan` turns them, together with what the
source tree already has, into the exact ``make`` arguments and the cache key.  Adding an option
(say ``lockstep``) means: a field here, its effect in :func:`bfsitl.build.plan.plan_build`
(extra defines, a tree hook, a name suffix) and nothing else: every field that is not marked
:data:`RESOLVED` enters the cache key as it is, so a new option can never be forgotten there.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, fields

from bfsitl.errors import FirmwareBuildError

RESOLVED = "resolved_into_make_arguments"
"""Field metadata flag: the option is fully expressed by the plan's ``make`` arguments (the
defines it becomes), so the key takes those instead of the raw option.  That is what makes
``--gps`` on a tree that always has GPS the very same build as without it."""

# A C macro name, and a value that survives make's EXTRA_FLAGS="..." and the shell unquoted:
# no spaces, quotes or shell metacharacters.
_DEFINE_RE = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?:=(?P<value>[A-Za-z0-9_.+\-]*))?$")


@dataclass(frozen=True, order=True)
class Define:
    """One preprocessor definition: ``NAME`` or ``NAME=VALUE`` (given as ``-DNAME[=VALUE]``)."""

    name: str
    value: str | None = None

    @classmethod
    def parse(cls, text: str) -> Define:
        raw = text.strip()
        if raw.startswith("-D"):
            raw = raw[2:]
        match = _DEFINE_RE.match(raw)
        if match is None:
            raise FirmwareBuildError(
                f"bad define {text!r}: expected NAME or NAME=VALUE, NAME a C identifier and "
                f"VALUE letters, digits or . _ + - (no spaces or quotes: it goes through make)"
            )
        return cls(match.group("name"), match.group("value"))

    @property
    def flag(self) -> str:
        """The compiler flag, ``-DNAME`` or ``-DNAME=VALUE``."""
        return f"-D{self}"

    def __str__(self) -> str:
        return self.name if self.value is None else f"{self.name}={self.value}"


def normalize_defines(texts: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """Parsed, de-duplicated and sorted by name; the same name twice with two values is refused.

    Sorted so that the order on the command line never changes the cache key.
    """
    by_name: dict[str, Define] = {}
    for text in texts:
        define = Define.parse(text)
        known = by_name.get(define.name)
        if known is not None and known != define:
            raise FirmwareBuildError(
                f"define {define.name} given twice with different values: {known} and {define}"
            )
        by_name[define.name] = define
    return tuple(str(by_name[name]) for name in sorted(by_name))


@dataclass(frozen=True)
class FirmwareBuildOptions:
    """The options of one SITL build (what ``bfsitl firmware build`` takes, minus run settings
    like ``--jobs`` and ``--name`` that do not change the binary)."""

    #: Extra preprocessor definitions, ``NAME`` or ``NAME=VALUE``; normalized (sorted, unique).
    defines: tuple[str, ...] = field(default=(), metadata={RESOLVED: True})
    #: GPS (virtual provider), GPS Rescue, altitude hold and position hold, wherever the tree
    #: has the code for them (see :mod:`bfsitl.build.features`).
    gps: bool = field(default=False, metadata={RESOLVED: True})
    #: The lockstep patch (:mod:`bfsitl.build.lockstep`): fdm packets become the FC's clock.
    lockstep: bool = False

    def __post_init__(self) -> None:
        # Frozen: normalizing needs the back door once, at construction.
        object.__setattr__(self, "defines", normalize_defines(tuple(self.defines)))

    @property
    def parsed_defines(self) -> tuple[Define, ...]:
        return tuple(Define.parse(text) for text in self.defines)

    def key_fields(self) -> dict[str, object]:
        """The fields that enter the cache key as they are (all but the :data:`RESOLVED` ones)."""
        return {f.name: getattr(self, f.name) for f in fields(self) if not f.metadata.get(RESOLVED)}
