"""Reading a TOML file a user wrote (a mission, a scenario): one error class, one message
shape, whether the file is missing, is not text, or is not TOML."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bfsitl.errors import BfsitlError


def read_text_file(
    path: Path, what: str, error: type[BfsitlError], *, kind: str = "text, one CLI line per line"
) -> str:
    """The text of ``path``; ``error`` naming the file when it cannot be read or is not UTF-8
    text (a binary file given by mistake, a file saved in another encoding)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"cannot read the {what} file {path}: {exc.strerror or exc}") from exc
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(
            f"{path} is not UTF-8 text (byte {exc.start} is 0x{data[exc.start]:02x}): "
            f"a {what} file is {kind}"
        ) from None


def read_toml_file(path: Path, what: str, error: type[BfsitlError]) -> dict[str, Any]:
    """The tables of ``path``; ``error`` (naming ``what`` the file is) when it cannot be read,
    is not UTF-8 text or is not valid TOML."""
    text = read_text_file(path, what, error, kind="TOML text")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{path} is not valid TOML: {exc}") from None
    except RecursionError:  # thousands of nested brackets
        raise error(f"{path} is not valid TOML: nested too deeply") from None
