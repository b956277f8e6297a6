"""Vehicles by name or file: what ``--vehicle NAME|FILE.toml`` and ``[vehicle] model`` accept.

``iris`` is the physics' own :data:`~bfsitl.physics.params.IRIS` (Gazebo's, the default,
unchanged); the other names are the profiles shipped in ``bfsitl/library/vehicles``.  Anything
else is read as a profile file.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from pathlib import Path
from types import MappingProxyType

from bfsitl.errors import VehicleProfileError
from bfsitl.library import vehicle_files
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.vehicles.profile_file import read_profile
from bfsitl.vehicles.spec import VehicleSpec, quad_params

#: The default vehicle: Gazebo's IRIS, which the tutorial flies.
DEFAULT_VEHICLE = "iris"


@functools.cache
def shipped_profiles() -> Mapping[str, VehicleSpec]:
    """The profiles shipped with bfsitl, by name (read once: they are package data)."""
    specs = (read_profile(path) for path in vehicle_files())
    return MappingProxyType({spec.name: spec for spec in specs})


def vehicle_names() -> tuple[str, ...]:
    """Every name ``--vehicle`` takes: ``iris`` and the shipped profiles."""
    return (DEFAULT_VEHICLE, *sorted(shipped_profiles()))


def load_vehicle(given: str | Path, *, relative_to: Path | None = None) -> QuadParams:
    """The physics of a vehicle named ``given`` (``iris``, ``5inch-freestyle``), or of the
    profile file at that path (relative to ``relative_to`` when given and relative).

    Args:
        given: A vehicle's name (:func:`vehicle_names`) or a profile file's path.
        relative_to: Where a relative path is taken from (a scenario file's folder); None:
            the working directory.

    Returns:
        The embedded physics' parameters of the vehicle (for ``World(quad=...)``).

    Raises:
        VehicleProfileError: Neither a known name nor a readable profile (the message lists
            the names), or a profile with bad fields.
    """
    text = str(given)
    if text == DEFAULT_VEHICLE:
        return IRIS
    shipped = shipped_profiles()
    if text in shipped:
        return quad_params(shipped[text])
    path = Path(text).expanduser()
    if relative_to is not None and not path.is_absolute():
        path = relative_to / path
    if path.suffix == ".toml" or path.exists():
        if not path.is_file():
            raise VehicleProfileError(
                f"vehicle profile {path} does not exist (shipped vehicles: "
                f"{', '.join(vehicle_names())})"
            )
        return quad_params(read_profile(path))
    raise VehicleProfileError(
        f"unknown vehicle {text!r}: give one of {', '.join(vehicle_names())}, or a profile "
        "file (NAME.toml; docs/vehicles.md)"
    )
