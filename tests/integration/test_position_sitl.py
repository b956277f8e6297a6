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

from bfsitl import (
    FcSetup,
    FlightLoop,
    FlightSession,
    SessionConfig,
    SitlLaunch,
    World,
    make_controller,
)
from bfsitl.errors import MissionError
from bfsitl.mission.session import FLY_PROFILE, with_fast_serial
from bfsitl.physics.wind import Wind

pytestmark = pytest.mark.sitl


@pytest.fixture(params=["4.6.0-gps", "master"])
def gps_lockstep_firmware(request: pytest.FixtureRequest) -> Path:
    name = (
        "lockstep_gps_46_firmware" if request.param == "4.6.0-gps" else "lockstep_master_firmware"
    )
    return request.getfixturevalue(name)


def position_session(
    firmware: Path, tmp_path: Path, wind: Wind | None = None, seed: int = 1
) -> FlightSession:
    return FlightSession(
        SessionConfig(
            sitl=SitlLaunch(firmware=firmware, workdir=tmp_path / "run"),
            world=World(seed=seed, wind=wind),
            fc=FcSetup(profile=with_fast_serial(FLY_PROFILE)),
        )
    )


def test_legs_north_and_east_end_where_they_should(gps_lockstep_firmware, tmp_path):
    with position_session(gps_lockstep_firmware, tmp_path) as session:
        loop = FlightLoop(session, make_controller("fused"), rate_hz=100)
        loop.arm()
        loop.takeoff(2.0)
        ends = []
        for north, east in ((6.0, 0.0), (6.0, 6.0)):
            took_s = loop.fly_to(north, east)
            row = loop.rows[-1]
            ends.append((row.sim_north_m, row.sim_east_m, row.fc_north_m, row.fc_east_m))
            assert took_s < 12.0, f"{took_s:.1f} s for a 6 m leg"
        loop.land()
    for (north, east), (sim_n, sim_e, fc_n, fc_e) in zip(
        ((6.0, 0.0), (6.0, 6.0)), ends, strict=True
    ):
        assert math.hypot(sim_n - north, sim_e - east) < 0.4, (sim_n, sim_e)
        assert math.hypot(fc_n - sim_n, fc_e - sim_e) < 0.3  # the FC's GPS is the truth's
    assert max(abs(r.sim_alt_m - 2.0) for r in loop.rows if r.phase == "goto") < 0.5


def test_in_wind_it_flies_back_and_holds_its_start(gps_lockstep_firmware, tmp_path):
    wind = Wind.from_direction(3.0, 30.0, 1.5)
    # Seed 2's gusts sank the vehicle to the ground when the height was estimated from body z
    # alone: a test that can fail.
    with position_session(gps_lockstep_firmware, tmp_path, wind, seed=2) as session:
        loop = FlightLoop(session, make_controller("fused"), rate_hz=100)
        loop.arm()
        loop.takeoff(2.0)  # altitude only: the wind carries it off meanwhile
        drifted_m = math.hypot(loop.rows[-1].sim_north_m, loop.rows[-1].sim_east_m)
        loop.fly_to(0.0, 0.0, timeout_s=40.0)
        held = len(loop.rows)
        loop.hold_position(20.0, 0.0, 0.0)
        rows = loop.rows[held:]
        loop.land()
    errors = [math.hypot(r.sim_north_m, r.sim_east_m) for r in rows]
    rms_m = math.sqrt(sum(e * e for e in errors) / len(errors))
    assert drifted_m > 1.0  # the wind did push it (the test can tell holding from drifting)
    assert rms_m < 0.6 and max(errors) < 1.2, (rms_m, max(errors))
    # Tilted against the wind, the thrust and the rotors' drag share the vertical: the height
    # holds only if the FC's whole accelerometer is projected (body z alone lost metres).
    assert max(abs(r.sim_alt_m - 2.0) for r in rows) < 0.4


def test_a_build_without_gps_is_told_what_to_fly(lockstep_46_firmware, tmp_path):
    with position_session(lockstep_46_firmware, tmp_path) as session:
        loop = FlightLoop(session, make_controller("fused"))
        loop.arm()
        loop.takeoff(1.0)
        with pytest.raises(MissionError, match="firmware build --gps"):
            loop.fly_to(1.0, 0.0)
        loop.land()


SQUARE_TOML = """
takeoff_alt_m = 2.0
speed_m_s = 2.0
land = true

[[waypoint]]
north_m = 8.0
east_m = 0.0
alt_m = 2.0

[[waypoint]]
north_m = 8.0
east_m = 8.0
alt_m = 2.5

[[waypoint]]
north_m = 0.0
east_m = 8.0
alt_m = 2.0

[[waypoint]]
north_m = 0.0
east_m = 0.0
alt_m = 2.0
"""


