"""bfsitl's own physics under a SITL, in real time or in lockstep.

Both read the truth the same way (one consistent state between two physics steps) and offer
every disturbance; they differ in who owns time:

* :class:`RealTimeBackend`: a stock SITL on the wall clock.  The physics runs on its own
  thread at ``speed`` x real time; a wait is a wall-clock sleep; RC goes over UDP.  Away
  from 1x the firmware's clock is locked to the physics' pace.
* :class:`LockstepBackend`: a ``--lockstep`` build.  The SITL boots already locked to the
  physics (:meth:`LockstepBridge.lock` at each launch), every MSP wait and every mission
  wait steps the simulation, and RC rides in the fdm packets.
"""

from __future__ import annotations

import time
from collections.abc import Mapping
from contextlib import ExitStack
from typing import TYPE_CHECKING, ClassVar

from bfsitl.backend.base import SitlBackend, Truth
from bfsitl.backend.disturbances import Disturbances
from bfsitl.build.binary_scan import RX_FRAMES_ENV
from bfsitl.errors import SitlError, SitlExitedError
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.fc.rc_link import RcSender
from bfsitl.link.base import Link
from bfsitl.link.shm_exchange import ShmExchange
from bfsitl.physics import Simulator
from bfsitl.physics.frames import betaflight_attitude_and_tilt_deg
from bfsitl.sim.bridge import BridgeStats, SitlBridge, bridged_sitl, wait_for_replies
from bfsitl.sim.health import HealthMonitor, lock_clock
from bfsitl.sim.lockstep import (
    REPLY_SPIN_S,
    SITL_SPIN_ENV,
    LockstepBridge,
)
from bfsitl.sim.lockstep_io import LockstepClock, LockstepRc, SteppedLink
from bfsitl.sitl.process import SitlHooks

if TYPE_CHECKING:
    from collections.abc import Callable

    from bfsitl.fc.msp_client import MspClient
    from bfsitl.sitl.process import SitlProcess


class _EmbeddedPhysics(SitlBackend):
    """What both embedded backends share: the simulator, its truth, every disturbance."""

    def __init__(self, simulator: Simulator, progress: Callable[[str], None]) -> None:
        super().__init__()
        self._simulator = simulator
        self.progress = progress
        self.disturbances = Disturbances(
            self.name, rc=lambda: self.rc, simulator=simulator, gps_lost=self._set_gps_lost
        )

    @property
    def exchange(self) -> str | None:
        return "udp"

    def _set_gps_lost(self, lost: bool) -> None:
        if self.bridge is not None:
            self.bridge.set_gps_lost(lost)

    @property
    def simulator(self) -> Simulator:
        return self._simulator

    def time_s(self) -> float:
        return self._simulator.time_s

    def truth(self) -> Truth | None:
        bridge, simulator = self.bridge, self._simulator
        if bridge is None:
            return None

        def read() -> Truth:
            time_s, position_ned_m, velocity_ned_m_s, quaternion = simulator.kinematics()
            attitude_deg, tilt_deg = betaflight_attitude_and_tilt_deg(quaternion)
            north, east, _down = position_ned_m
            return Truth(
                time_s,
                simulator.altitude_m,
                -velocity_ned_m_s[2],
                tilt_deg,
                attitude_deg,
                simulator.on_ground,
                tuple(bridge.motors),  # type: ignore[arg-type]
                north,
                east,
            )

        # Between two steps (on the bridge thread in real time): one consistent state.
        return bridge.between_steps(read)

    def stats(self) -> BridgeStats | None:
        return self.bridge.stats() if self.bridge is not None else None

    def failure(self) -> str | None:
        error = self.bridge.error if self.bridge is not None else None
        return None if error is None else f"the physics bridge failed: {error!r}"


class RealTimeClock:
    """Simulation time of a real-time backend; letting it pass is a wall-clock sleep at the
    backend's pace."""

    def __init__(self, simulator: Simulator, speed: float) -> None:
        self.simulator = simulator
        self.speed = speed

    def now_s(self) -> float:
        return self.simulator.time_s

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds / self.speed)


