"""Pure physics: a multirotor, its ground contact, wind, sensors, atmosphere and frames.

Nothing here knows about the firmware, the network or a flight: :class:`Simulator` steps a
Gazebo-IRIS-equivalent quad (:data:`IRIS`) in a NED world and reports what its sensors read;
the exchange with a SITL lives in :mod:`bfsitl.sim`, the flight above that in
:mod:`bfsitl.mission`.  The model itself is C, written once (``bfsitl/kernel/physics.c``,
built with the machine's C compiler by :mod:`bfsitl.kernel`); this package is its typed face
and imports nothing else of bfsitl but that and :mod:`bfsitl.errors`.  Frame conventions are in
:mod:`bfsitl.physics.frames`, parameters and their sources in :mod:`bfsitl.physics.params`,
constants in :mod:`bfsitl.physics.constants`.
"""

from bfsitl.physics.atmosphere import betaflight_altitude_m, isa_pressure_pa
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.frames import GeoPoint
from bfsitl.physics.multirotor import Simulator, VehicleState
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.physics.sensors import SensorConfig, SensorReading
from bfsitl.physics.wind import Wind

__all__ = [
    "IRIS",
    "STANDARD_GRAVITY_M_S2",
    "GeoPoint",
    "QuadParams",
    "SensorConfig",
    "SensorReading",
    "Simulator",
    "VehicleState",
    "Wind",
    "betaflight_altitude_m",
    "isa_pressure_pa",
]
