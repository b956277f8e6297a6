"""Gazebo's conventions, checked against what a real Gazebo Harmonic and its plugin did
(``tests/data/gazebo``, recorded by ``benchmarks/gazebo_parity.py --record``).

Gazebo is not in a package registry, so CI cannot run it.  The recording stands in: a stock
4.6.0 SITL flown by bfsitl on Gazebo (bfsitl's world, the BetaflightPlugin, bfsitl's relay in
between) through a take-off, stick steps on roll, pitch and yaw, a climb, a descent, a turn
and a landing.  Three witnesses meet here, and each is checked against the others:

* Gazebo's own poses, from its scene broadcaster (ENU, the model's and its links' poses), read
  here with nothing but the ENU -> NED and FLU -> FRD axis swaps written out by hand;
* the plugin's fdm packets, as today's code reads them (:class:`PluginFrame`, the world's
  transforms): each must be Gazebo's pose at that sim time, in NED;
* the FC's own view (MSP attitude, altitude and motors in the flight log) and its servo
  packets: the firmware read the packets' quaternion and pressure the way Gazebo meant them,
  its motors come out of the servo packet in 4.6.0's slot order, and the sticks moved
  Gazebo's quad the way a pilot expects.

So a frame, a sign, the quaternion's order or the motor slots changed in today's code fails
here, saying which.
"""

from __future__ import annotations

import bisect
import gzip
import itertools
import json
import math
import statistics
from functools import cache
from pathlib import Path
from typing import Any

import pytest

from bfsitl.gazebo.plugin_frame import GazeboState, PluginFrame
from bfsitl.gazebo.world import world_path
from bfsitl.physics.frames import (
    betaflight_attitude_deg,
    body_to_world,
    quat_multiply,
    rotation_matrix,
)
from bfsitl.physics.params import Quat, Vec3
from bfsitl.protocol.firmware_profile import DEFAULT_PROFILE
from bfsitl.protocol.sitl_packets import FdmPacket, ServoPacket

DATA = Path(__file__).resolve().parents[2] / "data" / "gazebo"
#: Gazebo's physics step in bfsitl's world.
STEP_S = 0.001
#: The model holding the plugin, the nested IRIS, and the link the plugin reports.
CHAIN = ("iris_with_Betaflight", "iris_with_standoffs", "imu_link")


@cache
def recording() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(gzip.decompress((DATA / "exchange.json.gz").read_bytes()))
    return data


@cache
def fdm() -> list[tuple[float, FdmPacket]]:
    return [(wall_s, FdmPacket.unpack(bytes.fromhex(h))) for wall_s, h in recording()["fdm"]]


@cache
def fc_rows() -> list[dict[str, Any]]:
    columns = recording()["fc"]["columns"]
    return [dict(zip(columns, row, strict=True)) for row in recording()["fc"]["rows"]]


@cache
def gazebo_poses() -> dict[int, tuple[Vec3, Quat]]:
    """imu_link's world pose (ENU position, FLU -> ENU quaternion) by sim time in ms: each
    entity's pose is relative to its parent, so the chain is composed."""
    poses = {}
    for message in recording()["gazebo_poses"]:
        position: Vec3 = (0.0, 0.0, 0.0)
        q: Quat = (1.0, 0.0, 0.0, 0.0)
        for name in CHAIN:
            entity = message["entities"][name]
            offset = body_to_world(q, tuple(entity["position"]))  # type: ignore[arg-type]
            position = (position[0] + offset[0], position[1] + offset[1], position[2] + offset[2])
            q = quat_multiply(q, tuple(entity["orientation_wxyz"]))  # type: ignore[arg-type]
        poses[round(message["sim_time_s"] * 1000.0)] = (position, q)
    return poses


def ned_of_enu(v: Vec3) -> Vec3:
    east, north, up = v
    return (north, east, -up)


def betaflight_angles_of_gazebo(q_enu_flu: Quat) -> Vec3:
    """Roll (right wing down +), pitch (nose down +, 4.6.0's sign) and heading of a Gazebo
    model's attitude: M = P R F, with P the ENU -> NED swap and F the FLU -> FRD flip."""
    r = rotation_matrix(q_enu_flu)
    enu = [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]]
    ned = [enu[1], enu[0], [-x for x in enu[2]]]  # rows: north, east, down
    m = [[row[0], -row[1], -row[2]] for row in ned]  # columns: forward, right, down
    roll = math.degrees(math.atan2(m[2][1], m[2][2]))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, m[2][0]))))
    yaw = math.degrees(math.atan2(m[1][0], m[0][0])) % 360.0
    return (roll, pitch, yaw)


def _angle_error(a: float, b: float) -> float:
    return (a - b + 180.0) % 360.0 - 180.0


def paired() -> list[tuple[GazeboState, Vec3, Quat]]:
    """Each fdm packet read by today's code, beside Gazebo's own pose at its sim time."""
    frame = PluginFrame.of_world(world_path())
    poses = gazebo_poses()
    return [
        (frame.state(packet), *poses[round(packet.timestamp_s * 1000.0)])
        for _, packet in fdm()
        if round(packet.timestamp_s * 1000.0) in poses
    ]


