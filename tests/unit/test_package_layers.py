"""The package's layers: the physics at the bottom imports nothing of bfsitl above it (issue
21's first seam), and its modules stay small enough to read."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "src" / "bfsitl"
#: What the pure physics may import of bfsitl: itself, and the one exception tree.
PHYSICS_MAY_IMPORT = ("bfsitl.physics", "bfsitl.errors")


def _imports(path: Path) -> list[str]:
    tree = ast.parse(path.read_text())
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.append(node.module)
        elif isinstance(node, ast.Import):
            found.extend(alias.name for alias in node.names)
    return [name for name in found if name == "bfsitl" or name.startswith("bfsitl.")]


def test_the_physics_imports_nothing_above_it() -> None:
    offenders = [f"{path.name}: {name}"
                 for path in sorted((PACKAGE / "physics").glob("*.py"))
                 for name in _imports(path)
                 if not name.startswith(PHYSICS_MAY_IMPORT)]
    assert not offenders, offenders


def test_the_physics_modules_stay_small() -> None:
    sizes = {path.name: len(path.read_text().splitlines())
             for path in (PACKAGE / "physics").glob("*.py")}
    assert max(sizes.values()) <= 600, sizes
