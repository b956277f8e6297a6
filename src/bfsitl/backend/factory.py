"""The one place that picks a backend: from the firmware's build record, the session's
:class:`~bfsitl.backend.options.World` (the physics) and its
:class:`~bfsitl.backend.options.Timing` (the pace and the lockstep).

===========================  ==================  =============================================
``World.physics``            firmware            backend
===========================  ==================  =============================================
``embedded``                 stock build         :class:`RealTimeBackend` (0.05..4 x real time)
``embedded``                 ``--lockstep``      :class:`LockstepBackend` (any pace, max by
                                                 default); ``Timing(lockstep=False)`` flies it
                                                 on the wall clock instead
``gazebo``                   stock build         :class:`GazeboBackend`
===========================  ==================  =============================================

Every combination that cannot work is refused here, before anything starts, with the fix.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING

from bfsitl.backend.base import SitlBackend
from bfsitl.backend.options import LOCKSTEP_EXCHANGES, PHYSICS, LockstepExchange, Timing, World
from bfsitl.errors import BfsitlError
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from bfsitl.sitl.firmware import FirmwareBinary

if TYPE_CHECKING:
    from bfsitl.physics import Simulator

#: A stock SITL runs on the wall clock; outside this range it cannot keep up or crawls.
REAL_TIME_SPEEDS = (0.05, 4.0)


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
            f"build --lockstep`, then --firmware with its name"
        )
    return speed


def wants_lockstep(firmware: FirmwareBinary, asked: bool | None) -> bool:
    """Lockstep whenever the firmware is a lockstep build, unless told otherwise."""
    if asked and not firmware.lockstep:
        raise BfsitlError(
            f"lockstep asked for, but {firmware.path} is not a lockstep build: build one "
            f"with `bfsitl firmware build --lockstep` and pass its name"
        )
    return firmware.lockstep if asked is None else asked


def uses_shm_exchange(firmware: FirmwareBinary, asked: LockstepExchange) -> bool:
    """Whether a lockstep run of ``firmware`` takes the shared-memory exchange."""
    from bfsitl.link.shm_exchange import shm_exchange_supported

    if asked not in LOCKSTEP_EXCHANGES:
        raise BfsitlError(f"lockstep exchange {asked!r}: one of {', '.join(LOCKSTEP_EXCHANGES)}")
    if asked == "udp":
        return False
    possible = firmware.shm_exchange and shm_exchange_supported()
    if asked == "shm" and not possible:
        why = (
            "this machine is not x86-64 Linux"
            if firmware.shm_exchange
            else f"{firmware.path} was built without it: rebuild it with this bfsitl "
            f"(`bfsitl firmware build --lockstep`)"
        )
        raise BfsitlError(
            f"the shared-memory lockstep exchange was asked for, but {why}; or use the UDP exchange"
        )
    return possible


def make_simulator(world: World) -> Simulator:
    """The embedded physics of ``world`` (its C library is built on first use: without a C
    compiler, the KernelUnavailableError says what to install)."""
    from bfsitl.physics import Simulator

    simulator = Simulator(world.quad, sensors=world.sensors, wind=world.wind, seed=world.seed)
    if world.initial_heading_deg:
        simulator.reset(yaw_deg=world.initial_heading_deg)
    return simulator


def make_backend(
    world: World,
    timing: Timing,
    firmware: FirmwareBinary,
    *,
    progress: Callable[[str], None],
    rc_link: bool = True,
    rc_rate_hz: float | None = DEFAULT_RC_RATE_HZ,
    alive: Callable[[], None] | None = None,
) -> SitlBackend:
    """The backend for ``firmware`` in ``world`` on ``timing`` (see the module table).
    ``rc_link`` False (RC from elsewhere) needs a real-time SITL.  ``rc_rate_hz`` is the
    lockstep RC link's frame rate (None: a frame in every packet, and 4.6.0's stock receiver,
    which calls every check a frame).  ``alive`` is asked during a lockstep wait that runs
    long (it raises if the SITL has ended)."""
    from bfsitl.backend.embedded import LockstepBackend, RealTimeBackend
    from bfsitl.backend.gazebo import GazeboBackend

    speed = timing.speed
    check_speed(speed)
    if world.physics == "gazebo":
        if speed not in (None, 1.0):
            raise BfsitlError(
                "--speed applies to the embedded physics only; Gazebo sets its own pace"
            )
        backend = GazeboBackend(
            world.gz_plugin_dir, progress=progress, wind=world.wind, world_file=world.gz_world
        )
        if firmware.lockstep:
            raise BfsitlError(
                f"{firmware.path} is a lockstep build: its clock follows bfsitl's own "
                f"physics, and Gazebo's plugin reads only stock motor packets. Use a stock "
                f"build with --physics gazebo"
            )
        return backend
    if world.physics != "embedded":
        raise BfsitlError(f"unknown physics {world.physics!r}: {' or '.join(PHYSICS)}")
    if wants_lockstep(firmware, timing.lockstep):
        if not rc_link:
            raise BfsitlError(
                "rc_link=False (RC from elsewhere, e.g. MSP through the serial "
                "bridge) needs a real-time SITL: a lockstep build takes its RC "
                "in the fdm packets bfsitl steps it with; use a stock build"
            )
        shared = uses_shm_exchange(firmware, timing.lockstep_exchange)
        simulator = make_simulator(world)
        # Unsaid, a session spins: its run has the cores unless its runner says otherwise.
        spin = True if timing.lockstep_spin is None else timing.lockstep_spin
        return LockstepBackend(
            simulator,
            speed=None if speed is None or math.isinf(speed) else speed,
            spin=spin,
            progress=progress,
            alive=alive,
            shared_memory=shared,
            rc_rate_hz=rc_rate_hz,
            receiver_frames=rc_rate_hz is not None and firmware.rx_frames,
        )
    return RealTimeBackend(make_simulator(world), speed=real_time_speed(speed), progress=progress)
