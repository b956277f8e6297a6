"""The physics bridge: exchanges fdm and servo packets with the SITL, paced in wall time.

Per step k (``docs/lockstep.md``, "paced lockstep"):

1. apply any servo packet that arrived late (a newer command than the one held);
2. send the fdm packet for the state at t_k, timestamped by :mod:`bfsitl.sim.clock_lock`;
3. wait for the SITL's servo reply until the wall time of step k+1; without one, hold the last
   command (never zero it: a zeroed motor drops the craft) and count a miss;
4. integrate the physics over one step with that command, then sleep until step k+1.

The wall schedule is absolute (``t0 + k·step/speed``), so simulated time advances at exactly
``speed`` × wall time; with the rate-frozen timestamps the firmware clock runs at the same
rate, and firmware time / sim time stays 1.00.  If the bridge falls behind (a slow step, a GC
pause) it catches up without pausing the schedule: a burst only means some steps reuse a
command, while re-anchoring the schedule would let the firmware clock run ahead.

The motor port (UDP 9002) is bound before the SITL starts, without SO_REUSEADDR, so a second
simulator fails loudly instead of silently sharing the port, and the packet the SITL sends while
it boots is not lost.  The SITL ends on every reboot; :meth:`SitlBridge.pause` and
:meth:`SitlBridge.resume` bracket a restart (resume primes the new process's clock again).
"""

from __future__ import annotations

import errno
import queue
import select
import socket
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal, Protocol, TypeVar

from bfsitl.errors import PacketError, PortInUseError, SitlError
from bfsitl.physics.frames import GeoPoint
from bfsitl.physics.sensors import SensorReading
from bfsitl.protocol.fdm_encoding import FdmEncoder
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE, FirmwareProfile
from bfsitl.protocol.sitl_packets import ServoPacket
from bfsitl.sim.clock_lock import PRIMER_PACKETS, PRIMER_SPACING_S, FrozenRateStamps
from bfsitl.sitl.ports import SIM_UDP_PORTS, find_port_holders
from bfsitl.sitl.process import SitlProcess
from bfsitl.sitl.timer_slack import set_timer_slack

SITL_HOST = "127.0.0.1"
FDM_PORT = 9003
SERVO_PORT = 9002
DEFAULT_STEP_S = 0.001
#: A lockstep build answers with the servo packet and the fdm timestamp (sim/lockstep.py).
LOCKSTEP_REPLY_SIZE = 24

Motors = tuple[float, float, float, float]
T = TypeVar("T")
TimestampMode = Literal["frozen", "sim"]


class SensorSource(Protocol):
    """What the bridge needs from a physics model (:class:`bfsitl.sim.Simulator`)."""

    @property
    def time_s(self) -> float: ...

    def step(self, motors: Motors, dt_s: float) -> None: ...

    def read_sensors(self) -> SensorReading: ...


class _SocketFactory(Protocol):
    def socket(self, family: int, kind: int) -> socket.socket: ...


