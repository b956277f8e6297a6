"""Every supported firmware generation, against the real SITL: tests that tell conventions apart.

A symmetric hover in still air hides a wrong motor order, a wrong sign or a wrong axis. These
tests disturb the vehicle instead and compare what the FC reports with the simulated truth:

* a test stand: the vehicle held at known attitudes; the FC's attitude must match (the
  accelerometer's axes and the quaternion convention; on master the estimator converges to
  what the accelerometer and the virtual magnetometer say);
* stick steps in flight: roll, pitch and yaw each move the true attitude the way Betaflight's
  sticks mean it, the FC reports the same, and nothing runs away (motor order, gyro signs);
* a flight in wind and gusts: it still lands, and the FC's attitude follows the truth;
* the GPS builds: a 3D fix at the simulated position.

Each runs on 4.6.0 (PyPI) and on master built by ``bfsitl firmware build`` from the source
named by ``BFSITL_MASTER_SOURCE`` (fixture ``generation_firmware``; without it the master cases
are skipped, and tests/unit/sim/test_master_recordings.py checks master's conventions against a
recording of a real master SITL); the flights use their ``--lockstep`` builds (fixture
``lockstep_firmware``).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bfsitl.control import make_controller
from bfsitl.fc.cli_session import CliSession
from bfsitl.mission import FlightLoop, FlightSession, SessionConfig, SitlLaunch
from bfsitl.physics import GeoPoint, Simulator
from bfsitl.physics.frames import betaflight_attitude_deg, quat_from_euler_deg
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import Generation
from bfsitl.sim.bridge import SitlBridge, wait_for_replies
from bfsitl.sitl.process import SitlProcess

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]
HOME = GeoPoint(47.3977, 8.5456, 488.0)
# The flights below are not about real-time behaviour: they fly each generation's
# --lockstep build (the same conventions; the platform's clock is the only change), which no
# load on the machine can degrade. At 1x real time, during full test runs, stock SITLs
# answered only 60-78 % of fdm packets and these flights were degraded or unstable.


def angle_error_deg(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 360.0))


def test_the_profile_is_chosen_from_what_the_firmware_says(generation_firmware, tmp_path):
    with SitlProcess(generation_firmware, workdir=tmp_path, isolate=True) as sitl:
        profile = sitl.profile
        version = sitl.client.get(msg.FcVersion).text
    assert profile.firmware_version == version
    expected = Generation.V4_6 if version.startswith("4.") else Generation.MASTER
    assert profile.generation is expected
    assert profile.tested


def test_a_held_vehicle_reads_the_same_attitude_on_the_fc(generation_firmware, tmp_path):
    """Roll, pitch and a combination on a test stand: the FC converges to the truth."""
    sim = Simulator(home=HOME)
    sitl = SitlProcess(generation_firmware, workdir=tmp_path, isolate=True)
    bridge = SitlBridge(sim, sitl.prepare_network())
    bridge.bind()
    poses = [(20.0, 0.0), (0.0, 15.0), (-10.0, -12.0)]  # aerospace roll, pitch (nose up +)
    try:
        with sitl:
            bridge.set_profile(sitl.profile)
            bridge.start()
            wait_for_replies(bridge)
            for roll_deg, pitch_deg in poses:
                bridge.between_steps(
                    lambda r=roll_deg, p=pitch_deg: (
                        sim.reset((0.0, 0.0, -1.0), roll_deg=r, pitch_deg=p),
                        sim.hold(True),
                    )
                )
                truth = betaflight_attitude_deg(quat_from_euler_deg(roll_deg, pitch_deg, 0.0))
                deadline = time.monotonic() + 8.0
                while True:
                    attitude = sitl.client.get(msg.Attitude)
                    errors = (abs(attitude.roll_deg - truth[0]), abs(attitude.pitch_deg - truth[1]))
                    if max(errors) < 1.0 or time.monotonic() > deadline:
                        break
                    time.sleep(0.2)
                assert max(errors) < 1.0, (
                    f"held at roll {truth[0]:+.1f}, pitch {truth[1]:+.1f} (Betaflight "
                    f"convention), the FC reads roll {attitude.roll_deg:+.1f}, pitch "
                    f"{attitude.pitch_deg:+.1f}"
                )
    finally:
        bridge.close()


def test_stick_steps_move_the_truth_the_right_way_and_the_fc_agrees(lockstep_firmware, tmp_path):
    """Roll right, pitch forward and yaw right in ANGLE mode, each for 1.5 s in a hover."""
    config = SessionConfig(sitl=SitlLaunch(firmware=lockstep_firmware, workdir=tmp_path / "run"))
    with FlightSession(config) as session:
        estimated = session.sitl.profile.fdm.attitude_estimated
        loop = FlightLoop(session, make_controller("fused", {}))
        loop.arm()
        loop.wait_on_ground(2.0)
        loop.takeoff(1.5)
        steps = {
            "roll": {"roll_us": 1600.0},
            "pitch": {"pitch_us": 1600.0},
            "yaw": {"yaw_us": 1600.0},
        }
        seen = {}
        for axis, sticks in steps.items():
            start = len(loop.rows)
            loop.hold(1.5, **sticks)
            seen[axis] = loop.rows[start:]
            loop.hold(2.0)
        loop.land()
    roll_row, pitch_row, yaw_rows = seen["roll"][-1], seen["pitch"][-1], seen["yaw"]
    # Roll right = right wing down = positive; pitch forward = nose down = positive.
    assert roll_row.sim_roll_deg > 2.0 and roll_row.roll_deg > 2.0, roll_row
    assert pitch_row.sim_pitch_deg > 2.0 and pitch_row.pitch_deg > 2.0, pitch_row
    # The estimator (master) sees the sustained sideways acceleration as a smaller tilt.
    tolerance_deg = 2.0 if estimated else 0.5
    assert abs(roll_row.roll_deg - roll_row.sim_roll_deg) < tolerance_deg
    assert abs(pitch_row.pitch_deg - pitch_row.sim_pitch_deg) < tolerance_deg
    # Yaw right = clockwise from above = heading increases; a wrong gyro sign runs away.
    turned_deg = math.remainder(yaw_rows[-1].sim_yaw_deg - yaw_rows[0].sim_yaw_deg, 360.0)
    assert turned_deg > 20.0, f"a yaw-right step turned the truth by {turned_deg:+.1f} deg"
    assert angle_error_deg(yaw_rows[-1].yaw_deg, yaw_rows[-1].sim_yaw_deg) < 3.0
    assert max(abs(r.sim_roll_deg) for r in loop.rows if r.phase == "hold") < 15.0


def fly_in_wind(firmware: Path, tmp_path: Path, *extra: str) -> dict:
    summary_path = tmp_path / f"wind{len(extra)}.json"
    done = subprocess.run(
        [
            *BFSITL,
            "fly",
            "--firmware",
            str(firmware),
            "--wind",
            "3",
            "--gusts",
            "1.5",
            "--hold",
            "6",
            "--summary",
            str(summary_path),
            *extra,
        ],
        capture_output=True,
        text=True,
        timeout=240,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(summary_path.read_text())


def test_a_flight_in_wind_and_gusts_lands_and_the_fc_follows_the_truth(lockstep_firmware, tmp_path):
    """Issue 10's criterion: in 3 m/s wind with 1.5 m/s gusts it lands, holds within 15 cm
    and the FC's roll/pitch stay within 2 deg of the truth, on both generations."""
    summary = fly_in_wind(lockstep_firmware, tmp_path)
    assert summary["outcome"] == "landed"
    # 4.6 copies the attitude.  Master estimates it, and a drifting vehicle's gust-driven
    # acceleration looks like tilt to the accelerometer; master has a GPS, so the flight
    # holds the take-off point, and a vehicle that stays put is not fooled (the control:
    # the next test).
    assert summary["attitude"]["max_abs_error_deg"] < 2.0, summary["attitude"]
    assert summary["hold"]["max_abs_error_m"] < 0.15, summary["hold"]


