"""Lockstep: the physics and a ``--lockstep`` SITL advance together, one step at a time.

A lockstep build (``bfsitl firmware build --lockstep``, :mod:`bfsitl.build.lockstep`) takes
its clock from the fdm packets: for each packet it runs its scheduler up to the packet's time
and sends exactly one servo packet back.  So nothing here waits on the wall clock: a step is

1. send the state at t_k, with the RC command in the same datagram (it takes effect with the
   sensors, at a defined FC time);
2. wait for the one reply, which names the packet it answers (MSP bytes the FC wrote during
   those passes are already readable);
3. integrate the physics over one step with that motor command.

The SITL is locked at boot: :meth:`LockstepBridge.lock` sends the first packet while the
process starts (``SitlProcess.on_spawn``), so the FC's first scheduler pass already runs on
the simulator's time and the whole run, boot included, repeats exactly.

Everything runs in the caller's thread: the mission loop, MSP telemetry and the physics take
turns, so a flight is a pure function of its inputs and seed.  The MSP client steps the
simulation while it waits for a reply (the FC only answers while its clock moves), and the
mission's clock steps while it waits (:mod:`bfsitl.sim.lockstep_io`).

``speed=None`` steps as fast as the machine allows (``--speed max``); a number paces the
steps to that multiple of real time (a wall-clock sleep that only changes how long it takes).
"""

from __future__ import annotations

import math
import select
import socket
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, TypeVar

from bfsitl.errors import PacketError, SitlError
from bfsitl.fc.rc_link import SAFE_COMMAND, RcCommand, RcFaultState
from bfsitl.link.shm_exchange import ShmExchange
from bfsitl.physics.frames import GeoPoint
from bfsitl.protocol.fdm_encoding import FdmEncoder
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, FirmwareProfile
from bfsitl.protocol.sitl_packets import RcPacket, ServoPacket
from bfsitl.sim import lockstep_stepper as outcome
from bfsitl.sim.bridge import (
    FDM_PORT,
    SITL_HOST,
    BridgeStats,
    Motors,
    SensorSource,
    bind_motor_port,
)
from bfsitl.sim.lockstep_stepper import KernelRun, KernelStepper
from bfsitl.sim.rc_frames import RcFrameClock

T = TypeVar("T")

#: Busy-poll the reply this long before sleeping in select(): a reply usually comes within
#: tens of microseconds, and waking a sleeping thread costs about as much again.  Only when
#: the run has cores to itself: two runs spinning on two cores steal each other's time slices
#: (measured: two scenario runs side by side took 2.4x as long as one after the other).
REPLY_SPIN_S = 0.0005
#: The SITL side's spin, set through its environment (sitl_lockstep.c).
SITL_SPIN_ENV = "BFSITL_LOCKSTEP_SPIN_US"
#: No reply this long (wall time) means the FC is gone or not a lockstep build.
REPLY_TIMEOUT_S = 2.0
#: Resend the same packet (the FC answers a repeat without applying it) this often first.
REPLY_RETRIES = 2
#: The lock packet is repeated this often while the SITL boots, until it answers.
LOCK_RESEND_S = 0.005
LOCK_TIMEOUT_S = 10.0
#: The compiled loop hands a step back to Python when its reply is this late (the Python
#: wait then asks whether the SITL still runs, and resends).
KERNEL_WAIT_S = 0.05
#: At most this many compiled steps per call: Ctrl-C is seen between two calls.
KERNEL_MAX_STEPS = 1000
#: After bytes are written to the FC's TCP ports, it services them after this many packets
#: (shared memory; over UDP after every one).  One reads a request as over UDP; the second
#: also reads what a connection made just before it brings (the first accepts it).
TCP_READ_REQUESTS = 2
#: A lockstep reply: the servo packet, then the timestamp of the fdm packet it answers.
REPLY_FORMAT = struct.Struct("<4fd")


