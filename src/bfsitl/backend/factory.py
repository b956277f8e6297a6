"""The one place that picks a backend: from the firmware's build record and the options.

===========================  ==================  =============================================
physics                      firmware            backend
===========================  ==================  =============================================
``embedded``                 stock build         :class:`RealTimeBackend` (0.05..4 x real time)
``embedded``                 ``--lockstep``      :class:`LockstepBackend` (any pace, max by
                                                 default); ``lockstep=False`` flies it on the
                                                 wall clock instead
``gazebo``                   stock build         :class:`GazeboBackend`
===========================  ==================  =============================================

Every combination that cannot work is refused here, before anything starts, with the fix.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Protocol, get_args

from bfsitl.backend.base import SitlBackend
from bfsitl.errors import BfsitlError
from bfsitl.physics.params import QuadParams
from bfsitl.physics.sensors import SensorConfig
from bfsitl.physics.wind import Wind
from bfsitl.sitl.firmware import FirmwareBinary

if TYPE_CHECKING:
    from bfsitl.physics import Simulator

#: A stock SITL runs on the wall clock; outside this range it cannot keep up or crawls.
REAL_TIME_SPEEDS = (0.05, 4.0)
PHYSICS = ("embedded", "gazebo")


class BackendOptions(Protocol):
    """What the factory reads of a session's configuration (``SessionConfig`` has it)."""

    @property
    def physics(self) -> str: ...
    @property
    def speed(self) -> float | None: ...
    @property
    def lockstep(self) -> bool | None: ...
    @property
    def rc_link(self) -> bool: ...
    @property
    def lockstep_spin(self) -> bool: ...
    @property
    def lockstep_exchange(self) -> LockstepExchange: ...
    @property
    def quad(self) -> QuadParams: ...
    @property
    def sensors(self) -> SensorConfig: ...
    @property
    def wind(self) -> Wind | None: ...
    @property
    def seed(self) -> int: ...
    @property
    def initial_heading_deg(self) -> float: ...
    @property
    def gz_plugin_dir(self) -> str | Path | None: ...


def check_speed(speed: float | None) -> None:
    """Refuse a speed that is no positive number, whatever the backend."""
    if speed is not None and not (speed > 0 and not math.isnan(speed)):
        raise BfsitlError(f"speed {speed} must be a positive number")


def real_time_speed(speed: float | None) -> float:
    """The speed of a stock SITL (None: real time), checked against its range."""
    speed = 1.0 if speed is None else speed
    low, high = REAL_TIME_SPEEDS
    if not low <= speed <= high:
        raise BfsitlError(
            f"speed {speed:g} is outside {low:g}..{high:g} for a stock SITL, which runs on the "
            f"wall clock; faster (or --speed max) needs a lockstep build: `bfsitl firmware "
            f"build --lockstep`, then --firmware with its name")
    return speed


def wants_lockstep(firmware: FirmwareBinary, asked: bool | None) -> bool:
    """Lockstep whenever the firmware is a lockstep build, unless told otherwise."""
    if asked and not firmware.lockstep:
        raise BfsitlError(
            f"lockstep asked for, but {firmware.path} is not a lockstep build: build one "
            f"with `bfsitl firmware build --lockstep` and pass its name")
    return firmware.lockstep if asked is None else asked


#: How packets pass between the physics and a lockstep firmware: shared memory where the
#: build and the machine have it (``auto``), always (``shm``), or UDP.
LockstepExchange = Literal["auto", "shm", "udp"]
LOCKSTEP_EXCHANGES: tuple[LockstepExchange, ...] = get_args(LockstepExchange)


def uses_shm_exchange(firmware: FirmwareBinary, asked: LockstepExchange) -> bool:
    """Whether a lockstep run of ``firmware`` takes the shared-memory exchange."""
    from bfsitl.link.shm_exchange import shm_exchange_supported

    if asked not in LOCKSTEP_EXCHANGES:
        raise BfsitlError(f"lockstep exchange {asked!r}: one of {', '.join(LOCKSTEP_EXCHANGES)}")
    if asked == "udp":
        return False
    possible = firmware.shm_exchange and shm_exchange_supported()
    if asked == "shm" and not possible:
        why = ("this machine is not x86-64 Linux" if firmware.shm_exchange else
               f"{firmware.path} was built without it: rebuild it with this bfsitl "
               f"(`bfsitl firmware build --lockstep`)")
        raise BfsitlError(f"the shared-memory lockstep exchange was asked for, but {why}; "
                          f"or use the UDP exchange")
    return possible


def make_simulator(options: BackendOptions) -> Simulator:
    """The embedded physics for ``options`` (its C library is built on first use: without a C
    compiler, the KernelUnavailableError says what to install)."""
    from bfsitl.physics import Simulator

    simulator = Simulator(options.quad, sensors=options.sensors, wind=options.wind,
                          seed=options.seed)
    heading_deg = getattr(options, "initial_heading_deg", 0.0)
    if heading_deg:
        simulator.reset(yaw_deg=heading_deg)
    return simulator


def make_backend(options: BackendOptions, firmware: FirmwareBinary, *,
                 progress: Callable[[str], None],
                 alive: Callable[[], None] | None = None) -> SitlBackend:
    """The backend for ``firmware`` under ``options`` (see the module table).  ``alive`` is
    asked during a lockstep wait that runs long (it raises if the SITL has ended)."""
    from bfsitl.backend.embedded import LockstepBackend, RealTimeBackend
    from bfsitl.backend.gazebo import GazeboBackend

    check_speed(options.speed)
    if options.physics == "gazebo":
        if options.speed not in (None, 1.0):
            raise BfsitlError("--speed applies to the embedded physics only; Gazebo sets "
                              "its own pace")
        backend = GazeboBackend(options.gz_plugin_dir, progress=progress)
        if firmware.lockstep:
            raise BfsitlError(
                f"{firmware.path} is a lockstep build: its clock follows bfsitl's own "
                f"physics, and Gazebo's plugin reads only stock motor packets. Use a stock "
                f"build with --physics gazebo")
        return backend
    if options.physics != "embedded":
        raise BfsitlError(f"unknown physics {options.physics!r}: "
                          f"{' or '.join(PHYSICS)}")
    if wants_lockstep(firmware, options.lockstep):
        if not options.rc_link:
            raise BfsitlError("rc_link=False (RC from elsewhere, e.g. MSP through the serial "
                              "bridge) needs a real-time SITL: a lockstep build takes its RC "
                              "in the fdm packets bfsitl steps it with; use a stock build")
        speed = options.speed
        shared = uses_shm_exchange(firmware, options.lockstep_exchange)
        simulator = make_simulator(options)
        return LockstepBackend(simulator, speed=None if speed is None or math.isinf(speed)
                               else speed, spin=options.lockstep_spin, progress=progress,
                               alive=alive, shared_memory=shared)
    return RealTimeBackend(make_simulator(options),
                           speed=real_time_speed(options.speed), progress=progress)