def test_the_recording_covers_a_flight() -> None:
    pairs = paired()
    assert len(pairs) >= 30
    altitudes = [state.altitude_m for state, _, _ in pairs]
    assert max(altitudes) > 5.0, "the climb to 6 m is in it"
    tilts = [
        max(abs(a) for a in betaflight_attitude_deg(s.quaternion_wxyz)[:2]) for s, _, _ in pairs
    ]
    assert max(tilts) > 5.0, "tilted moments are in it"
    assert recording()["meta"]["firmware"].startswith("4.6.0")


def test_each_fdm_packet_is_gazebos_own_pose_in_ned() -> None:
    """Exact, to the recording's rounding, but for a few packets whose stamp and the scene's
    name neighbouring physics steps: those are off by one step of the motion (1 ms)."""
    exact = 0
    pairs = paired()
    for state, position_enu, q_enu_flu in pairs:
        where = f"at sim time {state.sim_time_s:.3f} s"
        speed_m_s = max(abs(v) for v in state.velocity_ned_m_s)
        rate_deg_s = math.degrees(max(abs(w) for w in state.gyro_rad_s))
        position_error = max(
            abs(a - b) for a, b in zip(state.position_ned_m, ned_of_enu(position_enu), strict=True)
        )
        assert position_error <= 1e-4 + speed_m_s * STEP_S * 1.05, where
        theirs = betaflight_angles_of_gazebo(q_enu_flu)
        ours = betaflight_attitude_deg(state.quaternion_wxyz)
        worst = 0.0
        for axis, a, b in zip(("roll", "pitch", "heading"), ours, theirs, strict=True):
            error = abs(_angle_error(a, b))
            assert error <= 1e-3 + rate_deg_s * STEP_S * 1.05, (
                f"{axis} {where}: packet {a:.3f}, Gazebo {b:.3f}"
            )
            worst = max(worst, error)
        exact += position_error < 1e-4 and worst < 1e-3
    assert exact >= 0.95 * len(pairs)


def test_the_fdm_velocity_is_gazebos_motion_in_ned() -> None:
    """Gazebo's poses differenced over 100 ms, against the packets' velocity between them."""
    poses = gazebo_poses()
    checked = 0
    for state, _, _ in paired():
        t_ms = round(state.sim_time_s * 1000.0)
        before, after = poses.get(t_ms - 50), poses.get(t_ms + 50)
        if before is None or after is None:
            continue
        moved = ned_of_enu(tuple(a - b for a, b in zip(after[0], before[0], strict=True)))  # type: ignore[arg-type]
        expected = tuple(m / 0.1 for m in moved)
        assert state.velocity_ned_m_s == pytest.approx(expected, abs=0.15), state.sim_time_s
        checked += 1
    assert checked >= 10


def _sim_time_at(wall_s: float) -> float:
    """The sim time of the fdm packet the relay had just received at ``wall_s``."""
    walls = [w for w, _ in fdm()]
    index = max(0, bisect.bisect_right(walls, wall_s) - 1)
    wall0, packet = fdm()[index]
    return (
        packet.timestamp_s
        + (wall_s - wall0)
        * recording()["meta"]["packets"]["sim_time_s"]
        / (recording()["meta"]["packets"]["wall_time_s"])
    )


def _gazebo_at(sim_time_s: float) -> tuple[Vec3, Quat]:
    poses = gazebo_poses()
    times = sorted(poses)
    index = bisect.bisect_left(times, sim_time_s * 1000.0)
    nearest = min(times[max(0, index - 1) : index + 1], key=lambda t: abs(t - sim_time_s * 1000.0))
    return poses[nearest]


def test_the_fc_read_gazebos_attitude_and_pressure() -> None:
    """MSP_ATTITUDE and MSP_ALTITUDE during the flight against Gazebo's own pose then: 4.6.0
    copies the packet's quaternion and reads the pressure field as its barometer."""
    rows = [r for r in fc_rows() if r["armed"]]
    arming_altitude = _gazebo_at(_sim_time_at(rows[0]["time_s"]))[0][2]
    roll_err, pitch_err, yaw_err, alt_err, tilted = [], [], [], [], 0
    for row in rows:
        position, q = _gazebo_at(_sim_time_at(row["time_s"]))
        roll, pitch, yaw = betaflight_angles_of_gazebo(q)
        tilted += abs(roll) > 5 or abs(pitch) > 5
        roll_err.append(_angle_error(row["roll_deg"], roll))
        pitch_err.append(_angle_error(row["pitch_deg"], pitch))
        # MSP_ATTITUDE's heading is whole degrees, truncated.
        yaw_err.append(_angle_error(row["yaw_deg"] + 0.5, yaw))
        alt_err.append(row["fc_alt_m"] - (position[2] - arming_altitude))
    rms = lambda errors: math.sqrt(statistics.fmean(e * e for e in errors))  # noqa: E731
    assert tilted > 20
    assert rms(roll_err) < 1.5 and rms(pitch_err) < 1.5, (rms(roll_err), rms(pitch_err))
    assert rms(yaw_err) < 1.5, rms(yaw_err)
    assert rms(alt_err) < 0.3, rms(alt_err)


