"""Reading a TOML file a user wrote (a mission, a scenario): one error class, one message
shape, whether the file is missing or is not TOML."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bfsitl.errors import BfsitlError


def read_toml_file(path: Path, what: str, error: type[BfsitlError]) -> dict[str, Any]:
    """The tables of ``path``; ``error`` (naming ``what`` the file is) when it cannot be read
    or is not valid TOML."""
    try:
        text = path.read_text()
    except OSError as exc:
        raise error(f"cannot read the {what} file {path}: {exc.strerror or exc}") from exc
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path} is not valid TOML: {exc}") from exc