@dataclass(frozen=True, slots=True)
class BridgeStats:
    """Counters since the bridge started (or of a window: see :meth:`minus`)."""

    steps: int
    fdm_sent: int
    replies: int  # servo packets that arrived before the next step was due
    late_replies: int  # servo packets that arrived after; applied at the next step
    misses: int  # steps that reused the previous command
    sim_time_s: float
    wall_time_s: float
    skipped: int = 0  # steps integrated without an exchange, to catch up after a delay

    @property
    def answered_ratio(self) -> float:
        """Share of fdm packets the SITL answered (in time or late)."""
        return (self.replies + self.late_replies) / self.fdm_sent if self.fdm_sent else 0.0

    @property
    def speed(self) -> float:
        """Simulated time per wall time."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else 0.0

    def minus(self, earlier: BridgeStats) -> BridgeStats:
        return BridgeStats(
            self.steps - earlier.steps,
            self.fdm_sent - earlier.fdm_sent,
            self.replies - earlier.replies,
            self.late_replies - earlier.late_replies,
            self.misses - earlier.misses,
            self.sim_time_s - earlier.sim_time_s,
            self.wall_time_s - earlier.wall_time_s,
            self.skipped - earlier.skipped,
        )


def bind_motor_port(network: _SocketFactory) -> socket.socket:
    """UDP 9002 bound (non-blocking) in ``network``, or a PortInUseError naming who has it."""
    sock = network.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind((SITL_HOST, SERVO_PORT))
    except OSError as exc:
        sock.close()
        if exc.errno == errno.EADDRINUSE:
            netns_pid = getattr(network, "netns_pid", None)
            holders = find_port_holders((), SIM_UDP_PORTS[:1], netns_pid=netns_pid)
            who = "; ".join(h.describe() for h in holders) or "another process"
            raise PortInUseError(
                f"UDP {SERVO_PORT} (motor packets from the SITL) is taken: {who}. Stop "
                f"the other simulator, or run isolated (--start uses its own namespace)."
            ) from exc
        raise SitlError(f"cannot bind UDP {SERVO_PORT}: {exc}") from exc
    sock.setblocking(False)
    return sock


class SitlBridge:
    """Runs a physics model against a SITL, on a thread of its own.

    >>> bridge = SitlBridge(Simulator(), sitl.prepare_network())   # doctest: +SKIP
    >>> bridge.bind(); sitl.start(); bridge.start()
    """

    def __init__(
        self,
        simulator: SensorSource,
        network: _SocketFactory,
        *,
        speed: float = 1.0,
        step_s: float = DEFAULT_STEP_S,
        timestamps: TimestampMode = "frozen",
        profile: FirmwareProfile = DEFAULT_PROFILE,
        on_step: Callable[[SitlBridge], None] | None = None,
    ) -> None:
        if not 0.0001 <= step_s <= 0.01:
            raise ValueError(f"step_s {step_s} outside 0.1..10 ms")
        self.simulator = simulator
        self.network = network
        self.speed = speed
        self.step_s = step_s
        self.timestamps = timestamps
        self._use_profile(profile, getattr(simulator, "home", GeoPoint(0.0, 0.0)))
        self.on_step = on_step
        #: The command applied to the physics, Betaflight motor order M1..M4.
        self.motors: Motors = (0.0, 0.0, 0.0, 0.0)
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._running = threading.Event()  # cleared while paused
        self._paused_ack = threading.Event()
        self._needs_prime = True
        self._needs_calibration = False
        self._rate_correction = 1.0
        self._stamps = FrozenRateStamps(speed)
        self._steps = self._fdm_sent = self._replies = self._late = self._misses = 0
        self._skipped = 0
        self._sim_start_s = 0.0
        self._wall_start_s = 0.0
        self._wall_paused_s = 0.0
        self.error: BaseException | None = None
        self._actions: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()

    @property
    def profile(self) -> FirmwareProfile:
        return self.encoder.profile

    def set_profile(self, profile: FirmwareProfile) -> None:
        """Speak another firmware generation's conventions (before :meth:`start`: the
        profile is known once the FC has said who it is, after the motor port is bound)."""
        if self._thread is not None:
            raise SitlError("the firmware profile must be set before the bridge starts")
        self._use_profile(profile, self.encoder.home)

    def set_gps_lost(self, lost: bool) -> None:
        """Send the GPS loss sentinel from the next packet on (firmware that has one)."""
        self.encoder.gps_lost = lost

    def _use_profile(self, profile: FirmwareProfile, home: GeoPoint) -> None:
        self.encoder = FdmEncoder(profile, home)
        self._motor_slots = profile.motor_slot_of_betaflight_motor

    # -- sockets ---------------------------------------------------------------------------
    def bind(self) -> None:
        """Bind the motor port; call before the SITL starts so its boot packet is caught."""
        if self._sock is None:
            self._sock = bind_motor_port(self.network)

    def close(self) -> None:
        self.stop()
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    # -- lifecycle -------------------------------------------------------------------------
    def start(self) -> SitlBridge:
        """Start stepping (the SITL must be up); returns at once, the work is on a thread."""
        self.bind()
        if self._thread is not None:
            raise SitlError("bridge already started")
        self._running.set()
        self._thread = threading.Thread(target=self._run, name="bfsitl-bridge", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._running.set()  # wake a paused loop so it can see the stop
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def pause(self, timeout_s: float = 2.0) -> None:
        """Stop sending (before the SITL restarts); returns once the loop is idle."""
        self._paused_ack.clear()
        self._running.clear()
        if self._thread is not None and self._thread.is_alive():
            self._paused_ack.wait(timeout_s)

    def recalibrate(self, rate_correction: float = 1.0) -> None:
        """Send a new calibration pair at the next step (speed != 1 only).

        ``rate_correction`` scales the rate asked of the SITL: pass the measured firmware
        time / sim time to aim the next pair at the same share below (a pair's error is
        mostly random arrival jitter, so :func:`bfsitl.sim.health.lock_clock` repeats this
        until the measured ratio is within tolerance).
        """
        self._rate_correction = rate_correction
        self._needs_calibration = True

    def resume(self) -> None:
        """Carry on after a restart: primes the new SITL's clock, then steps again."""
        self._needs_prime = True
        self._running.set()

    def between_steps(self, action: Callable[[], T], timeout_s: float = 2.0) -> T:
        """Run ``action`` on the bridge thread between two steps and return its result.

        The simulator is not thread-safe: moving the vehicle (``reset``, ``hold``) from
        another thread while a step runs could mix two states in one fdm packet.
        """
        if (
            self._thread is None
            or not self._thread.is_alive()
            or threading.current_thread() is self._thread
        ):
            return action()
        done = threading.Event()
        outcome: list[object] = []

        def run() -> None:
            try:
                outcome.append(action())
            except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
                outcome.append(exc)
            done.set()

        self._actions.put(run)
        if not done.wait(timeout_s):
            raise SitlError(f"the bridge did not run the action within {timeout_s} s")
        if isinstance(outcome[0], BaseException):
            raise outcome[0]
        return outcome[0]  # type: ignore[return-value]

    @property
    def sim_time_s(self) -> float:
        return self.simulator.time_s

    def stats(self) -> BridgeStats:
        now_s = time.perf_counter()
        wall_s = (now_s - self._wall_start_s - self._wall_paused_s) if self._wall_start_s else 0.0
        return BridgeStats(
            self._steps,
            self._fdm_sent,
            self._replies,
            self._late,
            self._misses,
            self.simulator.time_s - self._sim_start_s,
            wall_s,
            self._skipped,
        )

    def __enter__(self) -> SitlBridge:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    # -- the loop --------------------------------------------------------------------------
    def _send(self, timestamp_s: float) -> None:
        assert self._sock is not None
        packet = self.encoder.encode(self.simulator.read_sensors(), timestamp_s)
        try:
            self._sock.sendto(packet.pack(), (SITL_HOST, FDM_PORT))
        except (BlockingIOError, ConnectionRefusedError):
            # Nothing bound on 9003 (SITL restarting) reports back as ECONNREFUSED on the
            # next send; the step simply goes unanswered.
            pass
        self._fdm_sent += 1

    def _receive_all(self) -> int:
        """Read every queued servo packet; the newest becomes the command.  Returns count."""
        assert self._sock is not None
        count = 0
        while True:
            try:
                data = self._sock.recv(64)
            except (BlockingIOError, InterruptedError):
                return count
            except ConnectionRefusedError:
                continue  # ICMP from an earlier send to a closed 9003
            if len(data) == LOCKSTEP_REPLY_SIZE:
                # A lockstep build's reply: the servo packet, then the stamp it answers. Paced
                # by this bridge, such a build simply follows the packets' time.
                data = data[: ServoPacket.SIZE]
            try:
                self.motors = ServoPacket.unpack(data).betaflight_motors(self._motor_slots)
            except PacketError:
                continue  # not ours (9001's raw packet has another size): ignore
            count += 1

    def _timestamp(self) -> float:
        if self.timestamps == "sim":
            return self.simulator.time_s
        return self._stamps.next()

    def _prime(self) -> None:
        """Primers and, at speed != 1, the calibration pair (see clock_lock)."""
        self._stamps = FrozenRateStamps(self.speed, self._stamps.timestamp_s)
        for _ in range(PRIMER_PACKETS):
            stamp = self._stamps.primer() if self.timestamps == "frozen" else self._timestamp()
            self._send(stamp)
            time.sleep(PRIMER_SPACING_S)
            self._receive_all()
        if self.timestamps == "frozen" and self._stamps.needs_calibration:
            self._calibration_pair()
        self._needs_prime = False

    def _calibration_pair(self) -> None:
        """Two packets whose Δtimestamp / Δwall is the speed: the SITL adopts it as simRate."""
        first = self._stamps.primer()
        self._send(first)
        sent_s = time.perf_counter()
        wait_s = self._stamps.calibration_wall_s()
        while time.perf_counter() - sent_s < wait_s:
            pass  # busy-wait: sleep granularity would be a large share of the window
        elapsed_s = (time.perf_counter() - sent_s) / self._rate_correction
        self._send(self._stamps.calibration_second(first, elapsed_s))
        self._needs_calibration = False

    def _run(self) -> None:
        set_timer_slack(1)  # this thread's sleeps should be as exact as the SITL's
        try:
            self._loop()
        except BaseException as exc:  # noqa: BLE001 - surfaced through .error
            self.error = exc

    def _loop(self) -> None:
        assert self._sock is not None
        step_wall_s = self.step_s / self.speed
        self._sim_start_s = self.simulator.time_s
        self._wall_start_s = time.perf_counter()
        t0 = k = None
        while not self._stop.is_set():
            if not self._running.is_set():
                paused_at = time.perf_counter()
                self._paused_ack.set()
                self._running.wait()
                self._wall_paused_s += time.perf_counter() - paused_at
                t0 = None
                continue
            if self._needs_prime:
                # Priming is set-up, not simulation: its wall time counts like a pause.
                priming_from_s = time.perf_counter()
                self._prime()
                self._wall_paused_s += time.perf_counter() - priming_from_s
                t0 = None
            elif self._needs_calibration and self.timestamps == "frozen":
                self._calibration_pair()  # the schedule catches up afterwards
            if t0 is None:
                t0, k = time.perf_counter(), 0
            assert k is not None
            while not self._actions.empty():
                self._actions.get_nowait()()
            # Behind schedule (this thread was descheduled): integrate the missed steps with
            # the held command instead of sending a burst of fdm packets, which the SITL
            # would answer once (one reply per PID run) while its clock saw nothing new.
            while time.perf_counter() > t0 + (k + 1) * step_wall_s:
                self.simulator.step(self.motors, self.step_s)
                self._steps += 1
                self._skipped += 1
                k += 1
            # 1. late packets: a newer command than the one held
            self._late += self._receive_all()
            # 2. the state at t_k
            self._send(self._timestamp())
            # 3. wait for the reply until step k+1 is due
            deadline_s = t0 + (k + 1) * step_wall_s
            if self._wait_reply(deadline_s):
                self._replies += 1
            else:
                self._misses += 1
            # 4. physics over one step with the command, then wait for the schedule
            self.simulator.step(self.motors, self.step_s)
            self._steps += 1
            k += 1
            if self.on_step is not None:
                self.on_step(self)
            remaining_s = t0 + k * step_wall_s - time.perf_counter()
            if remaining_s > 0:
                time.sleep(remaining_s)

    def _wait_reply(self, deadline_s: float) -> bool:
        assert self._sock is not None
        while True:
            remaining_s = deadline_s - time.perf_counter()
            if remaining_s <= 0:
                return self._receive_all() > 0
            readable, _, _ = select.select([self._sock], [], [], remaining_s)
            if readable and self._receive_all():
                return True


