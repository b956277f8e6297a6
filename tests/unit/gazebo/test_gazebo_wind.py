"""Gazebo's wind: the world bfsitl writes for a windy flight, and changing it while it flies."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from support.fake_processes import FakeGazebo

import bfsitl.gazebo
from bfsitl.backend.gazebo import GazeboBackend
from bfsitl.errors import DisturbanceUnavailableError, GazeboError
from bfsitl.gazebo.wind import GazeboWind, wind_enu_m_s, wind_message
from bfsitl.gazebo.world import (
    WIND_FORCE_PER_KG_PER_M_S,
    WorldChanges,
    world_name,
    world_path,
    write_session_world,
)
from bfsitl.physics.params import IRIS
from bfsitl.physics.wind import Wind

#: 3 m/s from the north: the air moves south.
NORTHERLY = Wind(velocity_ned_m_s=(-3.0, 0.0, 0.0))


def test_a_windy_world_loads_wind_effects_and_every_link_of_the_quad_feels_it(
    tmp_path: Path,
) -> None:
    written = write_session_world(
        world_path(), tmp_path, WorldChanges(9102, 9103, wind_enu_m_s(NORTHERLY))
    )
    world = ET.parse(written).getroot().find("world")
    assert world is not None
    effects = world.find("plugin[@filename='gz-sim-wind-effects-system']")
    assert effects is not None
    factor = float(effects.findtext("force_approximation_scaling_factor") or "nan")
    # The embedded IRIS's horizontal linear drag, per kilogram of the quad.
    assert factor * IRIS.mass_kg == pytest.approx(IRIS.drag_linear_n_s_per_m[0], rel=1e-4)
    assert factor == pytest.approx(WIND_FORCE_PER_KG_PER_M_S, rel=1e-4)
    rises = [float(e.text or "nan") for e in effects.iter("time_for_rise")]
    assert rises == [0.1, 0.1, 0.1]  # magnitude, direction, vertical: a new wind blows now
    # ENU: the air moves south, -y.
    velocity = [float(v) for v in (world.findtext("wind/linear_velocity") or "").split()]
    assert velocity == pytest.approx([0.0, -3.0, 0.0])
    links = list(world.iter("link"))
    quad_links = [link for link in links if link.findtext("enable_wind") == "true"]
    assert len(quad_links) == 6  # base, IMU and four rotors; the ground feels nothing
    assert all(link.get("name") != "link" for link in quad_links)


def test_a_still_world_is_left_without_wind(tmp_path: Path) -> None:
    written = write_session_world(world_path(), tmp_path, WorldChanges(9102, 9103))
    text = written.read_text()
    assert "wind-effects" not in text and "enable_wind" not in text
    assert world_name(written) == "empty_betaflight_world"


def _wind(started_with: Wind | None, code: int | None = 0) -> tuple[GazeboWind, list[list[str]]]:
    calls: list[list[str]] = []

    def spawn(argv: list[str], log: Path) -> FakeGazebo:
        calls.append(argv)
        return FakeGazebo(code, exit_after=None)

    return GazeboWind(spawn, Path("/opt/gz"), "w", Path("/tmp"), started_with), calls  # type: ignore[arg-type]


def test_the_wind_is_published_on_the_worlds_topic() -> None:
    wind, calls = _wind(Wind())
    wind.set_wind(NORTHERLY)
    assert wind.wind == NORTHERLY
    assert calls == [
        [
            "/opt/gz",
            "topic",
            "-t",
            "/world/w/wind",
            "-m",
            "gz.msgs.Wind",
            "-p",
            "linear_velocity: {x: 0.000000, y: -3.000000, z: -0.000000}, enable_wind: true",
        ]
    ]
    wind.set_wind(None)
    assert "x: 0.000000, y: 0.000000" in calls[-1][-1] and wind.wind is None


def test_what_gazebo_cannot_do_is_refused_in_one_line() -> None:
    started_still, calls = _wind(None)
    with pytest.raises(DisturbanceUnavailableError, match="started without one"):
        started_still.set_wind(NORTHERLY)
    windy, calls = _wind(Wind())
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        windy.set_wind(Wind(velocity_ned_m_s=(1.0, 0.0, 0.0), gust_std_m_s=1.0))
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        wind_enu_m_s(Wind(gust_std_m_s=0.5))
    assert calls == []
    failing, _ = _wind(Wind(), code=None)
    with pytest.raises(GazeboError, match="timeout"):
        failing.set_wind(NORTHERLY)
    assert wind_message(None).startswith("linear_velocity: {x: 0.000000")


def test_the_backends_disturbance_surface_reaches_gazebos_wind(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(bfsitl.gazebo, "check_gazebo", lambda plugin_dir: object())
    backend = GazeboBackend(None, progress=lambda line: None, wind=Wind())
    with pytest.raises(DisturbanceUnavailableError, match="not started"):
        backend.disturbances.set_wind(NORTHERLY)
    backend.gazebo_wind, calls = _wind(Wind())
    backend.disturbances.set_wind(NORTHERLY)
    assert backend.disturbances.wind == NORTHERLY and len(calls) == 1
    with pytest.raises(DisturbanceUnavailableError, match="Gazebo's physics"):
        backend.disturbances.set_motor_thrust(1, 0.5)
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        GazeboBackend(None, progress=lambda line: None, wind=Wind(gust_std_m_s=1.0))
