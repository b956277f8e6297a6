"""The compiled lockstep loop against a stand-in FC (tests/support/shared_fake_fc.py): the
same datagrams, motors and vehicle states as the bridge stepping in Python, step for step, on both
firmware generations' encodings; a late reply handed over to Python's wait; a reply for
another packet refused; RC changes, the GPS-loss sentinel and RC faults in between."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from support.shared_fake_fc import SharedFakeFc, assert_a_silent_fc_is_asked_about, bridge_on

from bfsitl.errors import SitlError
from bfsitl.fc.rc_link import RcCommand, RcFault
from bfsitl.link.shm_exchange import ShmExchange, shm_exchange_supported
from bfsitl.physics import Simulator
from bfsitl.physics.frames import GeoPoint
from bfsitl.physics.sensors import SensorConfig
from bfsitl.physics.wind import Wind
from bfsitl.protocol.firmware_profile import FirmwareProfile, profile_for
from bfsitl.protocol.sitl_packets import FdmPacket
from bfsitl.sim.lockstep import LockstepBridge
from bfsitl.sim.lockstep_io import LockstepClock, LockstepRc

pytestmark = pytest.mark.skipif(
    not shm_exchange_supported(), reason="the shared-memory exchange is x86-64 Linux only"
)

HOME = GeoPoint(47.397742, 8.545594, 488.0)
PROFILES = {
    "4.6.0": profile_for("1.47", "4.6.0", has_gps=True),
    "master": profile_for("1.49", "2026.12.0-alpha", has_gps=True),
    "4.6.0 no GPS": profile_for("1.47", "4.6.0", has_gps=False),
}


def hover_motors(data: bytes) -> tuple[float, float, float, float]:
    """A stand-in controller in the FC: each slot's command depends on the packet's gyro,
    accelerometer, altitude and time, so any difference in a datagram changes the flight."""
    fdm = FdmPacket.unpack(data[: FdmPacket.SIZE])
    g, a = fdm.gyro_rad_s, fdm.accel_m_s2
    base = 0.58 + 0.04 * math.sin(7.0 * fdm.timestamp_s) - 0.002 * (a[2] + 9.80665)
    roll, pitch, yaw = 0.03 * g[0], 0.03 * g[1], 0.01 * g[2]
    return (
        min(1.0, max(0.0, base - roll + pitch + yaw)),
        min(1.0, max(0.0, base + roll + pitch - yaw)),
        min(1.0, max(0.0, base + roll - pitch + yaw)),
        min(1.0, max(0.0, base - roll - pitch - yaw)),
    )


def fly(
    simulator: Simulator,
    tmp_path: Path,
    profile: FirmwareProfile,
    name: str,
    compiled_loop: bool,
    rc_rate_hz: float | None = None,
) -> tuple[list[bytes], LockstepBridge, object]:
    (tmp_path / name).mkdir()
    region = ShmExchange(tmp_path / name)
    fc = SharedFakeFc(region.path, motors=hover_motors)
    try:
        bridge = bridge_on(
            region, simulator, profile=profile, compiled_loop=compiled_loop, rc_rate_hz=rc_rate_hz
        )
        rc, clock = LockstepRc(bridge), LockstepClock(bridge)
        rc.set(RcCommand(throttle_us=1300, aux_us=(1800, 1000)))
        bridge.lock()
        clock.sleep_s(0.8)
        rc.set(RcCommand(throttle_us=1600, roll_us=1550, aux_us=(1800, 1800)))
        for _ in range(7):
            bridge.step()  # one at a time, as an MSP wait steps
        bridge.set_gps_lost(True)
        clock.sleep_s(0.3)
        bridge.set_gps_lost(False)
        rc.fault = RcFault(delay_s=0.02, jitter_s=0.005)  # Python steps it, step by step
        clock.sleep_s(0.1)
        rc.fault = None
        clock.sleep_s(0.4)
        state = (
            simulator.state,
            simulator.read_sensors(),
            bridge.motors,
            bridge.lockstep_stats().steps,
            bridge.lockstep_stats().resends,
        )
        bridge.close()
    finally:
        fc.close()
        region.close()
    return fc.datagrams, bridge, state


@pytest.mark.parametrize(
    ("generation", "rc_rate_hz"),
    [(generation, None) for generation in sorted(PROFILES)] + [("4.6.0", 250.0), ("master", 150.0)],
)
def test_the_compiled_loop_sends_and_flies_what_python_does(
    tmp_path: Path, generation: str, rc_rate_hz: float | None
) -> None:
    def make() -> Simulator:
        return Simulator(
            sensors=SensorConfig.typical_mems().with_typical_gps(),
            wind=Wind((2.0, -1.0, 0.0), gust_std_m_s=1.0),
            home=HOME,
            seed=7,
        )

    profile = PROFILES[generation]
    python_sent, python_bridge, python_end = fly(make(), tmp_path, profile, "p", False, rc_rate_hz)
    kernel_sent, kernel_bridge, kernel_end = fly(make(), tmp_path, profile, "k", True, rc_rate_hz)
    assert not python_bridge.compiled and kernel_bridge.compiled
    assert len(kernel_sent) == len(python_sent) > 1500
    with_rc = sum(len(datagram) > FdmPacket.SIZE for datagram in kernel_sent)
    # At a link rate, a frame per period after the lock (whose packets all carry one).
    assert with_rc == len(kernel_sent) if rc_rate_hz is None else with_rc < len(kernel_sent) / 3
    pairs = enumerate(zip(python_sent, kernel_sent, strict=True))
    first_difference = next((i for i, (a, b) in pairs if a != b), None)
    assert first_difference is None, f"datagram {first_difference} differs"
    assert kernel_end == python_end


@contextmanager
def compiled_bridge(
    tmp_path: Path, spin_s: float = 0.0, **fc_options: Any
) -> Iterator[tuple[LockstepBridge, SharedFakeFc, ShmExchange]]:
    """A bridge on a region a stand-in FC answers, locked and stepped
    once (so the compiled loop has taken over); the FC and the region are closed after."""
    region = ShmExchange(tmp_path)
    fc = SharedFakeFc(region.path, **fc_options)
    try:
        bridge = bridge_on(region, Simulator(seed=1), spin_s=spin_s)
        bridge.lock()
        bridge.step()
        assert bridge.compiled
        yield bridge, fc, region
    finally:
        fc.close()
        region.close()


def test_a_late_reply_is_handed_to_the_python_wait_and_a_dead_sitl_is_noticed(
    tmp_path: Path,
) -> None:
    with compiled_bridge(tmp_path, delay_s=0.08) as (bridge, fc, _region):  # later than the
        LockstepClock(bridge).sleep_s(0.002)  # loop waits
        assert bridge.lockstep_stats().steps == 4
        assert bridge.lockstep_stats().resends == 0  # waited out, not resent
        # The lock (Python) resends its packet every 5 ms; each step's went out once.
        stamps = [stamp for stamp, _ in fc.received]
        assert stamps[stamps.count(0.0) :] == pytest.approx([0.001, 0.002, 0.003])
        assert_a_silent_fc_is_asked_about(bridge, fc)
        bridge.close()


def test_a_reply_for_another_packet_stops_the_flight(tmp_path: Path) -> None:
    with compiled_bridge(tmp_path) as (bridge, fc, _region):
        fc.stamp_error_s = 1.0
        with pytest.raises(SitlError, match="out of step"):
            LockstepClock(bridge).sleep_s(0.01)
        bridge.close()


def test_a_closed_region_is_an_error_not_a_crash(tmp_path: Path) -> None:
    with compiled_bridge(tmp_path) as (bridge, _fc, _region):
        pass
    # The compiled loop holds the mapping's address: it must not step through it any more.
    with pytest.raises(SitlError, match="shared region is closed"):
        LockstepClock(bridge).sleep_s(0.01)
    bridge.close()


@pytest.mark.parametrize(
    ("version", "fc_polls", "loop_wakes", "fc_wakes"),
    [
        (3, True, False, False),  # both poll: no system call at all
        (3, False, True, False),  # the FC sleeps between packets: only it is woken
        (2, True, True, True),  # an older layout: every hand-over wakes, polling or not
    ],
)
def test_a_hand_over_wakes_only_a_side_that_sleeps(
    tmp_path: Path, version: int, fc_polls: bool, loop_wakes: bool, fc_wakes: bool
) -> None:
    # The loop polls up to 0.5 s, far longer than the stand-in FC takes to answer.
    with compiled_bridge(tmp_path, spin_s=0.5, version=version, poll=fc_polls) as (
        bridge,
        fc,
        _region,
    ):
        kernel = bridge._kernel
        assert kernel is not None
        before = bridge.lockstep_stats().steps, kernel.wakes, fc.wakes
        LockstepClock(bridge).sleep_s(0.05)
        steps = bridge.lockstep_stats().steps - before[0]
        assert steps == 50
        assert kernel.wakes - before[1] == (steps if loop_wakes else 0)
        assert fc.wakes - before[2] == (steps if fc_wakes else 0)
        bridge.close()
