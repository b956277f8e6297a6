"""Master's conventions, checked against what a real master SITL did (``tests/data/master``).

The project cannot carry master's source or a binary of it, so CI cannot run it.  These
recordings stand in: a lockstep master build flown by bfsitl in 3 m/s of wind, with roll,
pitch and yaw stick steps and a 10 m climb.  Two kinds of evidence meet here:

* what the firmware did with bfsitl's packets: its MSP replies (attitude, altitude, GPS,
  accelerometer) agree with the simulated truth recorded beside them, and its motors answered
  each stick step the way a quad-X must.  That proves the recorded packets were right;
* what today's code makes of the same inputs: the encoder turns each recorded sensor reading
  into the recorded fdm packet byte for byte, and the decoder turns each recorded servo reply
  into motors in the recorded order.  So a sign, an axis, the motor order, the barometer or a
  GPS field changed in the master encoder fails here, saying which field of which packet.
"""

from __future__ import annotations

import gzip
import json
import math
import statistics
from functools import cache
from pathlib import Path
from typing import Any

import pytest

from bfsitl.physics.frames import GeoPoint
from bfsitl.physics.params import IRIS
from bfsitl.physics.sensors import SensorReading
from bfsitl.protocol import messages as msg
from bfsitl.protocol.arming import decode_arming_flags
from bfsitl.protocol.fdm_encoding import FdmEncoder
from bfsitl.protocol.firmware_profile import FirmwareProfile, Generation, profile_for
from bfsitl.protocol.sitl_packets import FdmPacket, ServoPacket
from bfsitl.sim.lockstep import decode_reply

DATA = Path(__file__).resolve().parents[2] / "data" / "master"
#: Betaflight's quad-X: M1 rear right, M2 front right, M3 rear left, M4 front left.
RIGHT, LEFT = (0, 1), (2, 3)
REAR, FRONT = (0, 2), (1, 3)


@cache
def exchange() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(gzip.decompress((DATA / "exchange.json.gz").read_bytes()))
    return data


@cache
def msp() -> dict[str, Any]:
    data: dict[str, Any] = json.loads((DATA / "msp.json").read_text())
    return data


def master_profile() -> FirmwareProfile:
    api = msg.ApiVersion.decode(bytes.fromhex(msp()["identity"]["API_VERSION"]))
    version = msg.FcVersion.decode(bytes.fromhex(msp()["identity"]["FC_VERSION"]))
    profile = profile_for(f"{api.api[0]}.{api.api[1]}", version.text)
    assert profile.generation is Generation.MASTER
    return profile


def reading_of(record: dict[str, Any]) -> SensorReading:
    fields = {
        key: tuple(value) if isinstance(value, list) else value
        for key, value in record["reading"].items()
    }
    return SensorReading(**fields)


def _field_differences(made: bytes, recorded: bytes) -> list[str]:
    ours, theirs = FdmPacket.unpack(made), FdmPacket.unpack(recorded)
    return [
        f"{name}: encoder {getattr(ours, name)} != recorded {getattr(theirs, name)}"
        for name in (
            "timestamp_s",
            "gyro_rad_s",
            "accel_m_s2",
            "quaternion_wxyz",
            "velocity_m_s",
            "position",
            "pressure_pa",
        )
        # repr, not ==: a sign flipped on a zero (-0.0) is a changed byte too
        if repr(getattr(ours, name)) != repr(getattr(theirs, name))
    ] or ["(padding)"]


# --- what today's code makes of the recorded inputs -----------------------------------------


def test_the_encoder_makes_every_recorded_fdm_packet_from_its_reading() -> None:
    meta = exchange()["meta"]
    encoder = FdmEncoder(master_profile(), GeoPoint(**meta["home"]))
    records = exchange()["fdm"]
    assert len(records) > 500
    for record in records:
        encoder.gps_lost = record["gps_lost"]
        made = encoder.encode(reading_of(record), record["t"]).pack()
        recorded = bytes.fromhex(record["fdm_hex"])
        assert made == recorded, (
            f"t={record['t']}: the master encoder no longer makes the "
            f"packet master flew on: {_field_differences(made, recorded)}"
        )


def test_the_recording_exercises_every_field_the_encoder_writes() -> None:
    """A packet stream of zeros would let a broken axis pass: the flight moved every one."""
    packets = [FdmPacket.unpack(bytes.fromhex(r["fdm_hex"])) for r in exchange()["fdm"]]
    # (position is longitude and latitude in degrees, then metres up: 1e-6 deg is 0.1 m.)
    least = {
        "gyro_rad_s": (0.05,) * 3,
        "accel_m_s2": (0.1,) * 3,
        "velocity_m_s": (0.1,) * 3,
        "position": (1e-6, 1e-6, 1.0),
    }
    for name, spans in least.items():
        values = [getattr(packet, name) for packet in packets]
        for axis in range(3):
            column = [value[axis] for value in values]
            assert max(column) - min(column) > spans[axis], (name, axis)
    quaternions = [packet.quaternion_wxyz for packet in packets]
    for axis in range(4):
        assert max(q[axis] for q in quaternions) - min(q[axis] for q in quaternions) > 1e-3


