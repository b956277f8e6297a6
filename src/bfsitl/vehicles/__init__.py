"""Vehicle profiles: the quad the physics flies, as a pilot describes it.

``--vehicle NAME|FILE.toml`` wherever a flight starts, and ``[vehicle] model`` in a scenario,
take a name of :func:`vehicle_names` (``iris``, the default, and the shipped profiles) or a
profile file (:mod:`bfsitl.vehicles.profile_file`); :func:`load_vehicle` makes the physics'
:class:`~bfsitl.physics.params.QuadParams` of it.
"""

from bfsitl.vehicles.catalogue import (
    DEFAULT_VEHICLE,
    load_vehicle,
    shipped_profiles,
    vehicle_names,
)
from bfsitl.vehicles.profile_file import profile_text, read_profile, write_profile
from bfsitl.vehicles.spec import VehicleSpec, quad_params
from bfsitl.vehicles.throttle import hover_throttle_us, stick_per_acceleration_us

__all__ = [
    "DEFAULT_VEHICLE",
    "VehicleSpec",
    "hover_throttle_us",
    "load_vehicle",
    "profile_text",
    "quad_params",
    "read_profile",
    "shipped_profiles",
    "stick_per_acceleration_us",
    "vehicle_names",
    "write_profile",
]
