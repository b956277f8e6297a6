"""The suite runs as on a machine where bfsitl never ran: it never reads the user's cache.

Two tests once passed only on machines that had built ``4.6.0-gps-lockstep`` before; the
session's own empty cache (tests/conftest.py) and ``.ci/run``'s empty ``HOME`` make such a
test fail everywhere instead."""

from __future__ import annotations

import tempfile
from pathlib import Path

from bfsitl.build.cache import cache_root


def test_the_session_cache_is_its_own_and_not_the_users() -> None:
    root = cache_root()
    home_cache = Path.home() / ".cache" / "bfsitl"
    assert not root.is_relative_to(home_cache), root
    assert root.is_relative_to(Path(tempfile.gettempdir())), root
    assert root.parent.name.startswith("bfsitl-test-cache-"), root


def test_ci_runs_the_suite_with_an_empty_home() -> None:
    script = (Path(__file__).resolve().parents[3] / ".ci" / "run").read_text()
    test_line = next(
        line
        for line in script.splitlines()
        if "make test" in line and not line.lstrip().startswith("#")
    )
    assert 'HOME="$fresh_home"' in test_line and "-u XDG_CACHE_HOME" in test_line, test_line
    assert "-u BFSITL_CACHE_DIR" in test_line, test_line
