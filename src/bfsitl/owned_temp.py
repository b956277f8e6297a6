"""Temporary directories that name the process they belong to, so that what a killed run
left behind is removed by the next one.

A run cleans its temporary directory when it ends, however it ends in Python (an error, a
Ctrl-C, the CLI's SIGTERM handler).  A process killed outright (SIGKILL, an OOM kill, a
library script's SIGTERM with no handler) runs no cleanup at all.  Its directories carry its
pid in their names (``bfsitl-run-<pid>-<random>``), and each new one of the same kind first
removes those whose process is gone, as the shared-memory regions do
(:func:`bfsitl.link.shm_exchange.remove_stale_regions`).  A directory whose pid runs again
(a reused pid) is left until that process ends too: nothing is ever removed from under a
live process.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path


def owned_temp_dir(prefix: str, folder: Path | None = None) -> Path:
    """A new directory ``<prefix><pid>-<random>`` in ``folder`` (None: the system's
    temporary folder), after removing the ``prefix`` ones of processes that no longer run.

    Args:
        prefix: What names this kind of directory (``"bfsitl-run-"``).
        folder: Where to make it; None: :func:`tempfile.gettempdir`.

    Returns:
        The directory, empty; the caller removes it when done.
    """
    where = folder if folder is not None else Path(tempfile.gettempdir())
    remove_stale_dirs(prefix, where)
    return Path(tempfile.mkdtemp(prefix=f"{prefix}{os.getpid()}-", dir=where))


def remove_stale_dirs(prefix: str, folder: Path) -> list[Path]:
    """Remove the ``<prefix><pid>-...`` directories in ``folder`` whose process is gone.

    Args:
        prefix: The kind of directory, as given to :func:`owned_temp_dir`.
        folder: Where to look.

    Returns:
        The directories removed.
    """
    removed = []
    for entry in left_by_gone_processes(prefix, folder):
        if entry.is_symlink() or not entry.is_dir():
            continue
        shutil.rmtree(entry, ignore_errors=True)
        if not entry.exists():
            removed.append(entry)
    return removed


def left_by_gone_processes(prefix: str, folder: Path) -> list[Path]:
    """The entries ``<prefix><pid>-...`` of ``folder`` whose process no longer runs.

    Args:
        prefix: What names the kind of entry.
        folder: Where to look (a folder that cannot be read has none).

    Returns:
        Their paths; names without a pid (older bfsitl's, or another tool's) are not
        among them.
    """
    try:
        entries = list(folder.glob(f"{prefix}*"))
    except OSError:
        return []
    gone = []
    for entry in entries:
        pid_text = entry.name[len(prefix) :].split("-", 1)[0]
        if pid_text.isdigit() and not process_running(int(pid_text)):
            gone.append(entry)
    return gone


def process_running(pid: int) -> bool:
    """Whether a process with this pid exists (one of another user counts as running).

    Args:
        pid: The process id.

    Returns:
        True unless no such process exists.
    """
    if pid <= 0:
        return True  # not a process of its own: never a reason to remove anything
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
