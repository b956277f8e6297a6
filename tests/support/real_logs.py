"""The real blackbox logs beside the repository (``shared/blackbox/real`` next to the clone,
or the folder ``BFSITL_REAL_LOGS`` names): test data read from there, never copied in.  A
clone with nothing beside it skips what needs them, with one line."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

BESIDE_THE_CLONE = Path(__file__).resolve().parents[3] / "shared/blackbox/real"


def real_logs_dir() -> Path:
    named = os.environ.get("BFSITL_REAL_LOGS")
    return Path(named).expanduser() if named else BESIDE_THE_CLONE


def real_log_files() -> list[Path]:
    """Every real log there (none when the folder is not there)."""
    folder = real_logs_dir()
    return (
        sorted(p for p in folder.iterdir() if p.suffix.lower() in (".bbl", ".bfl", ".bf"))
        if folder.is_dir()
        else []
    )


def require_real_logs() -> list[Path]:
    """The real logs, or a skip saying where they are looked for."""
    files = real_log_files()
    if not files:
        pytest.skip(f"no real blackbox logs in {real_logs_dir()} (set BFSITL_REAL_LOGS)")
    return files
