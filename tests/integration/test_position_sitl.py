"""Horizontal position control from the FC's own GPS, on the real firmware in lockstep:
4.6.0 built with --gps and master (which always has GPS).

What is checked against the simulated truth: a leg north and a leg east end where they should
(a swapped axis or a wrong sign ends elsewhere, not just late); the FC's GPS agrees with the
truth; and in 3 m/s wind with gusts the vehicle flies back to its start and holds there.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from bfsitl import FlightSession, Mission, SessionConfig, make_controller
from bfsitl.errors import MissionError
from bfsitl.mission.session import FLY_PROFILE, with_fast_serial
from bfsitl.sim.params import Wind

pytestmark = pytest.mark.sitl


@pytest.fixture(params=["4.6.0-gps", "master"])
def gps_lockstep_firmware(request: pytest.FixtureRequest) -> Path:
    name = ("lockstep_gps_46_firmware" if request.param == "4.6.0-gps"
            else "lockstep_master_firmware")
    return request.getfixturevalue(name)


def position_session(firmware: Path, tmp_path: Path, wind: Wind | None = None,
                     seed: int = 1) -> FlightSession:
    return FlightSession(SessionConfig(firmware=firmware, workdir=tmp_path / "run", seed=seed,
                                       wind=wind, profile=with_fast_serial(FLY_PROFILE)))


def test_legs_north_and_east_end_where_they_should(gps_lockstep_firmware, tmp_path):
    with position_session(gps_lockstep_firmware, tmp_path) as session:
        mission = Mission(session, make_controller("fused"), rate_hz=100)
        mission.arm()
        mission.takeoff(2.0)
        ends = []
        for north, east in ((6.0, 0.0), (6.0, 6.0)):
            took_s = mission.fly_to(north, east)
            row = mission.rows[-1]
            ends.append((row.sim_north_m, row.sim_east_m, row.fc_north_m, row.fc_east_m))
            assert took_s < 12.0, f"{took_s:.1f} s for a 6 m leg"
        mission.land()
    for (north, east), (sim_n, sim_e, fc_n, fc_e) in zip(((6.0, 0.0), (6.0, 6.0)), ends,
                                                           strict=True):
        assert math.hypot(sim_n - north, sim_e - east) < 0.4, (sim_n, sim_e)
        assert math.hypot(fc_n - sim_n, fc_e - sim_e) < 0.3  # the FC's GPS is the truth's
    assert max(abs(r.sim_alt_m - 2.0) for r in mission.rows if r.phase == "goto") < 0.5


def test_in_wind_it_flies_back_and_holds_its_start(gps_lockstep_firmware, tmp_path):
    wind = Wind.from_direction(3.0, 30.0, 1.5)
    # Seed 2's gusts sank the vehicle to the ground when the height was estimated from body z
    # alone: a test that can fail.
    with position_session(gps_lockstep_firmware, tmp_path, wind, seed=2) as session:
        mission = Mission(session, make_controller("fused"), rate_hz=100)
        mission.arm()
        mission.takeoff(2.0)  # altitude only: the wind carries it off meanwhile
        drifted_m = math.hypot(mission.rows[-1].sim_north_m, mission.rows[-1].sim_east_m)
        mission.fly_to(0.0, 0.0, timeout_s=40.0)
        held = len(mission.rows)
        mission.hold_position(20.0, 0.0, 0.0)
        rows = mission.rows[held:]
        mission.land()
    errors = [math.hypot(r.sim_north_m, r.sim_east_m) for r in rows]
    rms_m = math.sqrt(sum(e * e for e in errors) / len(errors))
    assert drifted_m > 1.0  # the wind did push it (the test can tell holding from drifting)
    assert rms_m < 0.6 and max(errors) < 1.2, (rms_m, max(errors))
    # Tilted against the wind, the thrust and the rotors' drag share the vertical: the height
    # holds only if the FC's whole accelerometer is projected (body z alone lost metres).
    assert max(abs(r.sim_alt_m - 2.0) for r in rows) < 0.4


def test_a_build_without_gps_is_told_what_to_fly(lockstep_46_firmware, tmp_path):
    with position_session(lockstep_46_firmware, tmp_path) as session:
        mission = Mission(session, make_controller("fused"))
        mission.arm()
        mission.takeoff(1.0)
        with pytest.raises(MissionError, match="firmware build --gps"):
            mission.fly_to(1.0, 0.0)
        mission.land()