def decode_reply(data: bytes) -> tuple[tuple[float, float, float, float], float]:
    """(motor_speed[4] as sent, timestamp answered); PacketError if ``data`` is not one."""
    if len(data) != REPLY_FORMAT.size:
        raise PacketError(f"a lockstep reply is {REPLY_FORMAT.size} bytes, got {len(data)}")
    *speeds, stamp = REPLY_FORMAT.unpack(data)
    return (speeds[0], speeds[1], speeds[2], speeds[3]), stamp


class _SocketFactory(Protocol):
    def socket(self, family: int, kind: int) -> socket.socket: ...


@dataclass(frozen=True, slots=True)
class LockstepStats:
    """Wall-clock cost of the steps so far (what ``benchmarks/lockstep.py`` reports)."""

    steps: int
    sim_time_s: float
    wall_time_s: float
    exchange_s: float  # sending the packet and waiting for the FC's reply
    physics_s: float  # integrating the physics
    resends: int


class LockstepBridge:
    """Steps a physics model against a lockstep SITL, in the caller's thread.

    It offers what a :class:`~bfsitl.sim.bridge.SitlBridge` offers a session (motors, stats,
    ``between_steps``), plus :meth:`step`, :meth:`run_for` and the RC command that rides in
    the packets: a frame at the RC link's rate (``rc_rate_hz``, :mod:`bfsitl.sim.rc_frames`;
    None puts one in every packet).

    >>> bridge = LockstepBridge(Simulator(), sitl.prepare_network())   # doctest: +SKIP
    >>> bridge.bind(); sitl.start(); bridge.start(); bridge.run_for(1.0)
    """

    def __init__(
        self,
        simulator: SensorSource,
        network: _SocketFactory,
        *,
        speed: float | None = None,
        step_s: float = 0.001,
        profile: FirmwareProfile = DEFAULT_PROFILE,
        on_step: Callable[[LockstepBridge], None] | None = None,
        alive: Callable[[], None] | None = None,
        wall_clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] = time.sleep,
        spin_s: float = REPLY_SPIN_S,
        exchange: ShmExchange | None = None,
        compiled_loop: bool = True,
        rc_rate_hz: float | None = None,
    ) -> None:
        if not 0.0001 <= step_s <= 0.01:
            raise ValueError(f"step_s {step_s} outside 0.1..10 ms")
        if speed is not None and not (math.isfinite(speed) and speed > 0):
            raise ValueError(f"speed {speed} must be a positive number or None (max)")
        self.simulator = simulator
        self.network = network
        self.speed = speed
        self.step_s = step_s
        self.on_step = on_step
        #: Busy-poll for a reply this long before sleeping (0 when runs share the cores).
        self.spin_s = spin_s
        #: Called when a reply is overdue; raises if the SITL has died (set by the session).
        self.alive = alive
        self._wall = wall_clock
        self._sleep = sleep
        #: The shared-memory exchange, once the FC has mapped it (None: UDP).
        self.exchange = exchange
        #: The requests of the packet in flight through it: the first and the last sent (a
        #: resend is a new request; the FC's answer to any of them will do).
        self._first_seq = self._seq = 0
        self._seq_stamp_s = math.nan
        self.encoder = FdmEncoder(profile, getattr(simulator, "home", GeoPoint(0.0, 0.0)))
        self.motors: Motors = (0.0, 0.0, 0.0, 0.0)
        self.rc_command: RcCommand = SAFE_COMMAND
        #: Which datagrams carry the RC trailer: the first at or after each of the link's
        #: frame times (``rc_rate_hz``), or every one (None).  Between frames 4.6.0 and
        #: master hold the last channels.
        self.rc_frames = RcFrameClock.at_rate(rc_rate_hz)
        #: Send the RC trailer only in the first datagram after ``rc_command`` is set (each
        #: set is one receiver frame) instead: a log's replay gives the firmware its frames
        #: at the real receiver's rate and times, which its feedforward and RC smoothing
        #: measure.
        self.rc_frames_on_set = False
        self._every_datagram = RcFrameClock()  # the loop's clock for a trailer decided here
        #: An injected RC fault (:class:`~bfsitl.fc.rc_link.RcFault`), on simulation time.
        self.rc_fault = RcFaultState()
        self.error: BaseException | None = None
        self._sock: socket.socket | None = None
        self._started = False
        self._locked = False
        self._rc_packed = b""
        self._rc_packed_for: RcCommand | None = None
        self._rc_checked: RcCommand | None = None
        self._rc_packed_at_s = math.nan
        self._steps = self._resends = 0
        self._exchange_s = self._physics_s = 0.0
        self._sim_start_s = 0.0
        self._wall_start_s = 0.0
        #: The compiled loop (bfsitl.kernel), made on first use when the exchange is shared
        #: memory (and ``compiled_loop``: False steps every step in Python, the reference the
        #: loop is tested against); None: every step in Python.  A stand-in simulator without
        #: a C structure (tests) is always stepped in Python.
        self._kernel: KernelStepper | None = None
        self._kernel_possible = compiled_loop and hasattr(simulator, "kernel_pointer")

    # -- what a session needs from any bridge ------------------------------------------------
    @property
    def profile(self) -> FirmwareProfile:
        return self.encoder.profile

    def set_profile(self, profile: FirmwareProfile) -> None:
        self.encoder = FdmEncoder(profile, self.encoder.home)

    def set_gps_lost(self, lost: bool) -> None:
        """Send the GPS loss sentinel from the next packet on (firmware that has one)."""
        self.encoder.gps_lost = lost

    @property
    def sim_time_s(self) -> float:
        return self.simulator.time_s

    @property
    def steps_taken(self) -> int:
        """Exchanges with the FC so far (each one a step of its clock)."""
        return self._steps

    def between_steps(self, action: Callable[[], T], timeout_s: float = 2.0) -> T:
        """Steps only happen when the caller asks: between two of them is always now."""
        return action()

    def stats(self) -> BridgeStats:
        wall_s = self._wall() - self._wall_start_s if self._started else 0.0
        return BridgeStats(
            self._steps,
            self._steps + self._resends,
            self._steps,
            0,
            0,
            self.simulator.time_s - self._sim_start_s,
            wall_s,
        )

    def lockstep_stats(self) -> LockstepStats:
        wall_s = self._wall() - self._wall_start_s if self._started else 0.0
        kernel = self._kernel
        exchange_s = self._exchange_s + (kernel.exchange_s if kernel is not None else 0.0)
        physics_s = self._physics_s + (kernel.physics_s if kernel is not None else 0.0)
        return LockstepStats(
            self._steps,
            self.simulator.time_s - self._sim_start_s,
            wall_s,
            exchange_s,
            physics_s,
            self._resends,
        )

    @property
    def compiled(self) -> bool:
        """Whether the steps run in the compiled loop (bfsitl.kernel) when they can."""
        return self._kernel is not None

    # -- sockets and lifecycle ---------------------------------------------------------------
    def bind(self) -> None:
        """Bind the motor port (before the SITL starts, like the real-time bridge)."""
        if self._sock is None:
            self._sock = bind_motor_port(self.network)

    def start(self) -> LockstepBridge:
        """Ready to step (nothing runs in the background)."""
        self.bind()
        if not self._started:
            self._started = True
            self._sim_start_s = self.simulator.time_s
            self._wall_start_s = self._wall()
        return self

    def lock(self) -> None:
        """Lock a SITL that is booting (call right after spawning it): send the packet of now
        until it answers, then take the physics step.  A restarted SITL is locked again."""
        self.start()
        assert self._sock is not None
        self._seq = 0  # a new process: nothing it answers belongs to the one before
        stamp_s = self.simulator.time_s
        datagram = self._datagram()
        deadline_s = self._wall() + LOCK_TIMEOUT_S
        while True:
            self._send(datagram, stamp_s)
            reply = self._wait_reply(stamp_s, LOCK_RESEND_S, spin=False)
            if reply is not None:
                break
            if self._wall() > deadline_s:
                raise SitlError(
                    f"the SITL did not answer its first fdm packet within {LOCK_TIMEOUT_S:.0f} "
                    f"s: is it a --lockstep build (`bfsitl firmware info`), in this network?"
                )
        self._locked = True
        self._advance(reply, self._wall())

    def stop(self) -> None:
        self._started = False

    def close(self) -> None:
        self.stop()
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def __enter__(self) -> LockstepBridge:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- stepping --------------------------------------------------------------------------
    def _datagram(self) -> bytes:
        now_s = self.simulator.time_s
        return self.encoder.pack(self.simulator.read_sensors(), now_s) + self._rc_bytes(now_s)

    def set_rc_command(self, command: RcCommand) -> None:
        """Send ``command`` from the next datagram on; a channel that is not a number raises
        here.  Its channels are worked out when it is packed (a step may set it more than
        once: the sticks, then the throttle; only the last is packed)."""
        command.check()
        self._rc_checked = command
        self.rc_command = command

    def _rc_bytes(self, now_s: float) -> bytes:
        """The RC trailer of the datagram stamped ``now_s``: a frame when one is due."""
        trailer = self._rc_trailer(now_s)
        if self.rc_frames_on_set and self.rc_fault.fault is None:
            # A resend of the datagram that carried the frame carries it again (the FC takes
            # a datagram once per time stamp, so the frame still counts once).
            return trailer if now_s == self._rc_packed_at_s else b""
        return trailer if trailer and self.rc_frames.due(now_s) else b""

    def _rc_trailer(self, now_s: float) -> bytes:
        """What a frame sent now would carry: the command's channels, or an injected fault's
        (none at all for silence)."""
        # The firmware ignores the RC packet's timestamp; the channels change at the control
        # rate, not every step, so their packing is kept.
        command = self.rc_command
        if self.rc_fault.fault is not None:
            channels = self.rc_fault.channels(now_s, command)
            self._rc_packed_for = None
            return b"" if channels is None else RcPacket(now_s, channels).pack()
        if command is not self._rc_packed_for:
            if command is self._rc_checked:
                channels = command.checked_channels_aetr()
            else:  # set directly, not through set_rc_command
                channels = command.channels_aetr()
            self._rc_packed = RcPacket(now_s, channels).pack()
            self._rc_packed_for = command
            self._rc_packed_at_s = now_s
        return self._rc_packed

    def step(self) -> None:
        """One exchange with the FC, then one physics step with its reply."""
        if not self._locked or self._sock is None:
            raise SitlError("the lockstep bridge has no SITL locked to it (lock() first)")
        kernel = self._kernel_stepper()
        if kernel is not None:
            self._kernel_steps(kernel, math.inf, 0.0, 1)
        else:
            self._python_step(self._wall())

    def wrote_to_fc(self) -> None:
        """Bytes were just written to one of the FC's TCP ports: through shared memory the FC
        reads them after the next packets (it does not look at every one)."""
        if self.exchange is not None:
            self.exchange.serve_tcp_next(TCP_READ_REQUESTS)

    def step_until_readable(self, fd: int, until_s: float) -> None:
        """Step at least once, and on while the time is below ``until_s`` and ``fd`` has
        nothing to read (an MSP reply the FC writes during its passes): what an MSP wait
        does, step by step in Python, or in one call of the compiled loop."""
        kernel = self._kernel_stepper() if fd >= 0 else None
        if kernel is None:
            self.step()
        else:
            self._kernel_steps(kernel, until_s, 0.0, KERNEL_MAX_STEPS, fd)

    def _python_step(self, began_s: float, *, sent: bool = False) -> None:
        """A step in Python; ``sent``: its datagram is out already (the compiled loop sent
        it and handed the wait over)."""
        stamp_s = self.simulator.time_s
        datagram = self._datagram()
        for attempt in range(REPLY_RETRIES + 1):
            if not (sent and attempt == 0):
                self._send(datagram, stamp_s)
            reply = self._wait_reply(stamp_s, REPLY_TIMEOUT_S / (REPLY_RETRIES + 1))
            if reply is not None:
                break
            self._resends += 1
        else:
            raise SitlError(
                f"the SITL did not answer an fdm packet within {REPLY_TIMEOUT_S:.0f} s (sim "
                f"time {self.simulator.time_s:.3f} s). A lockstep build answers every packet: "
                f"is it still running, and is it a --lockstep build (`bfsitl firmware info`)?"
            )
        self._advance(reply, began_s)

    def _advance(self, motors: Motors, began_s: float) -> None:
        self.motors = motors
        stepped_s = self._wall()
        self.simulator.step(self.motors, self.step_s)
        done_s = self._wall()
        self._exchange_s += stepped_s - began_s
        self._physics_s += done_s - stepped_s
        self._steps += 1
        if self.on_step is not None:
            self.on_step(self)
        if self.speed is not None:
            ahead_s = (self.simulator.time_s - self._sim_start_s) / self.speed - (
                done_s - self._wall_start_s
            )
            if ahead_s > 0.002:
                self._sleep(ahead_s)

    def run_for(self, seconds: float) -> None:
        """Step until ``seconds`` of simulation time have passed (at least one step if > 0)."""
        self.run_until(self.simulator.time_s + seconds)

    def run_until(self, time_s: float) -> None:
        # Half a step of slack: float sums of step_s must not add a step.
        while self.simulator.time_s + self.step_s / 2 < time_s:
            kernel = self._kernel_stepper()
            if kernel is not None:
                self._kernel_steps(kernel, time_s, self.step_s / 2, KERNEL_MAX_STEPS)
            else:
                self.step()

    # -- the compiled loop -----------------------------------------------------------------
    def _kernel_stepper(self) -> KernelStepper | None:
        """The compiled loop, when it may take the next steps: the simulator's C structure, the
        shared-memory exchange ready, a locked SITL, and nothing that needs Python at every
        step (a callback, a pace, an RC fault whose channels follow the clock)."""
        if (
            not self._kernel_possible
            or self.on_step is not None
            or self.speed is not None
            or self.rc_fault.fault is not None
            or not self._locked
            or self._sock is None
        ):
            return None
        kernel = self._kernel
        if kernel is not None and kernel.exchange.closed:
            return None  # its region is unmapped: Python's path reports what is wrong
        if kernel is None:
            exchange = self.exchange
            if exchange is None or exchange.closed or not exchange.ready:
                return None
            kernel = self._kernel = KernelStepper(
                self.simulator.kernel_pointer,  # type: ignore[attr-defined]
                exchange,
                step_s=self.step_s,
                wait_s=KERNEL_WAIT_S,
            )
        return kernel

    def _kernel_steps(
        self,
        kernel: KernelStepper,
        until_s: float,
        slack_s: float,
        max_steps: int,
        watch_fd: int = -1,
    ) -> None:
        frames = self.rc_frames
        if self.rc_frames_on_set:
            rc = self._rc_bytes(self.simulator.time_s)
            if rc:
                max_steps = 1  # the frame rides in one datagram; the steps after it carry none
            frames = self._every_datagram
        else:
            rc = self._rc_trailer(self.simulator.time_s)  # the loop picks the datagrams
        run: KernelRun = kernel.run(
            self.encoder,
            rc,
            until_s=until_s,
            slack_s=slack_s,
            max_steps=max_steps,
            spin_s=self.spin_s,
            frames=frames,
            watch_fd=watch_fd,
        )
        self._steps += run.steps
        status = run.status
        if status == outcome.BAD_MOTORS:
            self._advance(run.motors, run.began_s)  # the simulator names the bad command
            return
        if run.steps:
            self.motors = run.motors
        if status == outcome.DONE:
            return
        if status == outcome.PENDING:
            # Late: the Python wait takes over that request (asking whether the SITL still
            # runs, resending), as if it had sent it.
            self._seq = self._first_seq = run.seq
            self._seq_stamp_s = run.stamp_s
            self._python_step(run.began_s, sent=True)
        elif status == outcome.OUT_OF_STEP:
            raise SitlError(
                f"the FC answered fdm time {run.answered_s} for {run.stamp_s} "
                f"through shared memory: its exchange is out of step"
            )
        else:
            self._python_step(self._wall())  # it names the reading, or steps in Python

    def _send(self, datagram: bytes, stamp_s: float) -> None:
        exchange = self.exchange
        if exchange is not None and exchange.closed:
            raise SitlError(
                "the lockstep exchange's shared region is closed: the session "
                "that made it has ended"
            )
        if exchange is not None and exchange.ready:
            seq = exchange.send(datagram)
            if not self._seq or stamp_s != self._seq_stamp_s:
                self._first_seq, self._seq_stamp_s = seq, stamp_s
            self._seq = seq
            return
        self._seq = 0
        assert self._sock is not None
        try:
            self._sock.sendto(datagram, (SITL_HOST, FDM_PORT))
        except (BlockingIOError, ConnectionRefusedError):
            pass  # no one on 9003 yet (or any more): the reply wait notices

    def _receive(self, stamp_s: float) -> Motors | None:
        """The reply to the packet stamped ``stamp_s`` if it has come; others are dropped."""
        assert self._sock is not None
        while True:
            try:
                data = self._sock.recv(64)
            except (BlockingIOError, InterruptedError):
                return None
            except ConnectionRefusedError:
                continue  # ICMP from an earlier send to a closed 9003
            try:
                speeds, answered_s = decode_reply(data)
            except PacketError:
                continue  # a stock servo packet, 9001's raw packet or garbage: not ours
            if answered_s != stamp_s:
                continue  # the answer to a resent packet, or to one before a restart
            return ServoPacket.in_betaflight_order(
                speeds, self.encoder.profile.motor_slot_of_betaflight_motor
            )

    def _wait_reply(self, stamp_s: float, timeout_s: float, *, spin: bool = True) -> Motors | None:
        if self._seq:
            return self._wait_shared_reply(stamp_s, timeout_s, spin=spin)
        assert self._sock is not None
        start_s = self._wall()
        spin_until_s = start_s + (self.spin_s if spin else 0.0)
        while True:
            reply = self._receive(stamp_s)
            if reply is not None:
                return reply
            now_s = self._wall()
            if now_s < spin_until_s:
                continue
            remaining_s = start_s + timeout_s - now_s
            if remaining_s <= 0:
                return None
            if (
                not select.select([self._sock], [], [], min(remaining_s, 0.05))[0]
                and self.alive is not None
            ):
                self.alive()  # a SITL that ended (a reboot, a crash) says so now

    def _wait_shared_reply(self, stamp_s: float, timeout_s: float, *, spin: bool) -> Motors | None:
        """The reply through shared memory: the same bytes as the UDP reply."""
        exchange = self.exchange
        assert exchange is not None
        wall = self._wall
        start_s = wall()
        spin_until_s = start_s + (self.spin_s if spin else 0.0)
        first, last = self._first_seq, self._seq

        def spinning() -> bool:
            return wall() < spin_until_s

        while True:
            remaining_s = start_s + timeout_s - wall()
            if remaining_s <= 0:
                return None
            data = exchange.wait_reply(first, last, min(remaining_s, 0.05), spinning)
            if data is not None:
                speeds, answered_s = decode_reply(data)
                if answered_s != stamp_s:
                    raise SitlError(
                        f"the FC answered fdm time {answered_s} for {stamp_s} "
                        f"through shared memory: its exchange is out of step"
                    )
                return ServoPacket.in_betaflight_order(
                    speeds, self.encoder.profile.motor_slot_of_betaflight_motor
                )
            if self.alive is not None:
                self.alive()  # a SITL that ended (a reboot, a crash) says so now
