"""The relay between the plugin and the SITL, on real loopback sockets of this host.

A "plugin" and a "SITL" socket stand at the relay's ends: every packet must come out at the
other end, byte for byte but for the fdm timestamp the relay restamps (unless told not to),
and the relay must read Gazebo's state and the motors (in Betaflight's order) from them, count
them, record them as Gazebo sent them, and forward what it cannot read without reading it.
"""

from __future__ import annotations

import functools
import math
import socket
import time
from collections.abc import Iterator

import pytest

from bfsitl.backend.gazebo import HOME
from bfsitl.errors import GazeboError
from bfsitl.gazebo.packet_tap import PluginTap, TapPorts
from bfsitl.gazebo.plugin_frame import PluginFrame, gps_fields
from bfsitl.protocol.sitl_packets import FdmPacket, ServoPacket
from bfsitl.sim.clock_lock import FROZEN_STEP_S, FrozenRateStamps
from bfsitl.sitl.network import HostNetwork

LOOPBACK = "127.0.0.1"


def _free_ports(count: int) -> list[int]:
    holders = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(count)]
    for sock in holders:
        sock.bind((LOOPBACK, 0))
    ports = [sock.getsockname()[1] for sock in holders]
    for sock in holders:
        sock.close()
    return ports


def _udp(port: int) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind((LOOPBACK, port))
    sock.settimeout(2.0)
    return sock


class Ends:
    def __init__(self, *, frozen_rate: bool = True, gps: bool = False) -> None:
        sitl_servo, sitl_fdm, plugin_servo, tap_fdm = _free_ports(4)
        self.ports = TapPorts(sitl_servo, sitl_fdm, plugin_servo, tap_fdm)
        self.plugin = _udp(plugin_servo)  # the plugin's fdm_port_in
        self.sitl = _udp(sitl_fdm)  # the SITL's state port
        self.recorded: list[tuple[str, float, bytes]] = []
        self.now_s = 100.0
        self.tap = PluginTap(
            HostNetwork(),
            PluginFrame(gazebo_to_ned_rpy=(math.pi, 0.0, math.pi / 2)),
            (3, 0, 1, 2),
            ports=self.ports,
            recorder=lambda kind, t, data: self.recorded.append((kind, t, data)),
            clock=lambda: self.now_s,
            next_timestamp=FrozenRateStamps().next if frozen_rate else None,
            gps_fields=functools.partial(gps_fields, home=HOME) if gps else None,
        ).start()

    def close(self) -> None:
        self.tap.stop()
        self.plugin.close()
        self.sitl.close()


@pytest.fixture
def ends() -> Iterator[Ends]:
    ends = Ends()
    yield ends
    ends.close()


def _fdm(sim_time_s: float, up_m: float) -> bytes:
    # 4.6.0's world: the packet is NED already.
    return FdmPacket(sim_time_s, position=(1.0, 2.0, -up_m), velocity_m_s=(0.0, 0.0, -0.5)).pack()


