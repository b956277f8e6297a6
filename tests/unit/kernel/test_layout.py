"""What exists in two languages is the same in both: the C structures and their ctypes
mirrors (every field's name, type, length and order), the lockstep loop's status codes, and
the constants the physics and its Python face both use, each read from the C source; and every
vehicle parameter of QuadParams reaches the C model."""

from __future__ import annotations

import ctypes
import dataclasses
import re
from pathlib import Path

import pytest

from bfsitl.kernel import layout
from bfsitl.physics import IRIS, QuadParams, Simulator, atmosphere, constants, multirotor
from bfsitl.sim import lockstep_stepper

SOURCES = Path(layout.__file__).parent
C_TYPES: dict[str, object] = {
    "double": ctypes.c_double,
    "int32_t": ctypes.c_int32,
    "uint32_t": ctypes.c_uint32,
    "uint64_t": ctypes.c_uint64,
    "int64_t": ctypes.c_int64,
    "uint8_t *": ctypes.c_void_p,
    "bk_rng": layout.Rng,
    "bk_reading": layout.Reading,
}


def c_struct(path: Path, name: str) -> list[tuple[str, str, tuple[int, ...]]]:
    """(field, C type, array lengths) of ``typedef struct name { ... } name;`` in ``path``."""
    text = re.sub(r"/\*.*?\*/", "", path.read_text(), flags=re.S)
    body = re.search(rf"typedef struct {name} \{{(.*?)\}} {name};", text, re.S)
    assert body, f"struct {name} not found in {path.name}"
    fields = []
    for declaration in body.group(1).split(";"):
        declaration = " ".join(declaration.split())
        if not declaration:
            continue
        match = re.fullmatch(r"(\w+(?: \*)?) ?(\w+)((?:\[\d+\])*)", declaration)
        assert match, f"{name}: cannot read {declaration!r}"
        c_type, field, dims = match.groups()
        fields.append((field, c_type.strip(), tuple(int(d) for d in re.findall(r"\d+", dims))))
    return fields


def ctypes_fields(structure: type[ctypes.Structure]) -> list[tuple[str, object, tuple[int, ...]]]:
    out = []
    for field, kind in structure._fields_:
        dims: list[int] = []
        while hasattr(kind, "_length_"):
            dims.append(kind._length_)
            kind = kind._type_
        out.append((field, kind, tuple(dims)))
    return out


@pytest.mark.parametrize(
    ("source", "name", "mirror"),
    [
        ("physics.h", "bk_sim", layout.Sim),
        ("physics.h", "bk_rng", layout.Rng),
        ("physics.h", "bk_reading", layout.Reading),
        ("lockstep_loop.c", "bk_lockstep", lockstep_stepper._Lockstep),
    ],
)
def test_each_ctypes_mirror_is_its_c_struct(
    source: str, name: str, mirror: type[ctypes.Structure]
) -> None:
    c_fields = [
        (field, C_TYPES[c_type], dims) for field, c_type, dims in c_struct(SOURCES / source, name)
    ]
    assert ctypes_fields(mirror) == c_fields


def test_the_check_can_tell() -> None:
    header = c_struct(SOURCES / "physics.h", "bk_sim")
    assert ("p", "double", (3,)) in header and ("rotors", "double", (4, 3)) in header
    assert ("reading", "bk_reading", ()) in header
    moved = [*layout.Sim._fields_[1:], layout.Sim._fields_[0]]

    class Moved(ctypes.Structure):
        _fields_ = moved

    assert ctypes_fields(Moved) != ctypes_fields(layout.Sim)


def test_the_lockstep_statuses_are_the_loops() -> None:
    text = (SOURCES / "lockstep_loop.c").read_text()
    statuses = dict(re.findall(r"BK_LOCKSTEP_(\w+) = (\d+),", text))
    assert len(statuses) == 7
    for name, value in statuses.items():
        assert getattr(lockstep_stepper, name) == int(value), name


def _defines(path: Path) -> dict[str, float]:
    return {
        name: float(value)
        for name, value in re.findall(
            r"^#define (\w+) (-?[\d.]+(?:e-?\d+)?)$", path.read_text(), re.M
        )
    }


def test_the_constants_both_sides_use_are_the_same() -> None:
    defines = _defines(SOURCES / "physics.c")
    assert defines["MAX_STEP_S"] == multirotor.MAX_STEP_S
    assert defines["SEA_LEVEL_PRESSURE_PA"] == constants.SEA_LEVEL_PRESSURE_PA
    assert defines["LAPSE_OVER_T0_PER_M"] == atmosphere._LAPSE_OVER_T0_PER_M
    assert defines["PRESSURE_EXPONENT"] == atmosphere._PRESSURE_EXPONENT
    assert defines["MIN_ALTITUDE_M"] == atmosphere.MIN_ALTITUDE_M
    assert defines["MAX_ALTITUDE_M"] == atmosphere.MAX_ALTITUDE_M


def test_the_library_and_the_mirrors_agree_in_size() -> None:
    from bfsitl.kernel.compiler import load_kernel

    library = load_kernel()
    assert library.bk_sim_size() == ctypes.sizeof(layout.Sim)
    assert library.bk_lockstep_size() == ctypes.sizeof(lockstep_stepper._Lockstep)


def _vehicle_bytes(params: QuadParams) -> bytes:
    """The C structure's vehicle block (mass_kg up to the step's cache) as the face wrote it."""
    sim = Simulator(params)
    start, end = layout.Sim.mass_kg.offset, layout.Sim.dt.offset
    return bytes(memoryview(sim._sim).cast("B")[start:end])


def _perturbed(value: object) -> object:
    if isinstance(value, bool):
        return not value
    if isinstance(value, float):
        return value * 1.01 if value else 0.01
    if isinstance(value, tuple):
        return (_perturbed(value[0]), *value[1:])
    raise TypeError(value)


#: What the model leaves out on purpose: the name.  (Also the rotor hubs' height: thrust is
#: along body z and no in-plane rotor force is modelled, so only x and y of a rotor's position
#: are perturbed below; physics.c, bk_init.)
NOT_IN_THE_MODEL = {"name"}


@pytest.mark.parametrize(
    "field", [f.name for f in dataclasses.fields(QuadParams) if f.name not in NOT_IN_THE_MODEL]
)
def test_every_vehicle_parameter_reaches_the_c_model(field: str) -> None:
    # A parameter added to QuadParams but not written into bk_sim would change nothing.
    value = getattr(IRIS, field)
    if field == "rotor_positions_frd_m":
        x, y, z = value[0]
        changed: object = ((x * 1.01, y, z), *value[1:])
    else:
        changed = _perturbed(value)
    assert _vehicle_bytes(dataclasses.replace(IRIS, **{field: changed})) != _vehicle_bytes(IRIS)