def test_drifting_in_the_same_wind_fools_masters_estimator(lockstep_master_firmware, tmp_path):
    """The control of the test above: without the position hold, master's attitude error
    in the same flight exceeds 2 deg, so holding the position is what keeps it small."""
    summary = fly_in_wind(lockstep_master_firmware, tmp_path, "--no-position-hold")
    assert summary["outcome"] == "landed"
    assert summary["attitude"]["max_abs_error_deg"] > 2.0, summary["attitude"]


@pytest.mark.parametrize("build", ["gps_firmware", "master_firmware"], ids=["4.6.0-gps", "master"])
def test_the_gps_build_reports_a_3d_fix_at_the_simulated_position(build, request, tmp_path):
    gps_firmware = request.getfixturevalue(build)
    sim = Simulator(home=HOME)
    sitl = SitlProcess(gps_firmware, workdir=tmp_path, isolate=True)
    bridge = SitlBridge(sim, sitl.prepare_network())
    bridge.bind()
    try:
        with sitl:
            assert sitl.profile.has_gps
            bridge.set_profile(sitl.profile)
            bridge.start()
            wait_for_replies(bridge)
            if sitl.profile.gps_setup_cli:
                # 4.6 leaves the GPS off by default (master enables it).
                with CliSession(sitl.client.link) as cli:
                    for line in sitl.profile.gps_setup_cli:
                        cli.run(line)
                    bridge.pause()  # no fdm packet while it boots again (4.6.0 crashed)
                    cli.save(restart=sitl.restart_after_reboot)
                bridge.resume()
                wait_for_replies(bridge)
            # 30 m north, 40 m west, 10 m up: the mirror (master) or not (4.6) must not show.
            bridge.between_steps(lambda: (sim.reset((30.0, -40.0, -10.0)), sim.hold(True)))
            truth_lon, truth_lat, truth_alt = sim.read_sensors().geodetic
            deadline = time.monotonic() + 10.0
            while True:
                gps = sitl.client.get(msg.RawGps)
                north_m = (gps.lat_deg - truth_lat) * 111_319.5
                east_m = (
                    (gps.lon_deg - truth_lon) * 111_319.5 * math.cos(math.radians(HOME.lat_deg))
                )
                if gps.has_fix and math.hypot(north_m, east_m) < 1.0 or time.monotonic() > deadline:
                    break
                time.sleep(0.2)
    finally:
        bridge.close()
    assert gps.has_fix and gps.satellites >= 5, gps
    assert math.hypot(north_m, east_m) < 1.0, (gps, truth_lat, truth_lon)
    assert abs(gps.altitude_m - truth_alt) <= 1.5, (gps.altitude_m, truth_alt)


