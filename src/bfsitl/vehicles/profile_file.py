"""Vehicle profile files: a :class:`~bfsitl.vehicles.spec.VehicleSpec` as TOML, read with one
clear line per bad field and written back so that a read of the written file gives the same
profile.

.. code-block:: toml

    [vehicle]
    name = "5inch-freestyle"
    description = "..."
    mass_g = 650
    wheelbase_mm = 225
    inertia_kg_m2 = [0.0024, 0.0024, 0.0042]
    # ... every field of VehicleSpec but sources

    [sources]            # optional: where each figure comes from
    mass_g = "..."
"""

from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path
from typing import Any

import tomli_w

from bfsitl.atomic_file import write_atomically
from bfsitl.errors import SimInputError, VehicleProfileError
from bfsitl.toml_file import read_toml_file
from bfsitl.vehicles.spec import VehicleSpec, quad_params

#: Figures that must be above zero, and those that may be zero.
_POSITIVE = (
    "mass_g",
    "wheelbase_mm",
    "prop_diameter_in",
    "prop_pitch_in",
    "max_thrust_g",
    "max_rpm",
    "motor_time_constant_ms",
    "rotor_inertia_kg_m2",
    "com_to_skids_mm",
)
_NON_NEGATIVE = ("yaw_torque_per_thrust_mm", "com_to_top_mm", "rotors_above_com_mm")
_TRIPLES_POSITIVE = ("inertia_kg_m2",)
_TRIPLES_NON_NEGATIVE = ("drag_linear_n_s_per_m", "drag_quadratic_n_s2_per_m2")
_TEXT = ("name", "description")
#: Fields with a default (VehicleSpec's own).
_OPTIONAL = {"rotors_above_com_mm"}
_KEYS = tuple(f.name for f in fields(VehicleSpec) if f.name != "sources")
#: Below this thrust-to-weight ratio a quad cannot hold a hover and manoeuvre.
MIN_THRUST_TO_WEIGHT = 1.5


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def _check_field(key: str, value: Any) -> tuple[Any, str | None]:
    """The value as the spec holds it, or why it is bad."""
    if key in _TEXT:
        if not isinstance(value, str) or (key == "name" and not value.strip()):
            return None, f"must be {'a name' if key == 'name' else 'text'}, got {value!r}"
        return value, None
    if key in _TRIPLES_POSITIVE or key in _TRIPLES_NON_NEGATIVE:
        numbers = [_number(v) for v in value] if isinstance(value, list) else []
        if len(numbers) != 3 or any(n is None for n in numbers):
            return None, f"must be three numbers [roll, pitch, yaw], got {value!r}"
        floor_ok = (lambda n: n > 0) if key in _TRIPLES_POSITIVE else (lambda n: n >= 0)
        if not all(floor_ok(n) for n in numbers):
            sign = "> 0" if key in _TRIPLES_POSITIVE else ">= 0"
            return None, f"each must be {sign}, got {value!r}"
        return (numbers[0], numbers[1], numbers[2]), None
    number = _number(value)
    if number is None:
        return None, f"must be a finite number, got {value!r}"
    if key in _POSITIVE and number <= 0:
        return None, f"must be > 0, got {value!r}"
    if key in _NON_NEGATIVE and number < 0:
        return None, f"must be >= 0, got {value!r}"
    return number, None


def spec_from_dict(data: dict[str, Any], where: str) -> VehicleSpec:
    """A profile from a file's tables; every bad field is one line of the error.

    Raises:
        VehicleProfileError: Unknown, missing or bad fields, or a quad that cannot fly.
    """
    problems: list[str] = []
    unknown_tables = set(data) - {"vehicle", "sources"}
    if unknown_tables:
        problems.append(
            f"unknown table(s) {', '.join(sorted(unknown_tables))}; a profile has [vehicle] "
            "and [sources]"
        )
    raw = data.get("vehicle")
    if not isinstance(raw, dict):
        raise VehicleProfileError(f"{where}: no [vehicle] table (a vehicle profile has one)")
    sources = data.get("sources", {})
    if not isinstance(sources, dict) or not all(isinstance(v, str) for v in sources.values()):
        problems.append("[sources] must map field names to text")
        sources = {}
    for key in sorted(set(raw) - set(_KEYS)):
        problems.append(f"{key}: unknown field; known: {', '.join(_KEYS)}")
    values: dict[str, Any] = {}
    for key in _KEYS:
        if key not in raw:
            if key not in _OPTIONAL:
                problems.append(f"{key}: missing")
            continue
        value, why = _check_field(key, raw[key])
        if why is not None:
            problems.append(f"{key}: {why}")
        else:
            values[key] = value
    for key in sorted(set(sources) - set(_KEYS)):
        problems.append(f"[sources] {key}: names no field of the profile")
    if problems:
        raise VehicleProfileError(_lines(where, problems))
    spec = VehicleSpec(**values, sources=dict(sources))
    check_flyable(spec, where)
    return spec


def check_flyable(spec: VehicleSpec, where: str) -> None:
    """Raise :class:`VehicleProfileError` when the figures make a quad that cannot fly."""
    if spec.thrust_to_weight < MIN_THRUST_TO_WEIGHT:
        raise VehicleProfileError(
            f"{where}: max_thrust_g: four motors give {4 * spec.max_thrust_g:g} g for "
            f"{spec.mass_g:g} g, a thrust-to-weight ratio of {spec.thrust_to_weight:.2f} "
            f"(at least {MIN_THRUST_TO_WEIGHT} is needed to fly)"
        )
    try:
        quad_params(spec).hover_command  # noqa: B018 - raises when it cannot hover
    except SimInputError as exc:
        raise VehicleProfileError(f"{where}: {exc}") from None


def _lines(where: str, problems: list[str]) -> str:
    count = f"{len(problems)} bad field{'s' if len(problems) != 1 else ''}"
    return f"{where}: {count}:\n" + "\n".join(f"  {line}" for line in problems)


def read_profile(path: Path) -> VehicleSpec:
    """The profile in ``path``.

    Raises:
        VehicleProfileError: The file cannot be read, is no TOML, or has bad fields.
    """
    data = read_toml_file(path, "vehicle profile", VehicleProfileError)
    return spec_from_dict(data, str(path))


def profile_text(spec: VehicleSpec) -> str:
    """``spec`` as a profile file's text (:func:`read_profile` reads it back unchanged)."""
    vehicle: dict[str, Any] = {}
    for key in _KEYS:
        value = getattr(spec, key)
        vehicle[key] = list(value) if isinstance(value, tuple) else value
    tables: dict[str, Any] = {"vehicle": vehicle}
    if spec.sources:
        tables["sources"] = dict(spec.sources)
    return tomli_w.dumps(tables)


def write_profile(spec: VehicleSpec, path: Path) -> None:
    """Write ``spec`` to ``path`` as a profile file."""
    write_atomically(path, profile_text(spec).encode())
