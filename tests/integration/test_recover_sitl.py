"""bfsitl/Recover-v0 on the real 4.6.0 SITL (a --gps --lockstep build): the FC sees each throw
as the physics made it, ANGLE mode rights the quad by itself while rate mode holds the tumble's
attitude (a throw that never reached the firmware, or a wrong mode, fails), and the same seed
throws and flies the same, bit for bit."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("gymnasium")

from bfsitl.backend.options import World  # noqa: E402
from bfsitl.gym.baseline import hover_stick  # noqa: E402
from bfsitl.gym.env import RecoverEnv  # noqa: E402
from bfsitl.gym.throws import Throw  # noqa: E402
from bfsitl.mission.session import SitlLaunch  # noqa: E402

pytestmark = pytest.mark.sitl

#: Tumbling hard: tilted 90..180 degrees only matters here, so the range starts wide.
THROW = Throw(height_m=10.0, max_tilt_deg=180.0, max_speed_m_s=2.0, max_rate_deg_s=180.0)
CENTRED = np.array([0.0, 0.0, hover_stick(World().quad), 0.0], dtype=np.float32)


def throws(env: RecoverEnv, seed: int, count: int) -> list[dict[str, Any]]:
    """``count`` throws from ``seed``, sticks centred at the hover throttle; per throw: the
    first step's FC and true attitude, the whole flight's observations, how it ended."""
    flights = []
    for number in range(count):
        observation, info = env.reset(seed=seed if number == 0 else None)
        thrown, observations = info["throw"], [observation]
        snapshot = env.snapshot
        assert snapshot is not None
        first = (snapshot.fc, snapshot.truth)
        tilts = []
        while True:
            observation, _reward, terminated, truncated, info = env.step(CENTRED)
            observations.append(observation)
            tilts.append(info["truth"]["tilt_deg"])
            if terminated or truncated:
                break
        flights.append(
            {
                "throw": thrown,
                "first": first,
                "tilts": tilts,
                "observations": np.array(observations),
                "recovered": info["recovered"] and info["ended_because"] is None,
                "ended_because": info["ended_because"],
                "height_lost_m": info["height_lost_m"],
            }
        )
    return flights


def test_angle_mode_rights_every_throw_and_rate_mode_holds_the_tumble(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    sitl = SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "angle")
    angle = RecoverEnv(sitl=sitl, throw=THROW, mode="angle")
    try:
        angled = throws(angle, seed=3, count=6)
    finally:
        angle.close()
    acro = RecoverEnv(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "acro"),
        throw=THROW,
        mode="acro",
    )
    try:
        rated = throws(acro, seed=3, count=6)
    finally:
        acro.close()
    for flight in angled + rated:
        fc, truth = flight["first"]
        # The FC reads the throw's attitude as thrown (4.6.0 takes the quaternion as it is):
        # the tilt from its roll and pitch is the truth's, upside down included.
        assert truth.tilt_deg == pytest.approx(flight["throw"]["tilt_deg"], abs=3.0)
        assert fc_tilt_deg(fc.roll_rad, fc.pitch_rad) == pytest.approx(truth.tilt_deg, abs=3.0)
        assert fc.armed
    # The same seed threw the same way in both modes.
    assert [f["throw"] for f in angled] == [f["throw"] for f in rated]
    assert any(f["throw"]["tilt_deg"] > 120.0 for f in angled)  # upside down among them
    # ANGLE, sticks centred: the FC levels the quad and the hover throttle stops the fall.
    assert all(f["recovered"] for f in angled), [f["ended_because"] for f in angled]
    assert all(0.0 <= f["height_lost_m"] < 4.0 for f in angled)
    worst = max(angled, key=lambda f: f["throw"]["tilt_deg"])
    assert worst["height_lost_m"] > 0.3  # upside down with the rotors stopped, it falls first
    # Rate mode, sticks centred: the FC holds the rates at zero, so a quad thrown tilted
    # stays tilted and comes down; none counts as recovered once tilted past 45 degrees.
    steep = [f for f in rated if f["throw"]["tilt_deg"] > 45.0]
    assert steep and not any(f["recovered"] for f in steep)
    for flight in steep:
        assert min(flight["tilts"]) > 20.0  # never came near level


def fc_tilt_deg(roll_rad: float, pitch_rad: float) -> float:
    """The angle between the body's z and the vertical, from roll and pitch (ZYX)."""
    return math.degrees(math.acos(max(-1.0, min(1.0, math.cos(roll_rad) * math.cos(pitch_rad)))))


