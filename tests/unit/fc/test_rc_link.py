"""The RC link: steady UDP stream, clamping, and disarm on every way out.

A receiver socket in a private namespace stands in for the SITL's UDP 9004; the real SITL arms
through this link in tests/integration/test_sim_bridge.py.
"""

from __future__ import annotations

import math
import random
import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest

from bfsitl.errors import BfsitlError
from bfsitl.fc.rc_link import RC_MAX_US, RC_MIN_US, RC_PORT, SAFE_COMMAND, RcCommand, UdpRcLink
from bfsitl.protocol.sitl_packets import RcPacket
from bfsitl.sitl.network import IsolatedNetwork, unshare_available

pytestmark = pytest.mark.skipif(not unshare_available(), reason="needs unshare")


@pytest.fixture
def network() -> Iterator[IsolatedNetwork]:
    with IsolatedNetwork() as net:
        yield net


@pytest.fixture
def receiver(network: IsolatedNetwork) -> Iterator[socket.socket]:
    sock = network.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", RC_PORT))
    sock.settimeout(0.2)
    yield sock
    sock.close()


def drain(sock: socket.socket) -> list[RcPacket]:
    packets = []
    while True:
        try:
            packets.append(RcPacket.unpack(sock.recv(64)))
        except TimeoutError:
            return packets


def test_channels_are_aetr_then_aux_and_clamped():
    command = RcCommand(
        roll_us=900, pitch_us=2500, throttle_us=1234.6, yaw_us=1500, aux_us=(1800, 1000)
    )
    assert command.channels_aetr() == (1000, 2000, 1235, 1500, 1800, 1000)
    assert command.disarmed().channels_aetr() == (1500, 1500, 1000, 1500, 1000, 1000)
    assert RcCommand().with_aux(1, 1700).aux_us == (1000, 1700)
    assert command.with_throttle(1600) == RcCommand(900, 2500, 1600, 1500, (1800, 1000))


def test_the_checked_channels_are_the_rounded_then_clamped_ones() -> None:
    rng = random.Random(7)
    for _ in range(2000):
        values = [rng.uniform(400.0, 2600.0) for _ in range(6)]
        values[rng.randrange(6)] = rng.choice([999.5, 1000.5, 1999.5, 2000.5, 1500, -1e9, 1e9])
        command = RcCommand(*values[:4], aux_us=tuple(values[4:]))
        slow = tuple(int(min(RC_MAX_US, max(RC_MIN_US, round(v)))) for v in values)
        assert command.checked_channels_aetr() == slow == command.channels_aetr()
        assert all(type(us) is int for us in command.channels_aetr())
    # numpy numbers (a policy's actions) give plain ints too
    command = RcCommand(np.float32(1234.4), np.float64(2500.0), np.int64(900), 1500)
    assert command.channels_aetr() == (1234, 2000, 1000, 1500, 1000)
    assert all(type(us) is int for us in command.channels_aetr())


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("channel", range(6))
def test_a_channel_that_is_not_a_number_is_named_whichever_it_is(bad: float, channel: int):
    values = [1500.0, 1500.0, 1000.0, 1500.0, 1000.0, 1000.0]
    values[channel] = bad
    command = RcCommand(*values[:4], aux_us=tuple(values[4:]))
    with pytest.raises(BfsitlError, match=f"RC channel value {bad!r} is not a number"):
        command.channels_aetr()
    with pytest.raises(BfsitlError, match=f"RC channel value {bad!r} is not a number"):
        command.check()
    # finite values whose sum overflows are still channels: clamped, not refused
    assert RcCommand(1e308, 1e308, 1e308, 1e308).channels_aetr() == (2000, 2000, 2000, 2000, 1000)


def test_non_numbers_are_refused_when_set(network):
    link = UdpRcLink(network)
    with pytest.raises(BfsitlError, match="not a number"):
        link.set(RcCommand(throttle_us=float("nan")))
    link.close()


def test_streams_at_100_hz_and_reports_jitter(network, receiver):
    with UdpRcLink(network) as link:
        link.set(RcCommand(throttle_us=1300, aux_us=(1800,)))
        time.sleep(1.0)
        stats = link.stats()
    packets = drain(receiver)
    assert 80 <= len(packets) <= 115
    assert stats.period_mean_ms == pytest.approx(10.0, abs=1.0)
    assert stats.period_max_ms >= stats.period_p99_ms >= stats.period_mean_ms * 0.5
    assert any(p.channels_us[2] == 1300 and p.channels_us[4] == 1800 for p in packets)


def test_close_sends_disarm_and_low_throttle_last(network, receiver):
    link = UdpRcLink(network).start()
    link.set(RcCommand(throttle_us=1700, aux_us=(1800,)))
    time.sleep(0.1)
    link.close()
    link.close()  # idempotent
    last = drain(receiver)[-1]
    assert last.channels_us[:5] == SAFE_COMMAND.channels_aetr()[:4] + (1000,)


def test_an_exception_inside_the_with_block_still_disarms(network, receiver):
    with pytest.raises(RuntimeError):
        with UdpRcLink(network) as link:
            link.set(RcCommand(throttle_us=1800, aux_us=(1900,)))
            time.sleep(0.05)
            raise RuntimeError("mission code failed")
    last = drain(receiver)[-1]
    assert last.channels_us[2] == 1000 and last.channels_us[4] == 1000


def test_rate_limits(network):
    with pytest.raises(ValueError):
        UdpRcLink(network, rate_hz=0)
