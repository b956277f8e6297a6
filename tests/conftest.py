"""Shared test setup: make tests/ importable for the fake FC helpers, and give the session a
bfsitl cache of its own.

A test must never see what the machine it runs on happens to hold: a newcomer's
``~/.cache/bfsitl`` is empty, a developer's holds their builds.  So the whole session runs
with ``BFSITL_CACHE_DIR`` pointed at an empty directory made for it (subprocesses inherit
it); a test that needs a named build makes it (the integration fixtures in
``tests/integration/firmware_builds.py``), and one that needs another cache state sets its
own ``BFSITL_CACHE_DIR``.  ``.ci/run`` also runs the suite with an empty ``HOME``, so a test
that reads the home directory some other way fails there as it would for a newcomer.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

_SESSION_CACHE_KEY = pytest.StashKey[Path]()


def pytest_configure(config: pytest.Config) -> None:
    root = Path(tempfile.mkdtemp(prefix="bfsitl-test-cache-"))
    config.stash[_SESSION_CACHE_KEY] = root
    os.environ["BFSITL_CACHE_DIR"] = str(root / "firmware")


def pytest_unconfigure(config: pytest.Config) -> None:
    root = config.stash.get(_SESSION_CACHE_KEY, None)
    if root is not None:
        shutil.rmtree(root, ignore_errors=True)
