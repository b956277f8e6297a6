"""Files that read as firmware builds to bfsitl's checks; nothing runs them."""

from __future__ import annotations

from pathlib import Path

from bfsitl.build.binary_scan import LOCKSTEP_MARKER


def fake_lockstep_build(directory: Path) -> Path:
    """A file that reads as a lockstep build (its marker inside); nothing runs it."""
    binary = directory / "betaflight_SITL.elf"
    binary.write_bytes(b"\x00" * 64 + LOCKSTEP_MARKER + b"\x00" * 64)
    binary.chmod(0o755)
    return binary
