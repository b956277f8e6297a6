"""The interface between what is under the flight controller and a flight.

A flight needs five things from whatever sits under the FC, and each backend brings its own
(the policy comes with the object; nobody asks which kind it is):

* a **clock**: simulation time and how to let some pass (a wall-clock sleep at a pace, or
  lockstep steps);
* the **RC sender**: UDP packets, the sticks riding in lockstep packets, or MSP to a board;
* what it does to the **SITL process and its MSP links** (:class:`~bfsitl.sitl.process.SitlHooks`);
* the **truth**: the simulated state, or None where nobody knows it (Gazebo, a board);
* a typed **disturbance surface** (:class:`~bfsitl.backend.disturbances.Disturbances`): RC,
  GPS, motors, sensors, wind, for faults and users alike.

It also says how the FC's accelerometer is scaled (:class:`ImuScale`): a SITL's virtual IMU
reads 256 LSB per g and truncates, a real board's sensor has its own scale.

:func:`~bfsitl.backend.factory.make_backend` is the one place that picks a backend, from the
firmware's build record and the session's options.
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar, Protocol

from bfsitl.backend.disturbances import Disturbances
from bfsitl.fc.rc_link import RcSender, UdpRcLink
from bfsitl.protocol import messages as msg
from bfsitl.sitl.process import SitlHooks

if TYPE_CHECKING:
    from bfsitl.fc.msp_client import MspClient
    from bfsitl.physics import Simulator
    from bfsitl.sim.bridge import BridgeStats, SitlBridge
    from bfsitl.sim.lockstep import LockstepBridge
    from bfsitl.sitl.process import SitlProcess


@dataclass(frozen=True, slots=True)
class ImuScale:
    """How MSP_RAW_IMU's accelerometer integers become physical units on this FC."""

    #: Accelerometer LSB per g (``acc.dev.acc_1G``).
    acc_1g_lsb: float
    #: What the FC's conversion to an integer takes off on average, in LSB (added back).
    acc_truncation_lsb: float = 0.0


#: The SITL's virtual IMU: 256 LSB per g, truncated to whole LSB (see protocol.messages.constants).
SITL_IMU = ImuScale(msg.SITL_ACC_1G_LSB, msg.SITL_ACC_TRUNCATION_LSB)
#: A real board: the usual MEMS IMUs (MPU6000, BMI270, ICM426xx at +-16 g) report 2048 per
#: g, and their driver rounds, so nothing is added back.
BOARD_IMU = ImuScale(2048.0)


@dataclass(frozen=True, slots=True)
class Truth:
    """The simulated state at one instant (NaN everywhere when nobody knows it)."""

    time_s: float
    altitude_m: float
    climb_m_s: float
    tilt_deg: float
    attitude_deg: tuple[float, float, float]  # Betaflight's roll, pitch, yaw
    on_ground: bool
    motors: tuple[float, float, float, float]
    north_m: float = math.nan  # NED metres from the world's origin
    east_m: float = math.nan

    @classmethod
    def unknown(cls, time_s: float) -> Truth:
        nan = math.nan
        return cls(time_s, nan, nan, nan, (nan, nan, nan), False, (nan, nan, nan, nan))


class SessionClock(Protocol):
    """The mission clock (simulation time) and how to let some of it pass."""

    def now_s(self) -> float: ...

    def sleep_s(self, seconds: float) -> None: ...


class WallClock:
    """Wall time since ``started_s``: the clock of a real board and of Gazebo."""

    def __init__(self, started_s: float) -> None:
        self.started_s = started_s

    def now_s(self) -> float:
        return time.monotonic() - self.started_s

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class Backend:
    """What any backend gives a flight; this base is the one that knows nothing: wall time,
    no truth, nothing to disturb (a real board is this with its own IMU scale)."""

    #: For progress lines and errors.
    name: ClassVar[str] = "a real board"
    #: The FC's clock follows the physics step by step.
    lockstep: ClassVar[bool] = False
    imu: ImuScale = BOARD_IMU

    def __init__(self) -> None:
        self.started_s = time.monotonic()
        self.clock: SessionClock = WallClock(self.started_s)
        self.disturbances = Disturbances(self.name)

    def time_s(self) -> float:
        """The mission clock's reading (simulation time where there is a simulation)."""
        return self.clock.now_s()

    def truth(self) -> Truth | None:
        """The simulated state now, NED from the world's origin; None where it is unknown."""
        return None

    @property
    def simulator(self) -> Simulator | None:
        """The simulated vehicle, for reading its state; None when the physics is not ours."""
        return None

    def stats(self) -> BridgeStats | None:
        """The physics exchange's counters, where there is one."""
        return None

    def failure(self) -> str | None:
        """Why the backend's own machinery stopped (a bridge thread that died), if it did."""
        return None

    @property
    def exchange(self) -> str | None:
        """How the physics' packets reach the firmware (``"udp"``, ``"shm"``); None when the
        physics is not ours."""
        return None


class SitlBackend(Backend):
    """A backend under a SITL process: it starts the process its own way, supplies its RC
    sender and handles a reboot.  This base runs the SITL with external physics (Gazebo):
    wall time, RC over UDP, no truth; RC is the only thing it can disturb."""

    name: ClassVar[str] = "external physics"
    imu = SITL_IMU

    def __init__(self) -> None:
        super().__init__()
        self.rc: RcSender | None = None
        #: The exchange with the firmware, where the physics is bfsitl's.
        self.bridge: SitlBridge | LockstepBridge | None = None
        self.disturbances = Disturbances(self.name, rc=lambda: self.rc)

    @property
    def hooks(self) -> SitlHooks:
        """Given to the SITL process when it is made."""
        return SitlHooks()

    @property
    def sitl_env(self) -> Mapping[str, str] | None:
        """Variables for the firmware's environment (None: it inherits bfsitl's)."""
        return None

    def start(self, sitl: SitlProcess, stack: ExitStack) -> None:
        """Start the SITL and whatever feeds it; ``stack`` stops them on the way out."""
        stack.callback(sitl.stop)
        sitl.start()

    def rc_sender(self, sitl: SitlProcess) -> RcSender:
        """The RC link, once the FC is provisioned (an RC packet during boot leaves 4.6.0 in
        RXLOSS for good)."""
        assert sitl.network is not None
        self.rc = UdpRcLink(sitl.network)
        return self.rc

    def reboot(self, sitl: SitlProcess, client: MspClient) -> None:
        """The FC was told to reboot: in SITL the process ends; start it again."""
        client.reboot()
        sitl.restart_after_reboot()
