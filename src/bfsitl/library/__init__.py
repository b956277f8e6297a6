"""What ships inside the wheel beside the code: the scenario library, example missions,
vehicle profiles and trained policies.

``bfsitl scenario list`` and ``bfsitl scenario run`` with no path use :func:`scenarios_dir`;
``bfsitl fly --mission square`` finds a shipped mission by its name (:func:`find_mission`).
``--vehicle 5inch-freestyle`` finds a shipped vehicle profile (:func:`vehicle_files`), and
``--policy hover-iris`` a shipped policy (:func:`find_policy`).
The files are package data, so an installed wheel has them with no checkout anywhere.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = [
    "find_mission",
    "find_policy",
    "mission_files",
    "missions_dir",
    "scenario_files",
    "scenarios_dir",
    "vehicle_files",
]


def _package_dir(name: str) -> Path:
    # The package is installed as plain files (setuptools wheels and editable installs both),
    # so the traversable is a real directory the TOML readers can open by path.
    return Path(str(resources.files(__package__).joinpath(name)))


def scenarios_dir() -> Path:
    """The shipped scenario library (one ``.toml`` file per scenario)."""
    return _package_dir("scenarios")


def missions_dir() -> Path:
    """The shipped example missions (``square.toml``...)."""
    return _package_dir("missions")


def scenario_files() -> list[Path]:
    """Every shipped scenario file, sorted by name."""
    return sorted(scenarios_dir().glob("*.toml"))


def mission_files() -> list[Path]:
    """Every shipped mission file, sorted by name."""
    return sorted(missions_dir().glob("*.toml"))


def find_mission(name: str) -> Path | None:
    """A shipped mission by its name, with or without ``.toml`` (``square``), or None."""
    stem = name[:-5] if name.endswith(".toml") else name
    if not stem or "/" in stem or "\\" in stem:
        return None
    path = missions_dir() / f"{stem}.toml"
    return path if path.is_file() else None


def find_policy(name: str) -> Path | None:
    """A shipped policy by its name, with or without ``.onnx`` (``hover-iris``), or None."""
    stem = name[:-5] if name.endswith(".onnx") else name
    if not stem or "/" in stem or "\\" in stem:
        return None
    path = _package_dir("policies") / f"{stem}.onnx"
    return path if path.is_file() else None


def vehicle_files() -> list[Path]:
    """Every shipped vehicle profile (``5inch-freestyle.toml``...), sorted by name."""
    return sorted(_package_dir("vehicles").glob("*.toml"))
