"""The package's layers as pyproject.toml declares them ([tool.importlinter]): each package
imports only those below it, directly or through others, at module level, under
TYPE_CHECKING or inside a function; no modules import each other round a circle."""

from __future__ import annotations

import ast
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
#: lint-imports itself, run by this interpreter (the script may not be on PATH).
LINT_IMPORTS = (
    "import sys; from importlinter.cli import lint_imports_command; "
    "sys.exit(lint_imports_command())"
)


def test_every_contract_is_kept() -> None:
    pytest.importorskip(
        "importlinter", reason="import-linter is in the dev extra: pip install -e '.[dev]'"
    )
    # This tree's sources first, so an installed bfsitl elsewhere is not the one checked.
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(
            [str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])]
        ),
    }
    done = subprocess.run(
        [sys.executable, "-c", LINT_IMPORTS, "--no-cache"],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stdout[-6000:] + done.stderr[-2000:]


def _lazy_table_and_mirror(
    path: Path, package: str
) -> tuple[set[tuple[str, str]], set[tuple[str, str]]]:
    """(name, module) pairs a package's ``_EXPORTS`` loads on first use, and those its
    ``if TYPE_CHECKING:`` block imports."""
    tree = ast.parse(path.read_text())
    table: set[tuple[str, str]] = set()
    mirror: set[tuple[str, str]] = set()
    for node in tree.body:
        if isinstance(node, ast.AnnAssign | ast.Assign) and isinstance(node.value, ast.Dict):
            target = node.target if isinstance(node, ast.AnnAssign) else node.targets[0]
            if getattr(target, "id", "") == "_EXPORTS":
                for key, value in zip(node.value.keys, node.value.values, strict=True):
                    module = ast.literal_eval(value)
                    table.add(
                        (ast.literal_eval(key), module if "." in module else f"{package}.{module}")
                    )
        elif isinstance(node, ast.If) and getattr(node.test, "id", "") == "TYPE_CHECKING":
            mirror.update(
                (alias.name, statement.module)
                for statement in node.body
                if isinstance(statement, ast.ImportFrom) and statement.module
                for alias in statement.names
            )
    return table, mirror


def test_the_lazy_tables_hide_no_import_from_the_check() -> None:
    """A package that loads names on first use (``importlib`` and a table) must import the
    same under TYPE_CHECKING: the import graph sees only import statements, and an
    import of the package must show as what it can load."""
    package = ROOT / "src" / "bfsitl"
    checked = 0
    for init in package.rglob("__init__.py"):
        if "_EXPORTS" not in init.read_text():
            continue
        name = ".".join(init.parent.relative_to(package.parent).parts)
        table, mirror = _lazy_table_and_mirror(init, name)
        assert table == mirror, (name, sorted(table ^ mirror))
        checked += 1
    assert checked >= 2  # the package root and bfsitl.build
