"""The checks of an environment's options, which say what an option takes when it is given
something else (a dict from a config file, a string ``gymnasium.make`` passed on)."""

from __future__ import annotations

import dataclasses

from bfsitl.errors import EnvironmentConfigError


def check_group(name: str, value: object, group: type) -> None:
    """Raise EnvironmentConfigError, saying what it takes, unless ``value`` is a ``group``."""
    # A group given as something else (a dict from a config file, a number for the old
    # ``wind``) is said with what it takes, not as an AttributeError deep in the start.
    if not isinstance(value, group):
        names = ", ".join(f.name for f in dataclasses.fields(group))
        raise EnvironmentConfigError(
            f"{name} must be a {group.__name__} (bfsitl.{group.__name__}({names}), all "
            f"optional), not {type(value).__name__}"
        )


def check_choice(name: str, value: str, choices: tuple[str, ...]) -> None:
    # The types say it to a type checker; this says it to everyone else (a string from a
    # config file, gymnasium.make's keywords).
    if value not in choices:
        raise EnvironmentConfigError(f"{name} must be one of {', '.join(choices)}, not {value!r}")
