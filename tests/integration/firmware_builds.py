"""Session-scoped SITL builds for the integration tests: master and 4.6.0 with GPS.

* ``master_firmware``: master (GPS built in, takes ``--ip``), built from the source the user
  names in ``BFSITL_MASTER_SOURCE``: a betaflight/betaflight tree, a tarball of one, or a git
  URL (``URL`` or ``URL@REF``, cloned as ``bfsitl firmware build --git`` does).  The project
  carries no master source; without that variable every master test is skipped with one line
  that says what to set, ``BFSITL_REQUIRE_SITL=1`` or not (CI has no master to give);
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
temporary directory.  Without the package, gcc or make the fixtures skip, unless
``BFSITL_REQUIRE_SITL=1``, where they fail.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from bfsitl.build import BuildProgress, FirmwareBuildOptions, FirmwareCache, build_firmware
from bfsitl.build.git_source import fetch_git_source, is_git_url
from bfsitl.build.source_tree import package_source_dir
from bfsitl.cli.firmware_command import GIT_SOURCES_DIR
from bfsitl.errors import FirmwareBuildError

MASTER_SOURCE_ENV_VAR = "BFSITL_MASTER_SOURCE"
#: The one line every master test is skipped with when no master source is given.
MASTER_SKIP_REASON = (
    f"master not given: set {MASTER_SOURCE_ENV_VAR} to a betaflight/betaflight "
    f"tree, tarball or git URL (URL@REF) to run the master tests"
)
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


def _build(
    cache: FirmwareCache, source: Path | None, options: FirmwareBuildOptions, name: str
) -> Path:
    _check_tools()
    try:
        result = build_firmware(
            source,
            options,
            name=name,
            jobs=BUILD_JOBS,
            cache=cache,
            progress=BuildProgress(live=False),
        )
    except FirmwareBuildError as exc:
        pytest.fail(f"building the {name} SITL failed: {exc}")
    return result.binary_path


def master_source_given() -> bool:
    """Whether the user pointed the suite at a master source (the tests that need one run)."""
    return bool(os.environ.get(MASTER_SOURCE_ENV_VAR, "").strip())


def master_source(cache: FirmwareCache) -> Path:
    """The master tree or tarball named by ``BFSITL_MASTER_SOURCE``; a git URL is cloned first
    (shallow, cached by commit).  Skips (never fails) when the variable is not set: the
    project has no master of its own, so its absence is not a broken machine."""
    given = os.environ.get(MASTER_SOURCE_ENV_VAR, "").strip()
    if not given:
        pytest.skip(MASTER_SKIP_REASON)
    if is_git_url(given):
        url, _, ref = given.rpartition("@") if _has_ref(given) else (given, "", "")
        try:
            return _clone(url, ref or None, cache)
        except FirmwareBuildError as exc:
            pytest.fail(f"{MASTER_SOURCE_ENV_VAR}={given}: {exc}")
    path = Path(given).expanduser()
    if not path.exists():
        pytest.fail(f"{MASTER_SOURCE_ENV_VAR}={given}: no such directory or tarball")
    return path.resolve()


def _clone(url: str, ref: str | None, cache: FirmwareCache) -> Path:
    """A shallow clone of ``ref`` at ``url`` in the session's cache, as ``--git`` makes."""
    progress = BuildProgress(live=False)
    return fetch_git_source(url, ref, cache.root / GIT_SOURCES_DIR, note=progress.note).tree


def _has_ref(given: str) -> bool:
    # ``https://host/repo@master``: an ``@`` after the last ``/`` names the ref (one in the
    # authority part, ``git@host:...`` or ``user@host``, does not).
    tail = given.rsplit("/", 1)[-1]
    return "@" in tail


@pytest.fixture(scope="session")
def master_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """Master's SITL, built from ``BFSITL_MASTER_SOURCE`` (named ``master``)."""
    source = master_source(firmware_build_cache)
    return _build(firmware_build_cache, source, FirmwareBuildOptions(), MASTER_NAME)


@pytest.fixture(scope="session")
def gps_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 with ``--gps``, from the installed betaflight package (named ``4.6.0-gps``)."""
    if package_source_dir() is None:
        _unavailable(
            "the betaflight package (the sitl extra), whose 4.6.0 tree is built, is not installed"
        )
    return _build(firmware_build_cache, None, FirmwareBuildOptions(gps=True), GPS_46_NAME)


@pytest.fixture(scope="session")
def lockstep_46_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 from the installed betaflight package with ``--lockstep``."""
    if package_source_dir() is None:
        _unavailable(
            "the betaflight package (the sitl extra), whose 4.6.0 tree is built, is not installed"
        )
    return _build(firmware_build_cache, None, FirmwareBuildOptions(lockstep=True), LOCKSTEP_46_NAME)


@pytest.fixture(scope="session")
def lockstep_gps_46_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """4.6.0 with ``--gps --lockstep``: position control on 4.6.0 needs its GPS."""
    if package_source_dir() is None:
        _unavailable(
            "the betaflight package (the sitl extra), whose 4.6.0 tree is built, is not installed"
        )
    return _build(
        firmware_build_cache,
        None,
        FirmwareBuildOptions(gps=True, lockstep=True),
        LOCKSTEP_GPS_46_NAME,
    )


@pytest.fixture(scope="session")
def lockstep_master_firmware(firmware_build_cache: FirmwareCache) -> Path:
    """Master from ``BFSITL_MASTER_SOURCE`` with ``--lockstep`` (named ``master-lockstep``)."""
    source = master_source(firmware_build_cache)
    return _build(
        firmware_build_cache, source, FirmwareBuildOptions(lockstep=True), LOCKSTEP_MASTER_NAME
    )


@pytest.fixture(scope="session")
def firmware_builds(master_firmware: Path, gps_firmware: Path) -> dict[str, Path]:
    return {MASTER_NAME: master_firmware, GPS_46_NAME: gps_firmware}
