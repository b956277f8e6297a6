"""Vehicle profiles: the shipped ones read, round-trip and say where their figures come from;
a profile file's bad fields are one line each; the physics made of a profile is the quad the
pilot described (full-throttle thrust and speed, motor lag, hover, the motor order)."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest

from bfsitl.errors import SimInputError, VehicleProfileError
from bfsitl.physics import IRIS, Simulator
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.vehicles import (
    hover_throttle_us,
    load_vehicle,
    profile_text,
    quad_params,
    read_profile,
    shipped_profiles,
    stick_per_acceleration_us,
    vehicle_names,
    write_profile,
)

SHIPPED = sorted(shipped_profiles())


def test_the_shipped_vehicles_are_iris_and_three_sizes() -> None:
    assert vehicle_names() == ("iris", "3inch-cinewhoop", "5inch-freestyle", "7inch-longrange")
    assert load_vehicle("iris") is IRIS  # the default, unchanged to the bit


@pytest.mark.parametrize("name", SHIPPED)
def test_a_shipped_profile_says_where_every_figure_comes_from(name: str) -> None:
    spec = shipped_profiles()[name]
    figures = {f.name for f in dataclasses.fields(spec)} - {"name", "description", "sources"}
    assert set(spec.sources) == figures
    assert all(len(text) > 10 for text in spec.sources.values())


@pytest.mark.parametrize("name", SHIPPED)
def test_a_profile_written_and_read_back_is_the_same(name: str, tmp_path: Path) -> None:
    spec = shipped_profiles()[name]
    path = tmp_path / "mine.toml"
    write_profile(spec, path)
    again = read_profile(path)
    assert again == spec
    assert quad_params(again) == load_vehicle(path) == load_vehicle(name)
    assert profile_text(again) == path.read_text()


@pytest.mark.parametrize("name", SHIPPED)
def test_the_physics_gives_the_thrust_table_s_top_row_and_the_motor_lag(name: str) -> None:
    spec = shipped_profiles()[name]
    quad = quad_params(spec)
    top_rad_s = quad.steady_rotor_speed_rad_s(1.0)
    assert top_rad_s == pytest.approx(spec.max_rpm * math.tau / 60.0, rel=1e-9)
    thrust_g = quad.thrust_coefficient_n_per_rad2_s2 * top_rad_s**2 / STANDARD_GRAVITY_M_S2
    assert thrust_g * 1000.0 == pytest.approx(spec.max_thrust_g, rel=1e-9)
    assert quad.motor_time_constant_s * 1000.0 == pytest.approx(
        spec.motor_time_constant_ms, rel=1e-9
    )
    assert quad.mass_kg * 1000.0 == pytest.approx(spec.mass_g)
    # The motor square of the wheelbase: each hub half the diagonal from the centre.
    for x, y, _z in quad.rotor_positions_frd_m:
        assert math.hypot(x, y) * 2000.0 == pytest.approx(spec.wheelbase_mm)


@pytest.mark.parametrize("name", SHIPPED)
def test_the_simulated_quad_hovers_lags_and_rolls_the_right_way(name: str) -> None:
    quad = load_vehicle(name)
    sim = Simulator(quad)
    hover_rad_s = quad.hover_rotor_speed_rad_s
    sim.reset((0.0, 0.0, -20.0), motor_speeds_rad_s=(hover_rad_s,) * 4)
    for _ in range(1000):
        sim.step((quad.hover_command,) * 4, 0.001)
    assert abs(sim.state.velocity_ned_m_s[2]) < 1e-3  # the hover command holds it
    # A step of the command: the rotor speed is 63 % of the way after about the lag.
    sim.reset((0.0, 0.0, -20.0), motor_speeds_rad_s=(hover_rad_s,) * 4)
    command = quad.hover_command * 1.02
    target = quad.steady_rotor_speed_rad_s(command)
    lag_steps = round(quad.motor_time_constant_s * 1000.0)
    for _ in range(lag_steps):
        sim.step((command,) * 4, 0.001)
    share = (sim.state.motor_speeds_rad_s[0] - hover_rad_s) / (target - hover_rad_s)
    assert share == pytest.approx(1.0 - math.exp(-1.0), abs=0.05)
    # More thrust on the right (M1 rear right, M2 front right) rolls it left; more at the
    # front (M2, M4) pitches the nose up; M1 and M4 spin clockwise, so more of them yaws left.
    for commands, axis, sign in (
        ((1.05, 1.05, 0.95, 0.95), 0, -1.0),
        ((0.95, 1.05, 0.95, 1.05), 1, +1.0),
        ((1.05, 0.95, 0.95, 1.05), 2, -1.0),
    ):
        sim.reset((0.0, 0.0, -20.0), motor_speeds_rad_s=(hover_rad_s,) * 4)
        for _ in range(60):
            sim.step(tuple(c * quad.hover_command for c in commands), 0.001)  # type: ignore[arg-type]
        rates = sim.state.angular_velocity_frd_rad_s
        assert rates[axis] * sign > 0.05, (commands, rates)
        others = [abs(r) for i, r in enumerate(rates) if i != axis]
        assert max(others) < 0.1 * abs(rates[axis])


def test_a_lighter_quad_hovers_lower_on_the_stick_and_needs_less_of_it() -> None:
    assert hover_throttle_us(IRIS) == 1545.0  # measured on IRIS
    assert stick_per_acceleration_us(IRIS) == pytest.approx(27.8, abs=0.05)
    five = load_vehicle("5inch-freestyle")
    # Thrust-to-weight 12: the hover is near a quarter of the stick, and the stick moves it
    # more per microsecond.
    assert 1150 < hover_throttle_us(five) < 1300
    assert stick_per_acceleration_us(five) < 0.6 * stick_per_acceleration_us(IRIS)


def _profile(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "quad.toml"
    path.write_text(text)
    return path


GOOD = profile_text(shipped_profiles()["5inch-freestyle"])


@pytest.mark.parametrize(
    ("change", "lines"),
    [
        (("mass_g = 650.0", "mass_g = -650.0"), ["mass_g: must be > 0, got -650.0"]),
        (
            ("mass_g = 650.0", 'mass_g = "heavy"'),
            ["mass_g: must be a finite number, got 'heavy'"],
        ),
        (
            ("inertia_kg_m2 = [", "inertia_kg_m2 = [0.1, "),
            ["inertia_kg_m2: must be three numbers [roll, pitch, yaw]"],
        ),
        (
            ("max_rpm = 31401.0\n", "max_rpm = 31401.0\nmax_rmp = 3\n"),
            ["max_rmp: unknown field; known: name, description"],
        ),
        (("wheelbase_mm = 228.0\n", ""), ["wheelbase_mm: missing"]),
        (
            ("drag_linear_n_s_per_m = [\n    0.45", "drag_linear_n_s_per_m = [\n    -0.45"),
            ["drag_linear_n_s_per_m: each must be >= 0"],
        ),
    ],
)
def test_a_bad_field_is_one_line_naming_it(
    tmp_path: Path, change: tuple[str, str], lines: list[str]
) -> None:
    assert change[0] in GOOD
    path = _profile(tmp_path, GOOD.replace(change[0], change[1], 1))
    with pytest.raises(VehicleProfileError) as caught:
        read_profile(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: 1 bad field:\n")
    assert [line.strip() for line in message.splitlines()[1:]][0].startswith(lines[0])


def test_every_bad_field_is_said_at_once(tmp_path: Path) -> None:
    text = GOOD.replace("mass_g = 650.0", "mass_g = 0").replace("max_rpm = 31401.0", "max_rpm = -1")
    with pytest.raises(VehicleProfileError, match=r"2 bad fields:\n  mass_g: .*\n  max_rpm: "):
        read_profile(_profile(tmp_path, text))


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("mass_g = 1", "no [vehicle] table"),
        ("[vehicle\n", "is not valid TOML"),
        (GOOD.replace("max_thrust_g = 1990.4", "max_thrust_g = 150.0"), "thrust-to-weight"),
    ],
)
def test_a_profile_that_cannot_be_flown_says_why(tmp_path: Path, text: str, says: str) -> None:
    with pytest.raises(SimInputError, match=re_escape(says)):
        read_profile(_profile(tmp_path, text))


def re_escape(text: str) -> str:
    import re

    return re.escape(text)


def test_an_unknown_vehicle_lists_the_names(tmp_path: Path) -> None:
    with pytest.raises(VehicleProfileError, match="unknown vehicle 'x500': give one of iris, "):
        load_vehicle("x500")
    with pytest.raises(VehicleProfileError, match="missing.toml does not exist"):
        load_vehicle(tmp_path / "missing.toml")
