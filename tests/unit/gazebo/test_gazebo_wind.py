"""Gazebo's wind: the world bfsitl writes for a windy flight, and changing it while it flies."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from support.fake_processes import FakeGazebo

import bfsitl.gazebo
from bfsitl.backend.gazebo import GazeboBackend
from bfsitl.errors import DisturbanceUnavailableError, GazeboError
from bfsitl.gazebo.wind import GazeboWind, parse_wind_reply, wind_enu_m_s, wind_message
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


class FakeWindEffects:
    """``gz topic`` and ``gz service`` against a WindEffects that loses the first ``lost``
    messages published to it and answers its wind_info service as ``gz service`` prints."""

    def __init__(self, started_enu: str = "", lost: int = 0, code: int | None = 0) -> None:
        self.blowing = started_enu  # the text inside linear_velocity { }
        self.lost = lost
        self.code = code
        self.published: list[list[str]] = []
        self.asked = 0

    def __call__(self, argv: list[str], log: Path) -> FakeGazebo:
        if argv[1] == "topic":
            self.published.append(argv)
            if self.lost:
                self.lost -= 1
            else:
                velocity = argv[-1].split("{")[1].split("}")[0]
                self.blowing = " ".join(
                    f"{axis}: {float(value)}"
                    for axis, value in (part.split(":") for part in velocity.split(","))
                    if float(value) != 0.0
                )
        else:
            self.asked += 1
            log.write_text(f"linear_velocity {{\n  {self.blowing}\n}}\nenable_wind: true\n\n")
        return FakeGazebo(self.code, exit_after=None)


def _wind(
    log_dir: Path, started_with: Wind | None, code: int | None = 0, lost: int = 0
) -> tuple[GazeboWind, list[list[str]]]:
    gazebo = FakeWindEffects(lost=lost, code=code)
    return GazeboWind(gazebo, Path("/opt/gz"), "w", log_dir, started_with), gazebo.published  # type: ignore[arg-type]


def test_the_wind_is_published_on_the_worlds_topic(tmp_path: Path) -> None:
    wind, calls = _wind(tmp_path, Wind())
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


def test_what_gazebo_cannot_do_is_refused_in_one_line(tmp_path: Path) -> None:
    started_still, calls = _wind(tmp_path, None)
    with pytest.raises(DisturbanceUnavailableError, match="started without one"):
        started_still.set_wind(NORTHERLY)
    windy, calls = _wind(tmp_path, Wind())
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        windy.set_wind(Wind(velocity_ned_m_s=(1.0, 0.0, 0.0), gust_std_m_s=1.0))
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        wind_enu_m_s(Wind(gust_std_m_s=0.5))
    assert calls == []
    failing, _ = _wind(tmp_path, Wind(), code=None)
    with pytest.raises(GazeboError, match="timeout"):
        failing.set_wind(NORTHERLY)
    assert wind_message(None).startswith("linear_velocity: {x: 0.000000")


def test_a_wind_gazebo_missed_is_sent_again_until_it_blows(tmp_path: Path) -> None:
    """``gz topic -p`` publishes once; WindEffects missed it twice in a row on a busy
    machine.  The wind it reports is read back and the message sent again."""
    wind, published = _wind(tmp_path, Wind(), lost=2)
    wind.set_wind(NORTHERLY)
    assert len(published) == 3 and wind.wind == NORTHERLY
    never, published = _wind(tmp_path, Wind(), lost=99)
    with pytest.raises(GazeboError, match=r"did not take the wind .* in 4 tries.*reports \(0.0"):
        never.set_wind(NORTHERLY)
    assert len(published) == 4 and never.wind == Wind()


def test_gazebo_s_wind_reply_is_read_as_it_prints_it() -> None:
    assert parse_wind_reply("linear_velocity {\n  x: 3\n}\nenable_wind: true\n") == (3, 0, 0)
    assert parse_wind_reply("linear_velocity {\n  y: -2.5\n  z: 1e-05\n}\n") == (0, -2.5, 1e-5)
    assert parse_wind_reply("linear_velocity {\n}\nenable_wind: true\n") == (0, 0, 0)
    assert parse_wind_reply("enable_wind: true\n") == (0, 0, 0)
    with pytest.raises(GazeboError, match="no wind"):
        parse_wind_reply("Service call timed out\n")


def test_the_backends_disturbance_surface_reaches_gazebos_wind(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setattr(bfsitl.gazebo, "check_gazebo", lambda plugin_dir: object())
    backend = GazeboBackend(None, progress=lambda line: None, wind=Wind())
    with pytest.raises(DisturbanceUnavailableError, match="not started"):
        backend.disturbances.set_wind(NORTHERLY)
    backend.gazebo_wind, calls = _wind(tmp_path, Wind())
    backend.disturbances.set_wind(NORTHERLY)
    assert backend.disturbances.wind == NORTHERLY and len(calls) == 1
    with pytest.raises(DisturbanceUnavailableError, match="Gazebo's physics"):
        backend.disturbances.set_motor_thrust(1, 0.5)
    with pytest.raises(DisturbanceUnavailableError, match="gusts"):
        GazeboBackend(None, progress=lambda line: None, wind=Wind(gust_std_m_s=1.0))