@pytest.mark.parametrize(
    "command",
    [
        ["status", "--start", "--json"],
        ["telemetry", "--start", "--rate", "20", "--duration", "1.5", "--json"],
        ["cli", "--start", "get", "small_angle"],
        ["top", "--start", "--once"],
    ],
)
def test_the_commands_work(generation_firmware, tmp_path, command):
    done = subprocess.run(
        [*BFSITL, command[0], "--firmware", str(generation_firmware), *command[1:]],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    if command[0] == "status":
        status = json.loads(done.stdout)
        assert status
    if command[0] == "telemetry":
        lines = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
        assert len(lines) >= 10
    if command[0] == "cli":
        assert "small_angle = " in done.stdout


def test_the_bare_flight_lands_and_holds(lockstep_firmware, tmp_path):
    summary_path = tmp_path / "fly.json"
    done = subprocess.run(
        [
            *BFSITL,
            "fly",
            "--firmware",
            str(lockstep_firmware),
            "--hold",
            "5",
            "--summary",
            str(summary_path),
        ],
        capture_output=True,
        text=True,
        timeout=200,
        cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads(Path(summary_path).read_text())
    # The target: within 10 cm. In lockstep no host load degrades the loop (real
    # time under a loaded full run gave up to 16 cm max with a +8 to +11 cm bias).
    assert summary["hold"]["max_abs_error_m"] < 0.10, summary["hold"]
