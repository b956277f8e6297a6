"""Every non-Python file in the package is declared as package data, so a wheel carries it
(an editable install would work without, and hide the loss: the lockstep C source was
missing from wheels until this test)."""

from __future__ import annotations

import fnmatch
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
PACKAGE = ROOT / "src" / "bfsitl"


def test_every_data_file_in_the_package_is_declared():
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]
    data_files = [
        p
        for p in PACKAGE.rglob("*")
        if p.is_file() and p.suffix not in (".py", ".pyc") and "__pycache__" not in p.parts
    ]
    assert data_files, "the walk found no data files"
    undeclared = []
    for path in data_files:
        relative = path.relative_to(PACKAGE.parent)  # bfsitl/...
        ok = False
        for package, patterns in declared.items():
            package_dir = Path(*package.split("."))
            if package_dir in relative.parents:
                inner = str(relative.relative_to(package_dir))
                ok = ok or any(fnmatch.fnmatch(inner, pattern) for pattern in patterns)
        if not ok:
            undeclared.append(str(relative))
    assert undeclared == [], "add these to [tool.setuptools.package-data] in pyproject.toml"
