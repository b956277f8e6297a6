"""What the declared layers (pyproject.toml's [tool.importlinter], run by
test_import_layers.py) leave open: the physics imports nothing of bfsitl but the errors,
nobody outside the backend factory asks what kind of backend or link it has, modules stay
small enough to read (issue 21's seams), and the unit tests mirror the packages."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[3] / "src" / "bfsitl"
#: What the physics may import of bfsitl: itself, the one exception tree, and the model it is
#: the face of (its C source's ctypes layout and the loader that builds it).
PHYSICS_MAY_IMPORT = (
    "bfsitl.physics",
    "bfsitl.errors",
    "bfsitl.kernel.compiler",
    "bfsitl.kernel.layout",
)


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
    offenders = [
        f"{path.name}: {name}"
        for path in sorted((PACKAGE / "physics").glob("*.py"))
        for name in _imports(path)
        if not name.startswith(PHYSICS_MAY_IMPORT)
    ]
    assert not offenders, offenders


def test_the_physics_modules_stay_small() -> None:
    sizes = {
        path.name: len(path.read_text().splitlines()) for path in (PACKAGE / "physics").glob("*.py")
    }
    assert max(sizes.values()) <= 600, sizes


#: The kinds of backend, bridge, clock and link: what the factory picks and nobody asks.
BACKEND_TYPES = {
    "SitlBridge",
    "LockstepBridge",
    "LockstepClock",
    "RealTimeClock",
    "WallClock",
    "Backend",
    "SitlBackend",
    "RealTimeBackend",
    "LockstepBackend",
    "GazeboBackend",
    "BoardBackend",
    "TcpLink",
    "SerialLink",
    "SteppedLink",
    "UdpRcLink",
    "MspRcLink",
    "LockstepRc",
    "FlightSession",
    "BoardVehicle",
}


def test_nobody_asks_which_kind_of_backend_or_link_it_has() -> None:
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        if path.relative_to(PACKAGE).as_posix() == "backend/factory.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id == "isinstance"
                and len(node.args) == 2
            ):
                kinds = node.args[1].elts if isinstance(node.args[1], ast.Tuple) else [node.args[1]]
                named = {k.id if isinstance(k, ast.Name) else getattr(k, "attr", "") for k in kinds}
                if named & BACKEND_TYPES:
                    offenders.append(f"{path.relative_to(PACKAGE)}:{node.lineno}")
    assert not offenders, offenders


def test_no_source_file_is_over_about_600_lines() -> None:
    sizes = {
        path.relative_to(PACKAGE).as_posix(): len(path.read_text().splitlines())
        for path in PACKAGE.rglob("*.py")
    }
    too_long = {name: lines for name, lines in sizes.items() if lines > 620}
    assert too_long == {}


UNIT_TESTS = PACKAGE.parents[1] / "tests" / "unit"
#: The folder of tests/unit that is no package of bfsitl: checks of the project as a whole.
PROJECT_CHECKS = "project"
#: Packages without unit tests of their own: shipped data (the scenario library, read by the
#: scenario and input-fuzz tests).
NO_UNIT_FOLDER = {"library"}


def test_the_unit_tests_mirror_the_packages() -> None:
    packages = {path.parent.name for path in PACKAGE.glob("*/__init__.py")}
    folders = {
        path.name for path in UNIT_TESTS.iterdir() if path.is_dir() and path.name != "__pycache__"
    }
    assert folders - {PROJECT_CHECKS} <= packages, "a folder of tests/unit names no package"
    assert packages - NO_UNIT_FOLDER <= folders, "a package has no folder in tests/unit"
    # Tests of the top-level modules (autopilot.py, errors.py) stand at tests/unit itself.
    top_level = {path.stem for path in PACKAGE.glob("*.py")}
    for test in UNIT_TESTS.glob("test_*.py"):
        assert test.stem.removeprefix("test_") in top_level, test.name
    # Test folders are no packages (pytest puts each on sys.path): a name must be unique.
    names = [path.name for path in UNIT_TESTS.parent.rglob("test_*.py")]
    assert len(names) == len(set(names)), sorted(n for n in names if names.count(n) > 1)
