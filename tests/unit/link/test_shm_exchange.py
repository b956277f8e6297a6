"""The shared-memory lockstep exchange without a firmware: a stand-in FC in a thread maps the
region as sitl_lockstep.c does (header, sequence words, futex wake-ups) and answers; the bridge
steps through it exactly as over UDP, falls back to UDP until the FC has mapped the region,
waits out an FC that answers late, and refuses a region of another layout."""

from __future__ import annotations

import struct
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from support.fake_simulator import FakeSimulator
from support.shared_fake_fc import (
    HEADER_WORDS,
    SharedFakeFc,
    assert_a_silent_fc_is_asked_about,
    bridge_on,
)

from bfsitl.backend.factory import uses_shm_exchange
from bfsitl.build.binary_scan import SHM_EXCHANGE_MARKER, clear_cache
from bfsitl.build.lockstep import MARKER
from bfsitl.errors import BfsitlError, SitlError
from bfsitl.fc.rc_link import RcCommand
from bfsitl.link.shm_exchange import (
    REGION_BYTES,
    SHM_ENV,
    ShmExchange,
    shm_exchange_supported,
)
from bfsitl.sim.lockstep_io import LockstepClock, LockstepRc
from bfsitl.sitl.firmware import FirmwareBinary

pytestmark = pytest.mark.skipif(
    not shm_exchange_supported(), reason="the shared-memory exchange is x86-64 Linux only"
)


@pytest.fixture
def region(tmp_path: Path):
    exchange = ShmExchange(tmp_path)
    yield exchange
    exchange.close()


def test_steps_go_through_the_region_with_their_rc_and_apply_their_own_answer(
    region: ShmExchange,
) -> None:
    assert region.env == {SHM_ENV: str(region.path)} and region.path.exists()
    fc = SharedFakeFc(region.path)
    simulator = FakeSimulator()
    try:
        bridge = bridge_on(region, simulator)
        rc = LockstepRc(bridge)
        rc.set(RcCommand(throttle_us=1300, aux_us=(1800, 1000)))
        bridge.lock()
        LockstepClock(bridge).sleep_s(0.005)
        assert region.ready
        assert bridge.lockstep_stats().steps == 6 and bridge.lockstep_stats().resends == 0
        bridge.close()
    finally:
        fc.close()
    assert all(motors == pytest.approx((0.1, 0.2, 0.3, 0.4)) for motors in simulator.applied)
    assert [stamp for stamp, _ in fc.received] == pytest.approx(
        [0.0, 0.001, 0.002, 0.003, 0.004, 0.005]
    )
    assert fc.received[-1][1] == (1500, 1500, 1300, 1500, 1800, 1000)


def test_until_the_fc_maps_the_region_the_lock_goes_over_udp_then_moves_over(
    region: ShmExchange, tmp_path: Path
) -> None:
    simulator = FakeSimulator()
    bridge = bridge_on(region, simulator)
    started: list[SharedFakeFc] = []
    # The FC maps the region while the bridge is already trying to lock it.
    timer = threading.Timer(0.05, lambda: started.append(SharedFakeFc(region.path)))
    timer.start()
    try:
        bridge.lock()
        bridge.step()
    finally:
        timer.join()
        for fc in started:
            fc.close()
        bridge.close()
    assert region.ready and len(simulator.applied) == 2
    assert started[0].received[0][0] == 0.0  # the lock's packet, taken from the region


def test_a_late_answer_is_waited_for_and_a_silent_fc_is_asked_about(region: ShmExchange) -> None:
    fc = SharedFakeFc(region.path, delay_s=0.08)  # longer than one futex wait
    try:
        bridge = bridge_on(region, FakeSimulator(), spin_s=0.0)
        bridge.lock()
        bridge.step()
        assert bridge.lockstep_stats().resends == 0
        assert_a_silent_fc_is_asked_about(bridge, fc)
        bridge.close()
    finally:
        fc.close()


def test_a_region_of_another_layout_is_refused_with_the_fix(region: ShmExchange) -> None:
    fc = SharedFakeFc(region.path, version=7)
    try:
        with pytest.raises(SitlError, match=r"version 7 .* rebuild the firmware"):
            assert region.ready
    finally:
        fc.close()


@pytest.mark.parametrize("version", [1, 2])
def test_a_write_to_the_fcs_tcp_ports_marks_the_next_two_requests_where_the_fc_reads_marks(
    region: ShmExchange, version: int
) -> None:
    # A version 2 FC services its TCP ports only after the packets the simulator marks (and
    # when it wrote, and every few ms): a request written now is read after the next packet,
    # the second one covers a connection made just before.  A version 1 FC services them
    # after every packet and has no such word: its datagram starts there, and stays whole.
    fc = SharedFakeFc(region.path, version=version)
    try:
        bridge = bridge_on(region, FakeSimulator())
        bridge.lock()
        LockstepClock(bridge).sleep_s(0.003)
        marked_after = region.seq
        word = bytes(fc.map[32:36])  # version 1: the start of the datagram last sent
        bridge.wrote_to_fc()
        assert (bytes(fc.map[32:36]) == word) is (version == 1)
        LockstepClock(bridge).sleep_s(0.004)
        bridge.close()
    finally:
        fc.close()
    if version == 1:
        assert fc.tcp_until == []
        return
    # Requests are numbered from 1 in a fresh region: the lock, three steps, then four.
    assert marked_after == 4 and len(fc.tcp_until) == 8
    asked = [((until - seq) & 0xFFFFFFFF) < 2**31 for seq, until in enumerate(fc.tcp_until, 1)]
    assert asked == [False] * 4 + [True, True, False, False]


def test_closing_removes_the_region_and_a_dead_owners_region_goes_too(tmp_path: Path) -> None:
    exchange = ShmExchange(tmp_path)
    assert exchange.path.stat().st_size == REGION_BYTES
    exchange.close()
    exchange.close()
    assert not exchange.path.exists()
    dead = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    stale = tmp_path / f"bfsitl-lockstep-{dead}-0123456789ab"
    stale.write_bytes(b"\0" * 64)
    forgotten = ShmExchange(tmp_path)  # never closed: removed when it goes
    alive = forgotten.path
    assert not stale.exists() and alive.exists()
    del forgotten
    assert not alive.exists()


def test_the_exchange_is_chosen_from_the_build_and_the_request(tmp_path: Path) -> None:
    def binary(name: str, *markers: bytes) -> FirmwareBinary:
        path = tmp_path / name
        path.write_bytes(b"\x00" * 64 + b"".join(markers))
        clear_cache()
        return FirmwareBinary(path, "test")

    new = binary("new", MARKER.encode() + b"\x00", SHM_EXCHANGE_MARKER)
    old = binary("old", MARKER.encode() + b"\x00")
    assert uses_shm_exchange(new, "auto") and not uses_shm_exchange(new, "udp")
    assert not uses_shm_exchange(old, "auto")  # an earlier lockstep build: UDP
    with pytest.raises(BfsitlError, match="built without it: rebuild it"):
        uses_shm_exchange(old, "shm")
    with pytest.raises(BfsitlError, match="one of auto, shm, udp"):
        uses_shm_exchange(new, "pigeon")
    assert struct.calcsize("<9I") == 4 * HEADER_WORDS[2]