class RealTimeBackend(_EmbeddedPhysics):
    """A stock SITL on the wall clock, fed by the physics on a thread (module docstring)."""

    name: ClassVar[str] = "real-time physics"

    def __init__(
        self, simulator: Simulator, *, speed: float, progress: Callable[[str], None]
    ) -> None:
        super().__init__(simulator, progress)
        self.speed = speed
        self.clock = RealTimeClock(simulator, speed)
        self._paced: SitlBridge | None = None

    def start(self, sitl: SitlProcess, stack: ExitStack) -> None:
        bridge = stack.enter_context(bridged_sitl(sitl, self._simulator, speed=self.speed))
        self._paced = self.bridge = bridge
        self.progress(f"physics running at {self.speed:g}x real time")
        if self.speed != 1.0:
            self.progress(f"locking the firmware clock to {self.speed:g}x")
            assert sitl.client is not None
            lock_clock(HealthMonitor(bridge, sitl.client))

    def reboot(self, sitl: SitlProcess, client: MspClient) -> None:
        bridge = self._paced
        if bridge is None:
            raise SitlError("the physics bridge is not started")
        bridge.pause()
        client.reboot()
        sitl.restart_after_reboot()
        bridge.resume()
        wait_for_replies(bridge)


class LockstepBackend(_EmbeddedPhysics):
    """A lockstep build stepped by the physics in the caller's thread (module docstring)."""

    name: ClassVar[str] = "lockstep physics"
    lockstep: ClassVar[bool] = True

    def __init__(
        self,
        simulator: Simulator,
        *,
        speed: float | None,
        spin: bool,
        progress: Callable[[str], None],
        alive: Callable[[], None] | None = None,
        shared_memory: bool = False,
        rc_rate_hz: float | None = None,
        receiver_frames: bool = False,
    ) -> None:
        super().__init__(simulator, progress)
        self.speed = speed
        self.spin = spin
        #: The RC link's frame rate (None: a frame in every packet).
        self.rc_rate_hz = rc_rate_hz
        #: Ask a 4.6.0 build to count a receiver frame per RC trailer (master always does).
        self.receiver_frames = receiver_frames
        #: Asked during a wait that runs long: raises if the SITL has ended.
        self.alive = alive
        self._lockstep: LockstepBridge | None = None
        #: The shared-memory exchange (made now: its path goes into the SITL's environment),
        #: or None for UDP.
        self.shared: ShmExchange | None = ShmExchange() if shared_memory else None

    @property
    def _bridge(self) -> LockstepBridge:
        if self._lockstep is None:
            raise SitlError("the lockstep bridge is not started")
        return self._lockstep

    @property
    def hooks(self) -> SitlHooks:
        # Bound methods, so the process may be made before the bridge exists.
        return SitlHooks(
            on_spawn=lambda: self._bridge.lock(),
            link_wrapper=self._wrap,
            client_clock=lambda: self._bridge.sim_time_s,
        )

    def _wrap(self, link: Link) -> Link:
        return SteppedLink(link, self._bridge)

    @property
    def exchange(self) -> str | None:
        return "shm" if self.shared is not None else "udp"

    @property
    def sitl_env(self) -> Mapping[str, str] | None:
        env = {} if self.spin else {SITL_SPIN_ENV: "0"}
        if self.receiver_frames:
            env.update([RX_FRAMES_ENV])
        if self.shared is not None:
            env.update(self.shared.env)
        return env or None

    def start(self, sitl: SitlProcess, stack: ExitStack) -> None:
        if self.shared is not None:
            stack.callback(self.shared.close)
        bridge = LockstepBridge(
            self._simulator,
            sitl.prepare_network(),
            speed=self.speed,
            profile=profile_of_binary(sitl.firmware.path),
            spin_s=REPLY_SPIN_S if self.spin else 0.0,
            alive=self.alive,
            exchange=self.shared,
            rc_rate_hz=self.rc_rate_hz,
        )
        self._lockstep = self.bridge = bridge
        bridge.bind()
        stack.callback(bridge.close)
        self.clock = LockstepClock(bridge)
        stack.callback(sitl.stop)
        sitl.start()
        bridge.set_profile(sitl.profile)
        pace = "as fast as it goes" if self.speed is None else f"paced to {self.speed:g}x real time"
        through = "shared memory" if self.shared is not None else "UDP"
        self.progress(
            f"lockstep: the FC's clock follows the physics, {pace}, packets through {through}"
        )

    def rc_sender(self, sitl: SitlProcess) -> RcSender:
        # Closes first on the way out: its disarm is stepped in before the rest stops.
        self.rc = LockstepRc(self._bridge)
        return self.rc

    def reboot(self, sitl: SitlProcess, client: MspClient) -> None:
        client.reboot()
        # The FC acts on the reboot in a later pass: step until the process has ended.
        try:
            self.clock.sleep_s(10.0)
        except SitlExitedError:
            pass
        sitl.restart_after_reboot()