def _wait_for(condition: object, timeout_s: float = 2.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():  # type: ignore[operator]
        assert time.monotonic() < deadline, "the relay did not get there in time"
        time.sleep(0.005)


def test_both_directions_are_forwarded_unchanged_and_read(ends: Ends) -> None:
    assert ends.tap.reading() is None
    state = _fdm(3.0, 2.5)
    ends.plugin.sendto(state, (LOOPBACK, ends.ports.tap_fdm))
    forwarded = ends.sitl.recv(2048)
    assert forwarded[8:] == state[8:]
    first_stamp = FdmPacket.unpack(forwarded).timestamp_s
    servo = ServoPacket((0.2, 0.3, 0.4, 0.1)).pack()
    ends.sitl.sendto(servo, (LOOPBACK, ends.ports.sitl_servo))
    assert ends.plugin.recv(2048) == servo
    ends.now_s = 101.0
    ends.plugin.sendto(_fdm(3.001, 3.0), (LOOPBACK, ends.ports.tap_fdm))
    # Gazebo's 1 ms becomes a step the SITL's rate estimator ignores (above its 20 ms).
    assert FdmPacket.unpack(ends.sitl.recv(2048)).timestamp_s - first_stamp == FROZEN_STEP_S
    _wait_for(lambda: ends.tap.counts().fdm == 2)
    reading = ends.tap.reading()
    assert reading is not None
    assert reading.state.position_ned_m == pytest.approx((1.0, 2.0, -3.0))
    assert reading.state.altitude_m == pytest.approx(3.0)
    assert reading.state_at_s == 101.0
    # 4.6.0's slots: motor 1 rides in slot 3, motors 2-4 in slots 0-2.
    assert reading.motors == pytest.approx((0.1, 0.2, 0.3, 0.4))
    counts = ends.tap.counts()
    assert (counts.fdm, counts.servo, counts.unreadable) == (2, 1, 0)
    assert counts.sim_time_s == pytest.approx(0.001)
    assert counts.wall_time_s == pytest.approx(1.0)
    assert counts.real_time_factor == pytest.approx(0.001)
    assert [(kind, t) for kind, t, _ in ends.recorded] == [
        ("fdm", 100.0),
        ("servo", 100.0),
        ("fdm", 101.0),
    ]
    assert ends.recorded[0][2] == state


def test_gazebos_timestamps_can_be_kept() -> None:
    ends = Ends(frozen_rate=False)
    try:
        state = _fdm(3.0, 2.5)
        ends.plugin.sendto(state, (LOOPBACK, ends.ports.tap_fdm))
        assert ends.sitl.recv(2048) == state
    finally:
        ends.close()


def test_a_gps_build_gets_longitude_latitude_altitude_and_enu_velocity() -> None:
    ends = Ends(gps=True)
    try:
        # 4.6.0's world: NED metres; 1000 m north, 2000 m east, 30 m up, moving north-east.
        packet = FdmPacket(5.0, position=(1000.0, 2000.0, -30.0), velocity_m_s=(3.0, 4.0, -1.0))
        ends.plugin.sendto(packet.pack(), (LOOPBACK, ends.ports.tap_fdm))
        forwarded = FdmPacket.unpack(ends.sitl.recv(2048))
        lon, lat, alt = forwarded.position
        # Flat earth at 0 N 0 E: a degree of latitude or longitude is R_E * pi / 180 there.
        metres_per_degree = 6378137.0 * math.pi / 180.0
        assert lat * metres_per_degree == pytest.approx(1000.0, rel=1e-3)
        assert lon * metres_per_degree == pytest.approx(2000.0, rel=1e-3)
        assert alt == pytest.approx(30.0)
        assert forwarded.velocity_m_s == pytest.approx((4.0, 3.0, 1.0))  # east, north, up
        assert forwarded.quaternion_wxyz == packet.quaternion_wxyz
        assert forwarded.pressure_pa == packet.pressure_pa
        # The truth stays NED metres.
        reading = ends.tap.reading()
        assert reading is not None
        assert reading.state.position_ned_m == pytest.approx((1000.0, 2000.0, -30.0))
    finally:
        ends.close()


def test_what_cannot_be_read_is_forwarded_and_counted(ends: Ends) -> None:
    ends.plugin.sendto(b"garbage", (LOOPBACK, ends.ports.tap_fdm))
    assert ends.sitl.recv(2048) == b"garbage"
    nan_servo = ServoPacket.FORMAT.pack(float("nan"), 0.0, 0.0, 0.0)
    ends.sitl.sendto(nan_servo, (LOOPBACK, ends.ports.sitl_servo))
    assert ends.plugin.recv(2048) == nan_servo
    _wait_for(lambda: ends.tap.counts().unreadable == 2)
    assert ends.tap.reading() is None
    assert ends.tap.error is None
    # A readable packet after them is read as usual.
    ends.plugin.sendto(_fdm(1.0, 0.2), (LOOPBACK, ends.ports.tap_fdm))
    ends.sitl.recv(2048)
    _wait_for(lambda: ends.tap.reading() is not None)
    reading = ends.tap.reading()
    assert reading is not None and all(math.isnan(m) for m in reading.motors)


def test_nobody_at_the_far_end_is_no_error(ends: Ends) -> None:
    ends.sitl.close()  # the SITL has not started yet
    ends.plugin.sendto(_fdm(1.0, 0.2), (LOOPBACK, ends.ports.tap_fdm))
    ends.plugin.sendto(_fdm(1.001, 0.2), (LOOPBACK, ends.ports.tap_fdm))
    _wait_for(lambda: ends.tap.counts().fdm == 2)
    assert ends.tap.error is None


def test_a_taken_port_is_refused_with_the_ports_named() -> None:
    ports = _free_ports(4)
    holder = _udp(ports[0])
    try:
        with pytest.raises(GazeboError, match=f"UDP ports {ports[0]} and {ports[3]}"):
            PluginTap(HostNetwork(), PluginFrame(), (0, 1, 2, 3), ports=TapPorts(*ports))
    finally:
        holder.close()
