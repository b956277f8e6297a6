"""pytest run as a user runs it with bfsitl's plugin: scenario files and fixtures in a folder
of their own."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path


def pytest_with_the_plugin(
    folder: Path, *options: str, env: dict[str, str] | None = None, timeout_s: float = 280
) -> subprocess.CompletedProcess[str]:
    """pytest with bfsitl's plugin on ``folder`` (its own root, no cache), ``options`` before
    it (``--bfsitl-firmware NAME``...): how a user runs scenario files and fixtures."""
    return subprocess.run(
        [
            sys.executable,
            "-m",
            "pytest",
            "-p",
            "bfsitl.pytest_plugin",
            "-p",
            "no:cacheprovider",
            *options,
            "-q",
            "--rootdir",
            str(folder),
            str(folder),
        ],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        cwd=folder,
        env=env,
    )