def test_the_same_seed_throws_and_flies_the_same_bit_for_bit(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    runs = []
    for name in ("a", "b"):
        env = RecoverEnv(
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / name),
            throw=THROW,
        )
        try:
            runs.append(throws(env, seed=11, count=3))
        finally:
            env.close()
    first, again = runs
    assert [f["throw"] for f in first] == [f["throw"] for f in again]
    for one, other in zip(first, again, strict=True):
        assert one["observations"].tobytes() == other["observations"].tobytes()


def test_a_small_quad_takes_off_in_still_air_and_is_thrown_into_the_wind(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    from bfsitl.physics.wind import Wind
    from bfsitl.vehicles import load_vehicle

    quad = load_vehicle("5inch-freestyle")
    wind = Wind.from_direction(3.0, 0.0, 1.5)  # from the north, gusting
    drift = {}
    for name, world in (("calm", World(quad=quad)), ("windy", World(quad=quad, wind=wind))):
        env = RecoverEnv(
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / name),
            throw=Throw(max_tilt_deg=30.0, max_speed_m_s=0.0, max_rate_deg_s=0.0),
            mode="angle",
            world=world,
        )
        try:
            _observation, info = env.reset(seed=5)  # a cold reset: the autopilot takes off
            assert env._vehicle is not None
            assert env._vehicle.disturbances.wind == world.wind  # back on for the throw
            hover = np.array([0.0, 0.0, hover_stick(quad), 0.0], dtype=np.float32)
            for _ in range(100):  # 1 s, sticks centred
                _observation, _reward, terminated, _truncated, info = env.step(hover)
                assert not terminated, info["ended_because"]
            drift[name] = info["truth"]["v_north_m_s"]
        finally:
            env.close()
    # The wind from the north pushes the released quad south; still air does not.
    assert drift["windy"] < drift["calm"] - 0.5, drift


def test_a_wind_drawn_per_episode_blows_the_quad_its_way_and_repeats_for_a_seed(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    from bfsitl.gym.random_wind import RandomWind

    runs = []
    for name in ("a", "b"):
        env = RecoverEnv(
            sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / name),
            throw=Throw(max_tilt_deg=10.0, max_speed_m_s=0.0, max_rate_deg_s=0.0),
            mode="angle",
            random_wind=RandomWind(max_speed_m_s=4.0, max_gust_m_s=0.5),
        )
        episodes = []
        try:
            for number in range(4):  # a cold reset, then warm ones
                env.reset(seed=8 if number == 0 else None)
                assert env._vehicle is not None
                wind = env._vehicle.disturbances.wind
                assert wind is not None
                for _ in range(80):  # 0.8 s, sticks centred: the quad goes with the wind
                    _observation, _reward, _terminated, _truncated, info = env.step(CENTRED)
                truth = info["truth"]
                episodes.append((wind, (truth["v_north_m_s"], truth["v_east_m_s"])))
        finally:
            env.close()
        runs.append(episodes)
    first, again = runs
    assert [wind for wind, _v in first] == [wind for wind, _v in again]
    assert len({wind for wind, _v in first}) == 4  # a new wind each episode
    assert any(math.hypot(*wind.velocity_ned_m_s[:2]) > 1.0 for wind, _v in first)
    for wind, (v_north, v_east) in first:
        w_north, w_east, _down = wind.velocity_ned_m_s
        if math.hypot(w_north, w_east) > 1.0:
            # Blown the wind's way, not another (a sign or axis swapped fails).
            assert v_north * w_north + v_east * w_east > 0.0, (wind, v_north, v_east)
