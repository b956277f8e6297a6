"""Whether a process the tests started is still there (a zombie counts as gone)."""

from __future__ import annotations


def process_alive(pid: int) -> bool:
    """True while ``pid`` runs; False once it exited, whether reaped or left a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False