def wait_for_replies(bridge: SitlBridge, count: int = 50, timeout_s: float = 5.0) -> BridgeStats:
    """Block until the SITL has answered ``count`` fdm packets (or raise); for start-up."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if bridge.error is not None:
            raise SitlError(f"physics bridge failed: {bridge.error!r}") from bridge.error
        stats = bridge.stats()
        if stats.replies + stats.late_replies >= count:
            return stats
        time.sleep(0.01)
    stats = bridge.stats()
    raise SitlError(
        f"the SITL answered {stats.replies + stats.late_replies} of {stats.fdm_sent} fdm "
        f"packets in {timeout_s:.0f} s. Either it runs in another network than the bridge, or "
        f"its gyro/PID loop is not running (`bfsitl cli tasks` shows GYRO/PID at 0 Hz; 4.6.0's "
        f"scheduler can lock them out for good at boot, which starting the SITL checks for): "
        f"start it again."
    )


@contextmanager
def bridged_sitl(
    sitl: SitlProcess, simulator: SensorSource, **bridge_options: Any
) -> Iterator[SitlBridge]:
    """A SITL with the physics bridge running and answering; everything stopped on exit.

    The order matters: the motor port is bound before the SITL boots (its boot-time packet is
    caught, a second simulator fails loudly), the bridge starts only once the FC answers MSP,
    and on the way out the bridge stops before the SITL does.
    """
    bridge = SitlBridge(simulator, sitl.prepare_network(), **bridge_options)
    if sitl.firmware.lockstep:
        # A lockstep build's clock *is* the timestamps: the rate-frozen ones, made to steer a
        # stock SITL's rate estimate, would run it 60x fast. Paced here, it follows sim time.
        bridge.timestamps = "sim"
    bridge.bind()
    try:
        with sitl:
            if "profile" not in bridge_options:
                bridge.set_profile(sitl.profile)
            bridge.start()
            wait_for_replies(bridge)
            yield bridge
    finally:
        bridge.close()