def test_servo_replies_decode_to_the_recorded_motor_order() -> None:
    profile = master_profile()
    assert (
        list(profile.motor_slot_of_betaflight_motor)
        == exchange()["meta"]["motor_slot_of_betaflight_motor"]
    )
    for record in exchange()["servo"]:
        speeds, answered_s = decode_reply(bytes.fromhex(record["reply_hex"]))
        assert answered_s == record["answered_t"]
        motors = ServoPacket(speeds).betaflight_motors(profile.motor_slot_of_betaflight_motor)
        assert all(0.0 <= m <= 1.0 for m in motors)


def _motors(phase: str, first_s: float) -> list[tuple[float, ...]]:
    """Decoded motors of a phase's replies in its first ``first_s`` seconds."""
    profile = master_profile()
    records = [r for r in exchange()["servo"] if r["phase"] == phase]
    start = records[0]["answered_t"]
    return [
        ServoPacket(decode_reply(bytes.fromhex(r["reply_hex"]))[0]).betaflight_motors(
            profile.motor_slot_of_betaflight_motor
        )
        for r in records
        if r["answered_t"] - start <= first_s
    ]


def _difference(
    motors: list[tuple[float, ...]], more: tuple[int, int], less: tuple[int, int]
) -> float:
    return statistics.fmean(m[more[0]] + m[more[1]] - m[less[0]] - m[less[1]] for m in motors)


def _yaw_right_motors() -> tuple[int, int]:
    """The two motors whose drag turns the body clockwise seen from above (nose right): those
    spinning counter-clockwise, from the simulated quad's own spin directions."""
    ccw = tuple(i for i, spins_ccw in enumerate(IRIS.rotor_spin_ccw) if spins_ccw)
    assert len(ccw) == 2
    return (ccw[0], ccw[1])


def test_each_stick_step_moved_the_motors_a_quad_x_must() -> None:
    """Roll right lifts the left side, nose down the rear, yaw right the motors whose drag
    turns the nose right: decoded in the wrong order, the differences change sign."""
    for record in exchange()["servo"]:
        if record["phase"] == "roll step":
            assert record["rc_aetr"][0] == 1700
    assert _difference(_motors("roll step", 0.08), LEFT, RIGHT) > 0.02
    assert _difference(_motors("pitch step", 0.08), REAR, FRONT) > 0.02
    yaw_right = _yaw_right_motors()
    others = tuple(i for i in range(4) if i not in yaw_right)
    assert _difference(_motors("yaw step", 0.08), yaw_right, (others[0], others[1])) > 0.02


# --- what the firmware did: its replies against the truth -----------------------------------


def snapshots(*, armed_only: bool = False) -> list[dict[str, Any]]:
    found = msp()["snapshots"]
    if armed_only:
        found = [
            s for s in found if msg.StatusEx.decode(bytes.fromhex(s["replies"]["STATUS_EX"])).armed
        ]
    return found


