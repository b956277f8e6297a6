"""Session-scoped SITL builds for the integration tests: master and 4.6.0 with GPS.

* ``master_firmware``: master (2026.12.0-alpha, MSP API 1.49, GPS built in, takes ``--ip``),
  built from the tarball in ``shared/firmware/`` beside the repository;
* ``gps_firmware``: 4.6.0 from the installed ``betaflight`` package, built with ``--gps``
  (virtual GPS, GPS Rescue, altitude and position hold);
* ``lockstep_46_firmware`` and ``lockstep_master_firmware``: both generations built with
  ``--lockstep`` (named ``4.6.0-lockstep`` and ``master-lockstep``);
* ``firmware_builds``: master and 4.6.0-gps, as ``{"master": path, "4.6.0-gps": path}``;
* ``firmware_build_cache``: the :class:`~bfsitl.build.FirmwareCache` they are in (its ``root``
  is what ``BFSITL_CACHE_DIR`` must be for a ``bfsitl`` subprocess to know their names).

Each fixture returns the binary's absolute :class:`~pathlib.Path`.  pytest finds fixtures
among the names of a conftest or a test module, so import them into either::

    from firmware_builds import gps_firmware  # noqa: F401  (a pytest fixture)

    def test_something(gps_firmware): ...

Imported in both places, each gets a second instance; it finds the first one's builds in the
session's cache directory (a cache hit, well under a second) rather than compiling again.

Each is built once per session, with ``-j2`` (CI has two cores): master in about 15 s, 4.6.0
in 30 to 45 s.  With ``BFSITL_TEST_CACHE_DIR`` set, the builds are kept there between sessions
and a later session finds them in well under a second; otherwise they go to pytest's session
temporary directory.  Without the tarball, the package, gcc or make the fixtures skip, unless
``BFSITL_REQUIRE_SITL=1``, where they fail.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from bfsitl.build import BuildProgress, FirmwareBuildOptions, FirmwareCache, build_firmware
from bfsitl.build.source_tree import package_source_dir
from bfsitl.errors import FirmwareBuildError

SHARED_DIR = Path(__file__).resolve().parents[2].parent / "shared"
MASTER_TARBALL = SHARED_DIR / "firmware" / "betaflight-2026.12.0-alpha-301d01a-sitl-src.tar.xz"
MASTER_NAME = "master"
GPS_46_NAME = "4.6.0-gps"
LOCKSTEP_46_NAME = "4.6.0-lockstep"
LOCKSTEP_MASTER_NAME = "master-lockstep"
LOCKSTEP_GPS_46_NAME = "4.6.0-gps-lockstep"
BUILD_JOBS = 2
CACHE_ENV_VAR = "BFSITL_TEST_CACHE_DIR"


def _unavailable(reason: str) -> None:
    if os.environ.get("BFSITL_REQUIRE_SITL") == "1":
        pytest.fail(f"BFSITL_REQUIRE_SITL=1 but {reason}")
    pytest.skip(reason)


def _check_tools() -> None:
    missing = [tool for tool in ("gcc", "make") if shutil.which(tool) is None]
    if missing:
        _unavailable(f"{' and '.join(missing)} not installed (apt-get install gcc make)")


@pytest.fixture(scope="session")
def firmware_build_cache(tmp_path_factory: pytest.TempPathFactory) -> FirmwareCache:
    configured = os.environ.get(CACHE_ENV_VAR)
    # One fixed directory per session, not mktemp: a module that imports these fixtures next
    # to a conftest that does too gets a second instance of each, which must find the builds
    # of the first in the cache instead of compiling them again.
    root = Path(configured) if configured else tmp_path_factory.getbasetemp() / "firmware-cache"
    return FirmwareCache(root)


def _build(cache: FirmwareCache, source: Path | None, options: FirmwareBuildOptions,
           name: str) -> Path:
    _check_tools()
    try:
        result = build_firmware(source, options, name=name, jobs=BUILD_JOBS, cache=cache,
                                progress=BuildProgress(live=False))
    except FirmwareBuildError as exc:
        pytest.fail(f"building the {name} SITL failed: {exc}")
    return result.binary_path


@pytest.fixture(scope="session")
def master_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """Master's SITL, built from ``shared/firmware/``'s tarball (named ``master``)."""
    if not MASTER_TARBALL.is_file():
        _unavailable(f"no master source tarball at {MASTER_TARBALL}")
    return _build(firmware_build_cache, MASTER_TARBALL, FirmwareBuildOptions(), MASTER_NAME)


@pytest.fixture(scope="session")
def gps_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 with ``--gps``, from the installed betaflight package (named ``4.6.0-gps``)."""
    if package_source_dir() is None:
        _unavailable("the betaflight package (the sitl extra), whose 4.6.0 tree is built, "
                     "is not installed")
    return _build(firmware_build_cache, None, FirmwareBuildOptions(gps=True), GPS_46_NAME)


@pytest.fixture(scope="session")
def lockstep_46_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 from the installed betaflight package with ``--lockstep``."""
    if package_source_dir() is None:
        _unavailable("the betaflight package (the sitl extra), whose 4.6.0 tree is built, "
                     "is not installed")
    return _build(firmware_build_cache, None, FirmwareBuildOptions(lockstep=True),
                  LOCKSTEP_46_NAME)


@pytest.fixture(scope="session")
def lockstep_gps_46_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 with ``--gps --lockstep``: position control on 4.6.0 needs its GPS."""
    if package_source_dir() is None:
        _unavailable("the betaflight package (the sitl extra), whose 4.6.0 tree is built, "
                     "is not installed")
    return _build(firmware_build_cache, None, FirmwareBuildOptions(gps=True, lockstep=True),
                  LOCKSTEP_GPS_46_NAME)


@pytest.fixture(scope="session")
def lockstep_master_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """Master from ``shared/firmware/``'s tarball with ``--lockstep``."""
    if not MASTER_TARBALL.is_file():
        _unavailable(f"no master source tarball at {MASTER_TARBALL}")
    return _build(firmware_build_cache, MASTER_TARBALL, FirmwareBuildOptions(lockstep=True),
                  LOCKSTEP_MASTER_NAME)


@pytest.fixture(scope="session")
def firmware_builds(master_firmware: Path, gps_firmware: Path) -> dict[str, Path]:
    return {MASTER_NAME: master_firmware, GPS_46_NAME: gps_firmware}