def test_a_square_mission_file_flies_in_wind_and_lands_at_its_start(
    gps_lockstep_firmware, tmp_path
):
    """`bfsitl fly --mission` end to end, in a crosswind with gusts (a swapped axis or sign
    would end the legs elsewhere; drifting would show in the cross-track)."""
    import json

    from test_fly_sitl import fly, read_rows

    mission = tmp_path / "square.toml"
    mission.write_text(SQUARE_TOML)
    result = fly(
        tmp_path,
        "--mission",
        str(mission),
        "--firmware",
        str(gps_lockstep_firmware),
        "--wind",
        "2",
        "--wind-from",
        "60",
        "--gusts",
        "0.5",
        "--seed",
        "3",
        "--log",
        "square.csv",
        "--plot",
        "square.png",
        "--json",
        timeout_s=150,
    )
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads(result.stdout)
    assert summary["outcome"] == "landed"
    legs = summary["waypoints"]
    assert [leg["waypoint"] for leg in legs] == [1, 2, 3, 4]
    assert all(leg["arrival_error_m"] < 0.5 for leg in legs), legs
    assert summary["cross_track_rms_m"] < 0.5
    assert summary["landed_from_start_m"] < 0.5
    # The analysers watched the whole flight and found nothing wrong in wind and gusts.
    assert summary["findings"] == [] and len(summary["analysers"]["watched"]) >= 10
    rows = read_rows(tmp_path / "square.csv")
    legs_rows = [r for r in rows if r["phase"] == "goto"]
    # The FC's GPS (what the autopilot flew by) agrees with the truth along the way.
    worst_m = max(
        math.hypot(
            float(r["fc_north_m"]) - float(r["sim_north_m"]),
            float(r["fc_east_m"]) - float(r["sim_east_m"]),
        )
        for r in legs_rows
    )
    assert worst_m < 0.4
    # The climb on the second leg is flown (the altitude target moves with the leg).
    second = [float(r["sim_alt_m"]) for r in rows if r["waypoint"] == "2" and r["phase"] == "goto"]
    assert second[-1] == pytest.approx(2.5, abs=0.2)
    assert (tmp_path / "square.png").stat().st_size > 10_000


def test_the_autopilot_turns_to_a_heading_from_python(gps_lockstep_firmware):
    """`launch_sitl` + `Autopilot` from the package's top level; the truth's heading after
    yaw_to(90) is within 3 degrees (wind pushes the vehicle while it turns), and the position
    held meanwhile from the fused estimate."""
    from bfsitl import Autopilot, Wind, launch_sitl

    with launch_sitl(
        firmware=gps_lockstep_firmware, seed=4, wind=Wind.from_direction(2.0, 200.0, 0.3)
    ) as vehicle:
        assert vehicle.truth is not None and vehicle.fc.api_version().api >= (1, 47)
        # The position loop on the GPS fused with the FC's accelerometer, on the real firmware
        # (its signs and axes: a wrong one would carry the vehicle off while it turns).
        pilot = Autopilot(vehicle, fuse_accelerometer=True)
        pilot.takeoff(2.0)
        pilot.yaw_to(90.0)
        turned = pilot.rows[-1]
        pilot.hold(2.0)  # the heading is kept afterwards
        kept = pilot.rows[-1]
        pilot.land()
    for row in (turned, kept):
        assert abs((row.sim_yaw_deg - 90.0 + 180.0) % 360.0 - 180.0) < 3.0, row.sim_yaw_deg
        # Held its place meanwhile: 2-4 cm measured; a north axis of the wrong sign in the
        # fused accelerometer drifted 0.6 m.
        assert math.hypot(row.sim_north_m, row.sim_east_m) < 0.25
    assert pilot.rows[-1].phase == "landed"


def test_ctrl_c_mid_mission_leaves_the_sticks_at_disarm_and_a_complete_log(
    lockstep_gps_46_firmware, tmp_path
):
    import signal
    import subprocess
    import time

    from test_fly_sitl import BFSITL, processes_in, read_rows, read_until_line

    mission = tmp_path / "square.toml"
    mission.write_text(SQUARE_TOML)
    log = tmp_path / "flight.csv"
    process = subprocess.Popen(
        [
            *BFSITL,
            "fly",
            "--mission",
            str(mission),
            "--workdir",
            str(tmp_path / "run"),
            "--speed",
            "1",
            "--log",
            str(log),
            "--firmware",
            str(lockstep_gps_46_firmware),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        read_until_line(process, "waypoint 2")
        time.sleep(1.0)  # a second into the second leg, tilted and moving
        process.send_signal(signal.SIGINT)
        _stdout, stderr = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr
    rows = read_rows(log)
    assert rows[-1]["phase"] == "interrupted"
    assert rows[-1]["rc_aux1_us"] == "1000" and rows[-1]["rc_throttle_us"] == "1000"
    assert {"1", "2"} <= {r["waypoint"] for r in rows if r["phase"] == "goto"}
    time.sleep(0.5)
    assert processes_in(tmp_path) == []