def test_the_pressure_field_falls_with_gazebos_altitude() -> None:
    """The air-pressure sensor's reading (what 4.6.0 takes as its barometer) falls about
    12 Pa per metre of imu_link's height, as the standard atmosphere does at sea level."""
    pairs = paired()
    heights = [position[2] for _, position, _ in pairs]
    pressures = [state.pressure_pa for state, _, _ in pairs]
    slope = statistics.linear_regression(heights, pressures).slope
    assert slope == pytest.approx(-12.0, abs=0.5)


def _step_start(axis: str) -> float:
    return float(recording()["meta"]["marks"][axis][0])


@pytest.mark.parametrize(
    ("axis", "index", "at_least"),
    [("roll", 0, 5.0), ("pitch", 1, 5.0), ("yaw", 2, 30.0)],
)
def test_each_stick_moves_gazebos_quad_the_way_a_pilot_expects(
    axis: str, index: int, at_least: float
) -> None:
    """Roll right, pitch forward, yaw right (1700 us) for 0.5 s: right wing down, nose down
    (Betaflight's positive pitch) and a heading turning clockwise, in Gazebo's own poses."""
    start_s = _step_start(axis)
    rows = [r for r in fc_rows() if start_s <= r["time_s"] <= start_s + 0.45]
    assert rows and all(r[f"rc_{axis}_us"] >= 1650 for r in rows[2:]), "the stick was held"
    before = betaflight_angles_of_gazebo(_gazebo_at(_sim_time_at(start_s))[1])
    after = betaflight_angles_of_gazebo(_gazebo_at(_sim_time_at(start_s + 0.45))[1])
    assert _angle_error(after[index], before[index]) > at_least


def test_the_servo_packets_slots_are_the_fcs_motors_in_order() -> None:
    """Each servo packet against MSP_MOTOR (the FC's own motors 1-4) taken within 10 ms of it:
    of the 24 ways to read the four slots, 4.6.0's order is the one that gives the FC's
    motors, whenever they differ enough to tell."""
    packets = [
        (wall_s, ServoPacket.unpack(bytes.fromhex(h)).motor_speed)
        for wall_s, h in recording()["servo"]
    ]
    walls = [w for w, _ in packets]
    pairs = []
    for row in fc_rows():
        index = bisect.bisect_left(walls, row["time_s"])
        fc = tuple(row[f"fc_motor{i}"] for i in range(1, 5))
        if row["armed"] and index < len(walls) and abs(walls[index] - row["time_s"]) < 0.01:
            if max(fc) - min(fc) > 0.03:  # a level hover looks the same in every order
                pairs.append((packets[index][1], fc))
    assert len(pairs) >= 10

    def error(slots: tuple[int, ...]) -> float:
        return statistics.fmean(
            abs(speeds[slot] - motor)
            for speeds, fc in pairs
            for slot, motor in zip(slots, fc, strict=True)
        )

    ranked = sorted(itertools.permutations(range(4)), key=error)
    assert ranked[0] == DEFAULT_PROFILE.motor_slot_of_betaflight_motor
    assert error(ranked[0]) < 0.03
    assert error(ranked[1]) > 2 * error(ranked[0])


def servo_motors() -> list[tuple[float, tuple[float, ...]]]:
    slots = DEFAULT_PROFILE.motor_slot_of_betaflight_motor
    out = []
    for wall_s, h in recording()["servo"]:
        out.append((wall_s, ServoPacket.unpack(bytes.fromhex(h)).betaflight_motors(slots)))
    return out


def test_a_right_roll_starts_on_the_left_motors() -> None:
    """At the roll step's start the FC speeds up motors 3 and 4 (left) over 1 and 2 (right),
    and Gazebo's quad rolled right (the stick test): so the world's channels drive the rotors
    where Betaflight's motors 3 and 4 sit."""
    start_s = _step_start("roll")
    early = [m for w, m in servo_motors() if start_s + 0.02 <= w <= start_s + 0.12]
    assert early
    left = statistics.fmean(m[2] + m[3] for m in early)
    right = statistics.fmean(m[0] + m[1] for m in early)
    assert left > right + 0.05


def test_one_fdm_packet_per_gazebo_millisecond_and_a_reply_to_each() -> None:
    packets = recording()["meta"]["packets"]
    # The plugin sends one packet per 1 ms physics step; the SITL answers nearly every one.
    assert packets["fdm"] == pytest.approx(packets["sim_time_s"] * 1000.0, rel=0.01)
    assert packets["servo"] / packets["fdm"] > 0.9
    real_time_factor = packets["sim_time_s"] / packets["wall_time_s"]
    assert 0.8 < real_time_factor <= 1.02
    # Every packet is stamped with a whole physics step of sim time.
    for _, packet in fdm():
        assert packet.timestamp_s * 1000.0 == pytest.approx(round(packet.timestamp_s * 1000.0))
    intervals = recording()["timing"]["fdm_intervals_us"]
    assert statistics.median(intervals) == pytest.approx(1000.0 / real_time_factor, rel=0.1)