def _angle_error_deg(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


def test_master_reported_the_true_attitude() -> None:
    checked = 0
    for snap in snapshots():
        attitude = msg.Attitude.decode(bytes.fromhex(snap["replies"]["ATTITUDE"]))
        truth = snap["truth"]
        # Master estimates its attitude from the gyro and accelerometer: a degree or two of
        # lag in a step, none at rest.
        assert _angle_error_deg(attitude.roll_deg, truth["roll_deg"]) < 3.0, snap["label"]
        assert _angle_error_deg(attitude.pitch_deg, truth["pitch_deg"]) < 3.0, snap["label"]
        assert _angle_error_deg(attitude.yaw_deg + 0.5, truth["yaw_deg"]) < 3.0, snap["label"]
        checked += 1
    assert checked >= 10
    # The steps moved each axis: a sign error would not hide behind zeros.
    rolled = next(s for s in snapshots() if s["label"] == "roll stick 1700 for 0.5 s")
    pitched = next(s for s in snapshots() if s["label"] == "pitch stick 1700 for 0.5 s")
    assert msg.Attitude.decode(bytes.fromhex(rolled["replies"]["ATTITUDE"])).roll_deg > 5
    assert msg.Attitude.decode(bytes.fromhex(pitched["replies"]["ATTITUDE"])).pitch_deg > 5


def test_master_reported_the_true_height_and_position() -> None:
    for snap in snapshots(armed_only=True):
        truth = snap["truth"]
        altitude = msg.Altitude.decode(bytes.fromhex(snap["replies"]["ALTITUDE"]))
        assert altitude.altitude_m == pytest.approx(truth["alt_m"], abs=0.3), snap["label"]
        gps = msg.RawGps.decode(bytes.fromhex(snap["replies"]["RAW_GPS"]))
        lon, lat, _alt = truth["geodetic_lon_lat_alt"]
        # Master mirrors its virtual GPS around the first fix; bfsitl sends the mirror image,
        # so the FC reports the truth: within a few centimetres (1e-7 deg is 1.1 cm).
        assert gps.lat_deg == pytest.approx(lat, abs=5e-7), snap["label"]
        assert gps.lon_deg == pytest.approx(lon, abs=5e-7), snap["label"]
    away = next(s for s in snapshots() if s["label"].startswith("climbed 10 m"))
    assert msg.Altitude.decode(bytes.fromhex(away["replies"]["ALTITUDE"])).altitude_m > 9
    # 6 m north and 4 m west of home: north and east apart, with their signs, so a swapped
    # or mirrored axis would show in the FC's GPS against the truth above.
    north_m, east_m = away["truth"]["position_ned_m"][:2]
    assert north_m == pytest.approx(6.0, abs=1.0) and east_m == pytest.approx(-4.0, abs=1.0)
    gps = msg.RawGps.decode(bytes.fromhex(away["replies"]["RAW_GPS"]))
    home = exchange()["meta"]["home"]
    metres_per_deg = 111_320.0
    assert (gps.lat_deg - home["lat_deg"]) * metres_per_deg == pytest.approx(north_m, abs=0.1)
    assert (gps.lon_deg - home["lon_deg"]) * metres_per_deg == pytest.approx(east_m, abs=0.1)


def test_master_felt_gravity_where_the_truth_says() -> None:
    for snap in snapshots():
        imu = msg.RawImu.decode(bytes.fromhex(snap["replies"]["RAW_IMU"]))
        x_g, y_g, z_g = imu.acc_g()
        if snap["label"] == "ground, disarmed":  # level at rest: 1 g along body z alone
            assert z_g == pytest.approx(1.0, abs=0.02) and abs(x_g) < 0.02 and abs(y_g) < 0.02
        if "hover" in snap["label"] or snap["label"].startswith("after the"):
            # A hover holds 1 g of thrust along the body's z, leaning into the wind.
            assert math.hypot(x_g, y_g, z_g) == pytest.approx(1.0, abs=0.1), snap["label"]
            assert z_g > 0.95, snap["label"]


def test_master_status_box_names_and_identity_decode() -> None:
    identity = {k: bytes.fromhex(v) for k, v in msp()["identity"].items()}
    assert msg.FcVariant.decode(identity["FC_VARIANT"]).identifier == "BTFL"
    assert msg.ApiVersion.decode(identity["API_VERSION"]).api >= (1, 49)
    status = msg.StatusEx.decode(identity["STATUS_EX"])
    assert status.arming_disable_flag_count == 30  # master: AUTOPILOT at 28, ARM_SWITCH at 29
    names = {
        flag.cli_name
        for flag in decode_arming_flags(
            status.arming_disable_flags, status.arming_disable_flag_count
        )
    }
    assert names and all(name.isupper() for name in names), names
    boxes = msg.BoxNames.decode(identity["BOXNAMES"]).names
    ids = msg.BoxIds.decode(identity["BOXIDS"]).ids
    assert len(boxes) == len(ids)
    named = dict(zip(ids, boxes, strict=True))
    assert named[0] == "ARM" and named[1] == "ANGLE"
    for snap in snapshots():
        status = msg.StatusEx.decode(bytes.fromhex(snap["replies"]["STATUS_EX"]))
        if "hover" in snap["label"] or "step" in snap["label"]:
            assert status.armed and not status.arming_disable_flags, snap["label"]
        if snap["label"] == "landed, disarmed":
            assert not status.armed


def test_the_cli_transcript_names_only_flags_master_has() -> None:
    text = (DATA / "cli.txt").read_text()
    line = next(x for x in text.splitlines() if x.startswith("Arming disable flags:"))
    known = {flag.cli_name for flag in decode_arming_flags((1 << 30) - 1, 30)}
    assert set(line.split(":", 1)[1].split()) <= known
    assert "MSP API: 1.49" in text and "gps_provider = VIRTUAL" in text
    assert "###ERROR IN input: UNKNOWN COMMAND" in text


def test_master_read_the_sticks_bfsitl_sent_on_the_right_channels() -> None:
    """RC rides in the lockstep datagram as AETR + AUX; MSP_RC answers in the FC's internal
    order (roll, pitch, yaw, throttle, AUX...): each stick landed where it belongs."""
    moved = set()
    for snap in snapshots():
        roll, pitch, throttle, yaw, *aux = snap["rc_aetr"]
        channels = msg.Rc.decode(bytes.fromhex(snap["replies"]["RC"])).channels_us
        assert channels[:4] == (roll, pitch, yaw, throttle), snap["label"]
        assert list(channels[4 : 4 + len(aux)]) == aux, snap["label"]
        moved |= {i for i, value in enumerate((roll, pitch, yaw)) if value != 1500}
    assert moved == {0, 1, 2}  # each stick step is in the recording
