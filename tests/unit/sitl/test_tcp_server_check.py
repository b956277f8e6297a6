"""TcpServerCheck: a SITL whose MSP port's TCP server was lost at boot is recognised at once.

The accept-queue symptom is produced with real kernel sockets here (a listener nobody
accepts on), read back through /proc exactly as for a SITL; the log symptom with a log file
written the way the SITL writes it."""

from __future__ import annotations

import socket
from collections.abc import Iterator
from contextlib import closing

import pytest

from bfsitl.errors import SitlNotReadyError, SitlTcpServerLostError
from bfsitl.sitl.tcp_server_check import TcpServerCheck

BOOT_LOG = """\
[SITL] start UDP server for RC input @9004...0
[FLASH_Unlock] loaded 'eeprom.bin', size = 32768 / 32768
[system]Reset!
"""


@pytest.fixture
def listener() -> Iterator[socket.socket]:
    """A TCP listener on a free loopback port that never accepts."""
    with closing(socket.socket(socket.AF_INET, socket.SOCK_STREAM)) as server:
        server.bind(("127.0.0.1", 0))
        server.listen(10)
        yield server


def check_for(port: int, tmp_path, log_text: str = "", offset: int = 0) -> TcpServerCheck:
    log_path = tmp_path / "sitl.log"
    log_path.write_text(log_text)
    return TcpServerCheck(
        log_path=log_path, log_offset=offset, netns_pid=None, port=port, stall_s=0.5
    )


def test_a_port_nobody_accepts_on_is_reported_after_the_stall_time(listener, tmp_path):
    port = listener.getsockname()[1]
    check = check_for(port, tmp_path)
    with closing(socket.create_connection(("127.0.0.1", port), timeout=1.0)):
        assert check.accept_queue() == 1
        check.check(10.0)  # first seen queued: not yet a verdict
        check.check(10.4)
        with pytest.raises(SitlTcpServerLostError, match="accepted no connection") as caught:
            check.check(10.5)
    # Handled wherever a start that never became ready is handled (the retry in start()).
    assert isinstance(caught.value, SitlNotReadyError)


def test_a_server_that_accepts_is_never_reported(listener, tmp_path):
    port = listener.getsockname()[1]
    check = check_for(port, tmp_path)
    with closing(socket.create_connection(("127.0.0.1", port), timeout=1.0)):
        check.check(10.0)
        accepted, _peer = listener.accept()
        with closing(accepted):
            assert check.accept_queue() == 0
            check.check(10.4)
            check.check(12.0)  # the clock restarted when the queue emptied


def test_nothing_listening_yet_is_booting_not_lost(tmp_path):
    with closing(socket.socket()) as probe:
        probe.bind(("127.0.0.1", 0))
        free_port = probe.getsockname()[1]
    check = check_for(free_port, tmp_path, BOOT_LOG)
    assert check.accept_queue() == 0
    check.check(0.0)
    check.check(100.0)


def test_a_failed_bind_in_this_launchs_log_is_reported_at_once(tmp_path):
    check = check_for(5761, tmp_path, BOOT_LOG + "bind port 5761 for UART1 failed!!\n")
    with pytest.raises(SitlTcpServerLostError, match="bind failed"):
        check.check(0.0)


def test_a_failed_bind_of_an_earlier_launch_is_not_this_ones(tmp_path):
    earlier = BOOT_LOG + "bind port 5761 for UART1 failed!!\n"
    now = BOOT_LOG + "bind port 5761 for UART1\n"
    check = check_for(5761, tmp_path, earlier + now, offset=len(earlier))
    check.check(0.0)


def test_another_uarts_failed_bind_is_not_the_msp_port(tmp_path):
    check = check_for(5761, tmp_path, BOOT_LOG + "bind port 5762 for UART2 failed!!\n")
    check.check(0.0)
