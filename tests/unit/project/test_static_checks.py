"""The static checks: the package type-checks (mypy over src/bfsitl, configured in
pyproject.toml; the public surface is typed, py.typed, so its annotations are part of the API
and must hold), ruff's lint passes over all the Python in the repository, and the code is as
``ruff format`` writes it (one layout, so a diff shows only what changed)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


def test_mypy_finds_no_errors(tmp_path):
    pytest.importorskip("mypy", reason="mypy is in the dev extra: pip install -e '.[dev]'")
    done = subprocess.run(
        [sys.executable, "-m", "mypy", "--cache-dir", str(tmp_path / "mypy-cache")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


#: What ruff reads: the package and everything that imports it.
RUFF_PATHS = ("src", "tests", "benchmarks", "examples", "tools")


def test_ruff_finds_no_lint(tmp_path):
    """ruff's rules (pyproject.toml: pycodestyle, pyflakes, isort, bugbear, pyupgrade) over
    the package, the tests, the benchmarks and the examples."""
    pytest.importorskip("ruff", reason="ruff is in the dev extra: pip install -e '.[dev]'")
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "check", "--no-cache", *RUFF_PATHS],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]


def test_the_code_is_as_ruff_format_writes_it():
    """``ruff format --check`` over the same paths: run ``ruff format src tests benchmarks
    examples`` to fix what it reports."""
    pytest.importorskip("ruff", reason="ruff is in the dev extra: pip install -e '.[dev]'")
    done = subprocess.run(
        [sys.executable, "-m", "ruff", "format", "--check", "--no-cache", *RUFF_PATHS],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
