"""What is under the FC, as a session or a learning environment configures it: the simulated
world (:class:`World`) and the clock that steps it with the firmware (:class:`Timing`).

Both are groups of :class:`~bfsitl.mission.session.SessionConfig` and options of the gym
environments alike; :func:`~bfsitl.backend.factory.make_backend` reads them to pick and build a
backend.  They live here, below the flights, because the backend is what they configure.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, get_args

from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.physics.sensors import SensorConfig
from bfsitl.physics.wind import Wind

#: The physics under the FC: bfsitl's own simulator, or Gazebo with the BetaflightPlugin.
Physics = Literal["embedded", "gazebo"]
PHYSICS: tuple[Physics, ...] = get_args(Physics)

#: How packets pass between the physics and a lockstep firmware: shared memory where the
#: build and the machine have it (``auto``), always (``shm``), or UDP.
LockstepExchange = Literal["auto", "shm", "udp"]
LOCKSTEP_EXCHANGES: tuple[LockstepExchange, ...] = get_args(LockstepExchange)

#: See World.sensors; measured: FC altitude within 1-2 cm of the truth on average.
DEFAULT_BARO_NOISE_PA = 0.5
#: Accelerometer noise by default, m/s^2 per physics step.  sitl.c truncates the fdm's
#: acceleration to whole LSB (0.038 m/s^2); without noise a hovering vehicle's reading sits
#: on one side of a step, an error of up to one LSB that integrating it turns into drift (it
#: was 2-3 cm/s after a few seconds of hover).  0.05 m/s^2 (about 5 mg, less than a real MEMS
#: accelerometer shows) dithers the steps so they average out.
DEFAULT_ACCEL_NOISE_M_S2 = 0.05


def fly_sensors(
    *,
    baro_noise_std_pa: float | None = None,
    accel_noise_std_m_s2: float | None = None,
    gps_noise: bool = False,
) -> SensorConfig:
    """The sensor errors bfsitl simulates by default; a value given replaces one, and
    ``gps_noise`` adds a typical receiver's GPS errors."""
    sensors = SensorConfig(
        baro_noise_std_pa=(
            DEFAULT_BARO_NOISE_PA if baro_noise_std_pa is None else baro_noise_std_pa
        ),
        accel_noise_std_m_s2=(
            DEFAULT_ACCEL_NOISE_M_S2 if accel_noise_std_m_s2 is None else accel_noise_std_m_s2
        ),
    )
    return sensors.with_typical_gps() if gps_noise else sensors


@dataclass(frozen=True, slots=True)
class World:
    """The simulated world the FC flies in: which physics, the vehicle, the air, the sensors'
    errors and the seed of their randomness.  Everything but ``physics`` and
    ``gz_plugin_dir`` belongs to the embedded physics (Gazebo has its own world file).

    Attributes:
        physics: ``"embedded"`` (bfsitl's simulator and bridge) or ``"gazebo"`` (``gz sim``
            with the BetaflightPlugin, started in the SITL's namespace; the truth is Gazebo's,
            read on the way to the SITL).
        gz_plugin_dir: Where libBetaflightPlugin.so is, for ``physics="gazebo"``; None
            uses Gazebo's search path.
        gz_world: A Gazebo world file of your own with the BetaflightPlugin, for
            ``physics="gazebo"`` (its model and names as in bfsitl's world: the plugin reads
            the barometer on a topic made of them); None flies bfsitl's world.
        quad: The simulated quad: Gazebo's IRIS unless told otherwise.
        wind: Wind and gusts; None is still air.
        sensors: The simulated sensors' errors; by default half a pascal of barometer noise
            and 0.05 metres per second squared of accelerometer noise
            (:func:`fly_sensors`), which dither the steps 4.6.0 truncates its readings to.
        seed: Seeds the sensor noise and the gusts: the same seed gives the same
            disturbances.
        initial_heading_deg: The quad's heading when the flight starts, degrees clockwise
            from north.  A firmware without a compass believes north at boot whatever it is.
    """

    physics: Physics = "embedded"
    gz_plugin_dir: str | Path | None = None
    gz_world: str | Path | None = None
    quad: QuadParams = IRIS
    wind: Wind | None = None
    #: 4.6.0 SITL truncates the fdm pressure to whole pascals (~8.3 cm of altitude), so a
    #: noiseless barometer gives the FC a staircase it cannot resolve inside a step.  Half a
    #: pascal of noise (about what a board's barometer shows) dithers it: the FC's own filter
    #: then averages to the true sub-pascal value.  The accelerometer likewise.
    sensors: SensorConfig = field(default_factory=fly_sensors)
    seed: int = 0
    initial_heading_deg: float = 0.0


@dataclass(frozen=True, slots=True)
class Timing:
    """How the simulation's time runs against the wall clock and the firmware's.

    Attributes:
        speed: Simulation speed as a multiple of wall time.  None: real time (1.0) with a
            stock SITL, as fast as possible with a lockstep build.  Real time allows 0.05 to
            4 (0.5 is the faithful speed on a busy 2-core machine); lockstep any positive
            speed, ``math.inf`` the most.
        lockstep: Step the firmware's clock with the physics (a ``--lockstep`` build is
            needed).  None: whenever the firmware is a lockstep build.
        lockstep_spin: Lockstep: busy-wait for each other's packets instead of sleeping;
            fastest when the run has cores to itself, slower when runs share the cores.
            None: the runner decides (a session spins; a gym environment spins unless it is
            pinned to a core or in a vector environment's worker).
        lockstep_exchange: Lockstep: how packets pass between the physics and the firmware:
            ``"auto"`` (shared memory where the build and the machine have it, else UDP),
            ``"shm"`` or ``"udp"``.  Either gives the same flight.
    """

    speed: float | None = None
    lockstep: bool | None = None
    #: Spinning steals time slices from the neighbours when runs share the cores
    #: (``bfsitl scenario run --jobs 2`` on two cores).
    lockstep_spin: bool | None = None
    lockstep_exchange: LockstepExchange = "auto"
