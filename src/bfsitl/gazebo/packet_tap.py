"""A relay between the BetaflightPlugin and the SITL that reads Gazebo's truth on the way.

The plugin and the SITL talk over fixed loopback ports: state to the SITL's UDP 9003, motors
to UDP 9002.  bfsitl moves the plugin's two ports in the world it writes (``fcu_port_out``,
``fdm_port_in``) and sits in between, in the same network namespace::

    plugin --fdm--> TAP_FDM_PORT  [tap]  --fdm-->   9003 SITL
    plugin <-servo- PLUGIN_SERVO_PORT [tap] <-servo- 9002 SITL

Every packet is forwarded as soon as it arrives; the tap keeps the latest of each (Gazebo's
pose, velocity and rates from the fdm packet; the motors from the servo packet), counts them,
and hands each, as Gazebo sent it, to an optional recorder.  That makes Gazebo's state the
flight's simulated truth, the way the embedded physics' state is.

One field is changed on the way, unless asked not to: the fdm timestamp.  The plugin stamps
each packet with Gazebo's sim time, 1 ms apart, and stock 4.6.0 re-estimates its clock rate
from every such pair against their arrival times; arrival jitter then runs the FC's clock
fast (1.74x real time measured in a Gazebo flight here, docs/firmware-facts.md#sim-clock).
Given ``next_timestamp``, the tap stamps them the way bfsitl's own bridge does (the Gazebo
backend gives it :mod:`bfsitl.sim.clock_lock`'s at speed 1), so the FC's clock keeps to the
wall clock, which Gazebo follows at its real-time factor.  Given ``gps_fields``, it also
rewrites the position and velocity for a GPS build (:func:`~bfsitl.gazebo.plugin_frame.gps_fields`).
"""

from __future__ import annotations

import contextlib
import select
import socket
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from bfsitl.errors import GazeboError, PacketError
from bfsitl.gazebo.plugin_frame import GazeboState, PluginFrame
from bfsitl.protocol.sitl_packets import FdmPacket, ServoPacket
from bfsitl.sitl.network import Network

_TIMESTAMP = struct.Struct("<d")
#: velocity_xyz then position_xyz, and where they sit in the 144 bytes (FdmPacket.FORMAT).
_VECTORS = struct.Struct("<3d3d")
_VELOCITY_AT = 88
_PRESSURE_AT = _VELOCITY_AT + _VECTORS.size

#: What a GPS build reads from Gazebo's state: (position_xyz, velocity_xyz) as it wants them.
GpsFields = Callable[[GazeboState], tuple[tuple[float, float, float], tuple[float, float, float]]]

LOOPBACK = "127.0.0.1"


@dataclass(frozen=True, slots=True)
class TapPorts:
    """The four UDP ports of the relay (all on loopback in the SITL's namespace)."""

    #: Where the SITL sends motors (fixed in the firmware): the tap binds it.
    sitl_servo: int = 9002
    #: Where the SITL reads state (fixed in the firmware).
    sitl_fdm: int = 9003
    #: The plugin's ``fdm_port_in``: where the tap forwards motors.
    plugin_servo: int = 9102
    #: The plugin's ``fcu_port_out``: where the tap reads state.
    tap_fdm: int = 9103


#: A recorder: ``("fdm" | "servo", wall seconds on the tap's clock, the packet's bytes)``.
PacketRecorder = Callable[[str, float, bytes], None]


@dataclass(frozen=True, slots=True)
class TapReading:
    """The latest state and motors, and when each arrived (tap clock, seconds)."""

    state: GazeboState
    state_at_s: float
    #: Betaflight motors 1-4 (0..1) from the latest servo packet; NaN before the first.
    motors: tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class TapCounts:
    fdm: int
    servo: int
    #: Packets of the wrong size or with non-finite numbers: forwarded, not read.
    unreadable: int
    #: Gazebo's sim time from the first to the latest fdm packet, and the wall time between.
    sim_time_s: float
    wall_time_s: float

    @property
    def real_time_factor(self) -> float:
        """Gazebo's sim time per wall time while the tap ran (0 before two packets)."""
        return self.sim_time_s / self.wall_time_s if self.wall_time_s > 0 else 0.0


_NAN4 = (float("nan"),) * 4


class PluginTap:
    """Relays and reads the plugin's packets on a thread; see the module docstring."""

    def __init__(
        self,
        network: Network,
        frame: PluginFrame,
        motor_slots: tuple[int, int, int, int],
        *,
        ports: TapPorts = TapPorts(),
        recorder: PacketRecorder | None = None,
        clock: Callable[[], float] = time.monotonic,
        next_timestamp: Callable[[], float] | None = None,
        gps_fields: GpsFields | None = None,
    ) -> None:
        self.frame = frame
        self.motor_slots = motor_slots
        self.ports = ports
        self.recorder = recorder
        self.clock = clock
        #: The timestamp each fdm packet gets on its way to the SITL; None forwards Gazebo's
        #: own (the tutorial's behaviour: a fast FC clock).
        self.next_timestamp = next_timestamp
        #: A GPS build reads position_xyz as longitude, latitude and altitude and
        #: velocity_xyz as ENU, where the plugin sends NED metres: given this, the tap
        #: rewrites both fields (None: forwarded as the plugin sent them).
        self.gps_fields = gps_fields
        self.error: BaseException | None = None
        self._reading: TapReading | None = None
        self._motors = _NAN4
        self._fdm = self._servo = self._unreadable = 0
        self._first: tuple[float, float] | None = None  # (sim, wall) of the first fdm
        self._last: tuple[float, float] = (0.0, 0.0)
        self._stop = threading.Event()
        self._sockets = self._bind(network)
        self._thread = threading.Thread(target=self._run, name="gazebo-tap", daemon=True)

    def _bind(self, network: Network) -> tuple[socket.socket, socket.socket]:
        bound: list[socket.socket] = []
        try:
            for port in (self.ports.sitl_servo, self.ports.tap_fdm):
                sock = network.socket(socket.AF_INET, socket.SOCK_DGRAM)
                bound.append(sock)
                sock.bind((LOOPBACK, port))
                sock.setblocking(False)
        except OSError as exc:
            for sock in bound:
                sock.close()
            raise GazeboError(
                f"cannot bind the Gazebo relay's UDP ports {self.ports.sitl_servo} and "
                f"{self.ports.tap_fdm} in the SITL's network: {exc}"
            ) from exc
        return bound[0], bound[1]

    def start(self) -> PluginTap:
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        for sock in self._sockets:
            sock.close()

    def reading(self) -> TapReading | None:
        """The latest state and motors; None before the plugin's first packet."""
        return self._reading

    def counts(self) -> TapCounts:
        first, last = self._first, self._last
        sim_s = wall_s = 0.0
        if first is not None:
            sim_s, wall_s = last[0] - first[0], last[1] - first[1]
        return TapCounts(self._fdm, self._servo, self._unreadable, sim_s, wall_s)

    def _run(self) -> None:
        servo_in, fdm_in = self._sockets
        to_plugin = (LOOPBACK, self.ports.plugin_servo)
        to_sitl = (LOOPBACK, self.ports.sitl_fdm)
        try:
            while not self._stop.is_set():
                ready, _, _ = select.select(self._sockets, (), (), 0.2)
                for sock in ready:
                    while True:
                        try:
                            data = sock.recv(2048)
                        except BlockingIOError:
                            break
                        if sock is servo_in:
                            self._send(servo_in, data, to_plugin)
                            self._on_servo(data)
                        else:
                            self._send(fdm_in, self._on_fdm(data), to_sitl)
        except BaseException as exc:  # the backend reports it as the flight's failure
            self.error = exc

    @staticmethod
    def _send(sock: socket.socket, data: bytes, address: tuple[str, int]) -> None:
        # Nobody listening yet (the SITL still booting) is not an error for a relay.
        with contextlib.suppress(ConnectionRefusedError, BlockingIOError):
            sock.sendto(data, address)

    def _on_fdm(self, data: bytes) -> bytes:
        """Read one fdm packet; what to forward (restamped, with the GPS fields rewritten)."""
        now_s = self.clock()
        self._fdm += 1
        if self.recorder is not None:
            self.recorder("fdm", now_s, data)
        try:
            state = self.frame.state(FdmPacket.unpack(data))
        except PacketError:
            self._unreadable += 1
            return data  # the SITL's own checks decide what to do with it
        if self._first is None:
            self._first = (state.sim_time_s, now_s)
        self._last = (state.sim_time_s, now_s)
        self._reading = TapReading(state, now_s, self._motors)
        out = data
        if self.gps_fields is not None:
            position, velocity = self.gps_fields(state)
            out = out[:_VELOCITY_AT] + _VECTORS.pack(*velocity, *position) + out[_PRESSURE_AT:]
        if self.next_timestamp is not None:
            out = _TIMESTAMP.pack(self.next_timestamp()) + out[_TIMESTAMP.size :]
        return out

    def _on_servo(self, data: bytes) -> None:
        now_s = self.clock()
        self._servo += 1
        if self.recorder is not None:
            self.recorder("servo", now_s, data)
        try:
            self._motors = ServoPacket.unpack(data).betaflight_motors(self.motor_slots)
        except PacketError:
            self._unreadable += 1
