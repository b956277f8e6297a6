"""Helpers for tests that fly the embedded physics against the real SITL.

The RC link proper belongs to the flight issue; these tests need only a plain UDP stream of
rc_packets (AETR + AUX) at 100 Hz, started after the FC answers MSP (an RC packet during
boot leaves 4.6.0 in RXLOSS forever).
"""

from __future__ import annotations

import socket
import threading
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from bfsitl.errors import SitlError
from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import msp_messages as msg
from bfsitl.protocol.sitl_packets import RcPacket
from bfsitl.sim import Simulator
from bfsitl.sim.bridge import SitlBridge, wait_for_replies
from bfsitl.sitl.process import SitlProcess

RC_PORT = 9004
LOW_US, MID_US, HIGH_US = 1000, 1500, 1800


@dataclass
class Sticks:
    roll_us: int = MID_US
    pitch_us: int = MID_US
    throttle_us: int = LOW_US
    yaw_us: int = MID_US
    aux1_us: int = LOW_US

    def channels(self) -> tuple[int, ...]:
        # rc_packet takes the receiver map order, AETR by default.
        return (self.roll_us, self.pitch_us, self.throttle_us, self.yaw_us, self.aux1_us)


class RcStreamer:
    """Sends the current sticks at 100 Hz from a thread until stopped (then disarm, low)."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.sticks = Sticks()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _send(self) -> None:
        packet = RcPacket(time.monotonic(), self.sticks.channels()).pack()
        try:
            self.sock.sendto(packet, ("127.0.0.1", RC_PORT))
        except OSError:
            pass

    def _run(self) -> None:
        while not self._stop.wait(0.01):
            self._send()

    def start(self) -> RcStreamer:
        self._thread.start()
        return self

    def stop(self) -> None:
        self.sticks = Sticks()  # UDP silence makes 4.6.0 hold the last sticks: disarm first
        self._send()
        self._stop.set()
        self._thread.join()


@dataclass
class Flight:
    sitl: SitlProcess
    sim: Simulator
    bridge: SitlBridge
    client: MspClient
    rc: RcStreamer | None = None


@contextmanager
def simulated_sitl(firmware, workdir, attempts: int = 2) -> Iterator[Flight]:
    """A SITL with the physics bridge running and answering.

    Under load, 4.6.0 SITL can lock its gyro/PID tasks out entirely and then never answers an
    fdm packet (shared/research/physics-and-timing.md §2.5).  That is the firmware, not the
    code under test, so a fresh SITL is tried once more, and the retry is reported.
    """
    for attempt in range(1, attempts + 1):
        sim = Simulator()
        sitl = SitlProcess(firmware, workdir=workdir / f"attempt{attempt}", isolate=True)
        bridge = SitlBridge(sim, sitl.prepare_network())
        bridge.bind()
        try:
            with sitl:
                bridge.start()
                try:
                    wait_for_replies(bridge)
                except SitlError as exc:
                    if attempt == attempts:
                        raise
                    warnings.warn(f"fresh SITL after: {exc}", stacklevel=1)
                    continue
                assert sitl.client is not None
                yield Flight(sitl, sim, bridge, sitl.client)
                return
        finally:
            bridge.close()


def start_rc(flight: Flight) -> RcStreamer:
    assert flight.sitl.network is not None
    sock = flight.sitl.network.socket(socket.AF_INET, socket.SOCK_DGRAM)
    flight.rc = RcStreamer(sock).start()
    return flight.rc


def arm(flight: Flight, timeout_s: float = 15.0) -> None:
    """ARM on AUX1 (RAM only), wait until nothing but the switch blocks, then arm."""
    client = flight.client
    client.set_mode_range(0, msg.ModeRange.from_us(0, 0, 1700, 2100))
    rc = flight.rc or start_rc(flight)
    deadline = time.monotonic() + timeout_s
    blockers: set[str] = set()
    while time.monotonic() < deadline:
        blockers = {b.cli_name for b in client.status().arming_blockers}
        if not blockers:
            break
        time.sleep(0.1)
    assert not blockers, f"still blocked: {blockers}"
    rc.sticks.aux1_us = HIGH_US
    while time.monotonic() < deadline:
        if client.status().armed:
            return
        time.sleep(0.05)
    raise AssertionError(f"did not arm: {[b.cli_name for b in client.status().arming_blockers]}")


def mean_motors(bridge: SitlBridge, seconds: float) -> tuple[float, float, float, float]:
    """Average of the applied motor commands (Betaflight M1..M4) over a wall interval."""
    samples = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        samples.append(bridge.motors)
        time.sleep(0.005)
    return tuple(sum(s[i] for s in samples) / len(samples) for i in range(4))  # type: ignore
