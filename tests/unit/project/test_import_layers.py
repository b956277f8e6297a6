"""The package's layers as pyproject.toml declares them ([tool.importlinter]): each package
imports only those below it, directly or through others, at module level, under
TYPE_CHECKING or inside a function; no modules import each other round a circle."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
#: lint-imports itself, run by this interpreter (the script may not be on PATH).
LINT_IMPORTS = ("import sys; from importlinter.cli import lint_imports_command; "
                "sys.exit(lint_imports_command())")


def test_every_contract_is_kept() -> None:
    pytest.importorskip("importlinter",
                        reason="import-linter is in the dev extra: pip install -e '.[dev]'")
    # This tree's sources first, so an installed bfsitl elsewhere is not the one checked.
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
    done = subprocess.run([sys.executable, "-c", LINT_IMPORTS, "--no-cache"], cwd=ROOT,
                          env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]

