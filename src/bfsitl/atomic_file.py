"""Writing a file whole: what a person or a CI server reads is the old file or the new one,
never half of one (an interrupted run, Ctrl-C)."""

from __future__ import annotations

import os
import secrets
from pathlib import Path


def write_atomically(path: Path, data: bytes) -> None:
    """Write ``data`` to a temporary file beside ``path``, then rename it over ``path``: an
    interrupted run leaves the old file or none, never half of one.  The temporary name is
    unique (two writers never share it) and the file is created with the usual permissions
    (``mkstemp`` would make a page others cannot read)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        with temporary.open("xb") as handle:
            handle.write(data)
        os.replace(temporary, path)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise
