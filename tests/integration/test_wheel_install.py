"""The wheel holds everything: built from the checkout, installed into an empty virtualenv, run
from a directory with no checkout anywhere on its path.

What a user who runs ``pip install bfsitl`` gets must work without the repository: the shipped
scenario library and example missions (package data), the lockstep patch's C source, the
``bfsitl`` command and ``--version``, and a whole lockstep flight.  The wheel is built by pip
(setuptools from the registry, as a user's pip would), installed with its dependencies from the
registry, and the firmware is the session's 4.6.0 lockstep build (compiling it again from the
wheel's venv would only repeat ``test_firmware_build_sitl``).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from bfsitl.library import mission_files, scenario_files

pytestmark = pytest.mark.sitl

REPO = Path(__file__).resolve().parents[2]
#: Left out of the copy the wheel is built from: never part of a source tree.
_NOT_SOURCE_ANYWHERE = shutil.ignore_patterns(
    ".git",
    ".venv",
    "*.egg-info",
    "__pycache__",
    ".pytest_cache",
    ".hypothesis",
    ".mypy_cache",
    ".ruff_cache",
)
#: Outputs at the top of a checkout (``src/bfsitl/build`` is a package: only the top's go).
_NOT_SOURCE_AT_TOP = {"build", "dist", "site"}


def _not_source(directory: str, names: list[str]) -> set[str]:
    ignored = set(_NOT_SOURCE_ANYWHERE(directory, names))
    if Path(directory) == REPO:
        ignored |= _NOT_SOURCE_AT_TOP & set(names)
    return ignored


def _clean_env() -> dict[str, str]:
    """The environment of a user's shell: no test-session variables pointing into the repo."""
    env = {
        key: value
        for key, value in os.environ.items()
        if not key.startswith(("BFSITL_", "PYTEST", "VIRTUAL_ENV", "PYTHON"))
    }
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, Path]]:
    """(the wheel, the bin/ of an empty venv with the wheel installed in it)."""
    root = tmp_path_factory.mktemp("wheel")
    source = root / "source"
    shutil.copytree(REPO, source, ignore=_not_source)
    built = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--quiet",
            "-w",
            str(root / "dist"),
            str(source),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        env=_clean_env(),
    )
    assert built.returncode == 0, built.stdout + built.stderr
    wheel = next((root / "dist").glob("bfsitl-*.whl"))
    venv.create(root / "venv", with_pip=True)
    bin_dir = root / "venv" / "bin"
    install = subprocess.run(
        [str(bin_dir / "python"), "-m", "pip", "install", "--quiet", str(wheel)],
        capture_output=True,
        text=True,
        timeout=600,
        env=_clean_env(),
    )
    assert install.returncode == 0, install.stdout + install.stderr
    yield wheel, bin_dir


def _bfsitl(
    bin_dir: Path,
    cwd: Path,
    *args: str,
    env: dict[str, str] | None = None,
    timeout_s: float = 120.0,
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(bin_dir / "bfsitl"), *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=timeout_s,
        env=env or _clean_env(),
    )


def test_the_wheel_carries_the_library_the_missions_and_the_lockstep_patch(installed):
    wheel, _bin = installed
    names = set(zipfile.ZipFile(wheel).namelist())
    for path in scenario_files():
        assert f"bfsitl/library/scenarios/{path.name}" in names
    for path in mission_files():
        assert f"bfsitl/library/missions/{path.name}" in names
    assert any(n.startswith("bfsitl/build/lockstep/") and n.endswith(".c") for n in names)
    for name in ("physics.c", "physics.h", "lockstep_loop.c"):  # the compiled step's sources
        assert f"bfsitl/kernel/{name}" in names
    assert "bfsitl/py.typed" in names
    # Nothing of the checkout's tests or data rides along.
    assert not any(n.startswith(("tests/", "benchmarks/")) for n in names)


def test_installed_bfsitl_runs_from_its_own_files(installed, tmp_path):
    _wheel, bin_dir = installed
    where = subprocess.run(
        [str(bin_dir / "python"), "-c", "import bfsitl; print(bfsitl.__file__)"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env=_clean_env(),
    )
    assert where.returncode == 0, where.stderr
    assert Path(where.stdout.strip()).is_relative_to(bin_dir.parent), where.stdout
    assert not Path(where.stdout.strip()).is_relative_to(REPO)

    version = _bfsitl(bin_dir, tmp_path, "--version")
    assert version.returncode == 0 and version.stdout.startswith("bfsitl "), version
    assert version.stdout.split()[1][0].isdigit()

    listed = _bfsitl(bin_dir, tmp_path, "scenario", "list")  # no path: the shipped library
    assert listed.returncode == 0, listed.stderr
    for path in scenario_files():
        assert path.stem in listed.stdout, (path.stem, listed.stdout)


def test_a_lockstep_flight_from_the_installed_wheel(installed, lockstep_46_firmware, tmp_path):
    _wheel, bin_dir = installed
    # A cache of its own: the physics is built from the wheel's C sources, not found.
    env = {**_clean_env(), "BFSITL_CACHE_DIR": str(tmp_path / "cache")}
    flown = _bfsitl(
        bin_dir,
        tmp_path,
        "fly",
        "--firmware",
        str(lockstep_46_firmware),
        "--hold",
        "2",
        "--json",
        "--log",
        "flight.csv",
        timeout_s=180,
        env=env,
    )
    assert flown.returncode == 0, flown.stderr[-3000:]
    summary = json.loads(flown.stdout)
    assert summary["outcome"] == "landed", summary
    assert list((tmp_path / "cache" / "kernel").glob("bfsitl-kernel-*.so"))
    assert (tmp_path / "flight.csv").stat().st_size > 1000
