"""Embedded quadrotor physics for flying Betaflight SITL without Gazebo.

``Simulator`` steps a Gazebo-IRIS-equivalent quad (:data:`IRIS`) in a NED world and reports
IMU and barometer readings in the 4.6.0 SITL's fdm conventions; the UDP bridge
(:mod:`bfsitl.sim.bridge`) exchanges them with the firmware.  Frame conventions live in
:mod:`bfsitl.sim.frames`; parameters and their sources in :mod:`bfsitl.sim.params`.
"""

from bfsitl.sim.atmosphere import betaflight_altitude_m, isa_pressure_pa
from bfsitl.sim.frames import GeoPoint
from bfsitl.sim.params import IRIS, STANDARD_GRAVITY_M_S2, QuadParams, SimInputError, Wind
from bfsitl.sim.sensors import SensorConfig, SensorReading
from bfsitl.sim.vehicle import Simulator, VehicleState

__all__ = [
    "IRIS",
    "STANDARD_GRAVITY_M_S2",
    "GeoPoint",
    "QuadParams",
    "SensorConfig",
    "SensorReading",
    "SimInputError",
    "Simulator",
    "VehicleState",
    "Wind",
    "betaflight_altitude_m",
    "isa_pressure_pa",
]
