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
                "recovered": info["recovered_step"] is not None and info["ended_because"] is None,
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
