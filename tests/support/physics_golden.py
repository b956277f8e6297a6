"""Recorded flights of the embedded physics: every float it reports, after every action.

Each script below drives one :class:`~bfsitl.physics.Simulator` through the public API only
(step, reset, hold, set_motor_thrust, set_wind, set_sensors, read_sensors and the state
properties) and records, after every action, the state, the ideal accelerometer, the wind,
the motor thrust fractions, the contact and rest flags and, where the script reads them, the
sensor readings, as bytes (-0.0 and 0.0 differ); an action that raises records the exception's
type and text instead.  Between them the scripts take every branch of the step: parked at rest
and taking off, random commands (clamped below 0 and above 1), hard and sliding landings,
tip-overs onto the top corners, wind and gusts, noisy sensors with GPS wander, drift and
offsets, resets to a tilted pose with velocity, the hold, motor faults, sensor and wind
changes mid-flight, several step lengths, and invalid inputs.

``tests/data/physics_golden.json`` holds, per script, the SHA-256 of every checkpoint's
records (one checkpoint per 250 records, so a failure says where the flights part) and the
last state as hexadecimal floats.  It was written with the physics as it was before its C
source became the only one (the pure-Python reference, commit b6b0eff), so the test that
replays these scripts (``tests/unit/physics/test_sim_golden.py``) shows that the model still
gives those flights bit for bit.  Rewrite it only for a change that is meant to change the
flights: ``python tests/support/physics_golden.py --write``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import random
import struct
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bfsitl.physics import IRIS, GeoPoint, SensorConfig, Simulator, Wind

GOLDEN_PATH = Path(__file__).resolve().parents[1] / "data" / "physics_golden.json"
#: Records per checkpoint digest.
CHECKPOINT = 250
HOVER = IRIS.hover_command


def _state_floats(sim: Any) -> tuple[float, ...]:
    s = sim.state
    return (
        s.time_s,
        *s.position_ned_m,
        *s.velocity_ned_m_s,
        *s.quaternion_wxyz,
        *s.angular_velocity_frd_rad_s,
        *s.motor_speeds_rad_s,
        *sim.specific_force_frd_m_s2,
        *sim.wind_ned_m_s,
        sim.altitude_m,
        sim.agl_m,
        sim.time_s,
        *sim.motor_thrust,
    )


def _reading_floats(r: Any) -> tuple[float, ...]:
    return (
        r.time_s,
        *r.gyro_frd_rad_s,
        *r.specific_force_frd_m_s2,
        *r.quaternion_wxyz,
        r.pressure_pa,
        *r.position_ned_m,
        *r.velocity_ned_m_s,
        *r.geodetic,
        *r.velocity_enu_m_s,
    )


def _bits(values: tuple[float, ...]) -> bytes:
    if not all(type(v) is float for v in values):
        raise TypeError(f"not all floats: {[type(v).__name__ for v in values]}")
    return struct.pack(f"<{len(values)}d", *values)


class Recorder:
    """One simulator, driven by a script; every action appends one record."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.sim = Simulator(*args, **kwargs)
        self.records: list[bytes] = []
        self._record(None)

    def _record(self, error: tuple[str, str] | None, reading: bytes = b"") -> None:
        sim = self.sim
        flags = bytes((sim.on_ground, sim.at_rest, sim.held, sim.state.on_ground))
        failure = b"" if error is None else f"{error[0]}: {error[1]}".encode()
        self.records.append(_bits(_state_floats(sim)) + flags + reading + failure)

    def _reading(self) -> bytes:
        try:
            first = self.sim.read_sensors()
        except Exception as exc:  # noqa: BLE001 - the same exception, whatever it is
            return f"{type(exc).__name__}: {exc}".encode()
        if self.sim.read_sensors() is not first:
            raise AssertionError("a reading is the same object until the next step")
        return _bits(_reading_floats(first))

    def read(self) -> None:
        self.records.append(self._reading())

    def step(self, motors: Any, dt_s: float = 0.001, read: bool = True) -> None:
        self.sim.step(motors, dt_s)
        self._record(None, self._reading() if read else b"")

    def run(self, motors: Any, n: int, dt_s: float = 0.001, read: bool = True) -> None:
        for _ in range(n):
            self.step(motors, dt_s, read)

    def do(self, method: str, *args: Any, **kwargs: Any) -> tuple[str, str] | None:
        """Call a method; its error (type and text) if it raised, and the state after it."""
        try:
            getattr(self.sim, method)(*args, **kwargs)
            error = None
        except Exception as exc:  # noqa: BLE001 - recorded, whatever it is
            error = (type(exc).__name__, str(exc))
        self._record(error)
        return error


# ---- the scripts --------------------------------------------------------------------------


def parked_take_off_and_landings() -> Recorder:
    r = Recorder(IRIS, seed=3)
    r.run((0.0, 0.0, 0.0, 0.0), 200)
    r.run((0.3, 0.3, 0.3, 0.3), 200)  # spinning up: still at rest
    r.run((0.7, 0.7, 0.0, 0.0), 150)  # the right-hand rotors alone: it tips
    r.do("reset")
    r.run((0.62, 0.62, 0.62, 0.62), 1500)
    r.run((HOVER, HOVER + 0.01, HOVER, HOVER - 0.01), 300)
    r.run((0.45, 0.45, 0.45, 0.45), 2000)  # comes down hard: it flips onto its top
    r.run((0.0, 0.0, 0.0, 0.0), 500, read=False)
    r.do("reset", (0.0, 0.0, -0.5), yaw_deg=20.0, velocity_ned_m_s=(0.3, 0.0, 0.5))
    r.run((0.2, 0.2, 0.2, 0.2), 800)
    r.do("reset", None, velocity_ned_m_s=(0.5, 0.0, 0.0))
    r.run((0.0, 0.0, 0.0, 0.0), 300)
    r.do("reset", None, angular_velocity_frd_rad_s=(0.0, 0.0, 2.0))
    r.run((0.0, 0.0, 0.0, 0.0), 300)
    r.do(
        "reset", None, velocity_ned_m_s=(0.0, 0.0, -0.2), angular_velocity_frd_rad_s=(0.0, 0.3, 0.0)
    )
    r.run((0.0, 0.0, 0.0, 0.0), 300)
    r.do("reset", None, angular_velocity_frd_rad_s=(-0.3, 0.0, 0.0))
    r.run((0.0, 0.0, 0.0, 0.0), 300)
    r.do("reset", (0.0, 0.0, -0.3), angular_velocity_frd_rad_s=(0.0, 0.0, 6.0))
    r.run((0.0, 0.0, 0.0, 0.0), 600)
    return r


def hard_sliding_and_tilted_landings() -> Recorder:
    r = Recorder(IRIS, sensors=SensorConfig.typical_mems(), seed=7)
    r.do(
        "reset",
        (0.0, 0.0, -3.0),
        roll_deg=20.0,
        pitch_deg=-10.0,
        yaw_deg=30.0,
        velocity_ned_m_s=(3.0, -1.0, 6.0),
        angular_velocity_frd_rad_s=(0.5, -1.0, 2.0),
    )
    r.run((0.0, 0.0, 0.0, 0.0), 1200)
    r.do("reset", None, roll_deg=35.0, yaw_deg=-120.0)
    r.run((0.1, 0.0, 0.1, 0.0), 600)
    r.do(
        "reset",
        (0.0, 0.0, -0.5),
        velocity_ned_m_s=(-8.0, 5.0, 2.0),
        motor_speeds_rad_s=(400.0, 420.0, 380.0, 400.0),
    )
    r.run((0.2, 0.2, 0.2, 0.2), 1500, read=False)
    return r


def tip_overs_onto_the_top_corners() -> Recorder:
    r = Recorder(IRIS, seed=11)
    r.do("reset", (0.0, 0.0, -0.6), roll_deg=180.0, velocity_ned_m_s=(0.0, 0.0, 2.0))
    r.run((0.0, 0.0, 0.0, 0.0), 800)
    r.do("reset", None, roll_deg=88.0, angular_velocity_frd_rad_s=(4.0, 0.0, 1.0))
    r.run((0.0, 0.0, 0.0, 0.0), 600)
    r.do("reset", (0.0, 0.0, -0.4), pitch_deg=50.0, velocity_ned_m_s=(0.0, 0.0, 3.0))
    r.run((1.0, 0.0, 1.0, 0.0), 400)
    r.run((0.0, 0.0, 0.0, 0.0), 800, read=False)
    return r


def slippery_ground_and_other_parameters() -> Recorder:
    params = dataclasses.replace(
        IRIS, axial_inflow=False, friction_coefficient=0.05, contact_damping_ratio=0.3, mass_kg=1.2
    )
    r = Recorder(
        params, wind=Wind((12.0, -6.0, 0.0)), home=GeoPoint(47.3977, 8.5456, 488.0), seed=2
    )
    r.run((0.0, 0.0, 0.0, 0.0), 600)  # the wind pushes it along the ice
    r.run((0.9, 0.9, 0.9, 0.9), 600)
    r.run((0.3, 0.3, 0.3, 0.3), 800, read=False)
    return r


def random_commands_noisy_sensors_and_gps() -> Recorder:
    sensors = dataclasses.replace(
        SensorConfig.typical_mems().with_typical_gps(),
        gyro_bias_rad_s=(0.01, -0.02, 0.003),
        accel_bias_m_s2=(0.1, 0.0, -0.05),
        baro_bias_pa=4.0,
        gps_offset_ne_m=(0.7, -0.3),
        baro_drift_pa_s=0.3,
    )
    r = Recorder(IRIS, sensors=sensors, home=GeoPoint(-33.0, 151.0, 30.0), seed=123)
    r.do("reset", (5.0, -3.0, -20.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    rng = random.Random(99)
    for i in range(2500):
        motors: tuple[float, ...] = tuple(HOVER + rng.uniform(-0.3, 0.3) for _ in range(4))
        if i % 97 == 0:
            motors = (-0.5, 1.7, 0.0, 1.0)  # clamped to 0..1
        r.step(motors, read=i % 3 != 1)  # a reading skipped now and then: no draw then
    return r


def fast_climbs_dives_and_tumbles() -> Recorder:
    r = Recorder(IRIS, seed=4)
    r.do(
        "reset",
        (0.0, 0.0, -300.0),
        velocity_ned_m_s=(0.0, 0.0, 25.0),
        motor_speeds_rad_s=(500.0,) * 4,
    )
    r.run((0.8, 0.8, 0.8, 0.8), 300)  # diving onto spinning rotors: the inflow cap
    r.do(
        "reset",
        (0.0, 0.0, -100.0),
        velocity_ned_m_s=(0.0, 0.0, -30.0),
        motor_speeds_rad_s=(50.0,) * 4,
    )
    r.run((0.0, 0.1, 0.0, 0.1), 300)  # climbing on slow rotors: thrust clamped at zero
    r.do("reset", (0.0, 0.0, -200.0), angular_velocity_frd_rad_s=(60.0, -20.0, 35.0))
    r.run((1.0, 0.0, 0.0, 1.0), 200, dt_s=0.004)  # the exact exponential map
    r.run((0.5, 0.5, 0.5, 0.5), 50, dt_s=0.02)
    return r


def wind_gusts_and_changes_mid_flight() -> Recorder:
    r = Recorder(
        IRIS, wind=Wind((3.0, -2.0, 0.5), gust_std_m_s=1.5, gust_time_constant_s=0.5), seed=21
    )
    r.run((0.0, 0.0, 0.0, 0.0), 300)
    r.run((0.7, 0.7, 0.7, 0.7), 700)
    r.do("set_wind", Wind.from_direction(8.0, 45.0, gust_std_m_s=3.0))
    r.run((HOVER, HOVER, HOVER, HOVER), 500)
    r.do("set_wind", None)
    r.run((HOVER, HOVER, HOVER, HOVER), 200)
    r.do("set_wind", Wind((0.0, 5.0, 0.0)))  # constant: no gust draws
    r.run((HOVER, HOVER, HOVER, HOVER), 200, dt_s=0.0005)
    r.do("set_wind", Wind((1.0, 1.0, 0.0), gust_std_m_s=0.5))
    r.run((0.4, 0.4, 0.4, 0.4), 800, dt_s=0.002)
    return r


def sensor_changes_drift_offsets_and_repeated_reads() -> Recorder:
    r = Recorder(IRIS, seed=5)
    r.do("reset", (0.0, 0.0, -10.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    hover = (HOVER,) * 4
    r.run(hover, 200)
    r.do("set_sensors", SensorConfig(baro_drift_pa_s=-2.5, gps_offset_ne_m=(3.0, -1.5)))
    r.read()
    r.read()
    r.run(hover, 300)
    r.do(
        "set_sensors",
        SensorConfig(
            gps_noise_std_m=0.5, gps_velocity_noise_std_m_s=0.2, accel_bias_m_s2=(0.0, 0.2, 0.0)
        ),
    )
    r.run(hover, 300)
    r.do("set_sensors", SensorConfig.typical_mems().with_typical_gps())
    r.run(hover, 300, read=False)
    r.run(hover, 300)
    r.do("reset", (0.0, 0.0, -5.0), yaw_deg=90.0)  # no time passes: the wander stays
    r.read()
    r.do(
        "set_sensors",
        SensorConfig(
            gyro_bias_rad_s=(0.1, 0.0, 0.0),
            baro_bias_pa=-3.0,
            gps_drift_std_m=1.0,
            gps_drift_time_s=2.0,
            gps_offset_ne_m=(0.25, 0.5),
            gps_noise_std_m=0.1,
        ),
    )
    r.run(hover, 300)
    r.do("set_sensors", SensorConfig())
    r.run(hover, 100)
    return r


def resets_holds_motor_faults_and_step_lengths() -> Recorder:
    r = Recorder(IRIS, sensors=SensorConfig.typical_mems(), seed=8)
    r.run((0.7, 0.7, 0.7, 0.7), 500)
    r.do(
        "reset",
        (0.0, 0.0, -15.0),
        quaternion_wxyz=(0.9, 0.2, -0.3, 0.1),
        velocity_ned_m_s=(2.0, -1.0, 0.5),
        angular_velocity_frd_rad_s=(0.3, 0.2, -0.4),
        motor_speeds_rad_s=(300.0, 310.0, 320.0, 330.0),
    )
    r.run((HOVER,) * 4, 300, dt_s=0.0005)
    r.do("hold")
    r.read()
    r.run((0.9, 0.1, 0.5, 0.3), 200)
    r.do("hold", False)
    r.run((HOVER,) * 4, 300)
    r.do("set_motor_thrust", 2, 0.6)
    r.run((HOVER,) * 4, 400, dt_s=0.004)
    r.do("set_motor_thrust", 4, 0.0)
    r.run((HOVER,) * 4, 300)
    r.do("set_motor_thrust", 2, 1.0)
    r.do("set_motor_thrust", 4, 1)
    r.run((0.6,) * 4, 200, dt_s=0.003)
    r.run((0.6,) * 4, 100, dt_s=0.001)
    r.do("reset")
    r.do("hold", True)
    r.run((0.8,) * 4, 100)
    r.do("hold", False)
    r.run((0.8,) * 4, 300)
    r.do("hold", 1)
    r.do("reset", (0.0, 0.0, -3.0), roll_deg=10.0, velocity_ned_m_s=(1.0, 0.0, 0.0))
    r.run((0.8,) * 4, 50)
    r.do("hold", 0)
    r.run((0.8,) * 4, 100)
    return r


#: (motors, dt_s) a step must refuse, naming what is wrong.
INVALID_STEPS: tuple[tuple[Any, float], ...] = (
    ((0.5, math.nan, 0.5, 0.5), 0.001),
    ((math.inf, -math.inf, 0.0, 0.0), 0.001),
    ((0.5, 0.5, 0.5), 0.001),
    ("abcd", 0.001),
    (None, 0.001),
    ((0.5, 0.5, 0.5, "x"), 0.001),
    ((0.5,) * 4, 0.0),
    ((0.5,) * 4, -0.001),
    ((0.5,) * 4, 0.0201),
    ((0.5,) * 4, math.nan),
    ((0.5,) * 4, math.inf),
)
#: (method, args, kwargs) that must be refused and change nothing.
INVALID_CALLS: tuple[tuple[str, tuple[Any, ...], dict[str, Any]], ...] = (
    ("reset", ((0.0, 0.0, 0.1),), {}),
    ("reset", ((0.0, 0.0, -5.0),), {"quaternion_wxyz": (1.0, 0.0, 0.0, 0.0), "roll_deg": 5.0}),
    ("reset", ((0.0, 0.0, -5.0),), {"quaternion_wxyz": (0.0, 0.0, 0.0, 0.0)}),
    ("reset", ((0.0, 0.0, -5.0),), {"motor_speeds_rad_s": (1.0, -1.0, 0.0, 0.0)}),
    ("reset", ((0.0, math.nan, -5.0),), {}),
    ("reset", ((0.0, -5.0),), {}),
    ("reset", (None,), {"velocity_ned_m_s": "fast"}),
    ("set_motor_thrust", (5, 0.5), {}),
    ("set_motor_thrust", (1, 1.5), {}),
    ("set_motor_thrust", (1, math.nan), {}),
)


def invalid_steps_and_calls() -> Recorder:
    r = Recorder(
        IRIS,
        sensors=SensorConfig.typical_mems().with_typical_gps(),
        wind=Wind((1.0, 0.0, 0.0), 1.0),
        seed=1,
    )
    for motors, dt_s in INVALID_STEPS:
        r.run((0.7,) * 4, 10)
        if r.do("step", motors, dt_s) is None:
            raise AssertionError(f"step({motors!r}, {dt_s!r}) was accepted")
    for method, args, kwargs in INVALID_CALLS:
        r.run((0.7,) * 4, 10)
        if r.do(method, *args, **kwargs) is None:
            raise AssertionError(f"{method}{args}{kwargs} was accepted")
    r.run((0.7,) * 4, 30)  # and the generators went on
    return r


def other_number_types() -> Recorder:
    r = Recorder(IRIS, seed=1)
    r.run([1, 0, True, 0.5], 20)
    r.run((1e308, 1e308, 1e308, 1e308), 20)  # the sum overflows; each command is finite
    r.run((0.6, 0.6, 0.6, 0.6), 20, dt_s=0.02)
    return r


def drifting_barometer_from_the_start() -> Recorder:
    r = Recorder(IRIS, sensors=SensorConfig(baro_drift_pa_s=1.5, baro_noise_std_pa=0.5), seed=2)
    r.run((0.0,) * 4, 100, read=False)
    r.run((0.0,) * 4, 100)
    return r


def leaving_and_entering_the_atmosphere_model() -> Recorder:
    r = Recorder(IRIS, home=GeoPoint(0.0, 0.0, -1000.5), seed=2)
    r.read()  # below the model: refused
    r.run((0.7,) * 4, 600, read=False)
    r.read()  # lifted off into it
    high = Recorder(
        IRIS,
        sensors=SensorConfig.typical_mems().with_typical_gps(),
        home=GeoPoint(10.0, 20.0, 19995.0),
        seed=9,
    )
    high.do("reset", (0.0, 0.0, -4.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    high.run((0.75,) * 4, 400)
    high.run((0.75,) * 4, 200, read=False)  # through 20 km MSL
    high.read()  # refused, without a draw
    high.do("reset", (0.0, 0.0, -1.0))
    high.run((0.0,) * 4, 50)
    r.records.extend(high.records)
    return r


SCRIPTS: dict[str, Callable[[], Recorder]] = {
    script.__name__: script
    for script in (
        parked_take_off_and_landings,
        hard_sliding_and_tilted_landings,
        tip_overs_onto_the_top_corners,
        slippery_ground_and_other_parameters,
        random_commands_noisy_sensors_and_gps,
        fast_climbs_dives_and_tumbles,
        wind_gusts_and_changes_mid_flight,
        sensor_changes_drift_offsets_and_repeated_reads,
        resets_holds_motor_faults_and_step_lengths,
        invalid_steps_and_calls,
        other_number_types,
        drifting_barometer_from_the_start,
        leaving_and_entering_the_atmosphere_model,
    )
}


def summary(recorder: Recorder) -> dict[str, Any]:
    """What the golden file keeps of one script: checkpoint digests and the last state."""
    checkpoints = []
    digest = hashlib.sha256()
    for index, record in enumerate(recorder.records, start=1):
        digest.update(len(record).to_bytes(4, "little") + record)
        if index % CHECKPOINT == 0 or index == len(recorder.records):
            checkpoints.append(digest.hexdigest()[:16])
    return {
        "records": len(recorder.records),
        "checkpoints": checkpoints,
        "last_state": [float.hex(v) for v in _state_floats(recorder.sim)],
    }


def main(argv: list[str]) -> None:
    flights = {name: summary(script()) for name, script in SCRIPTS.items()}
    text = json.dumps(flights, indent=1) + "\n"
    if "--write" in argv:
        GOLDEN_PATH.write_text(text)
        print(f"wrote {GOLDEN_PATH}")
    else:
        print(text)


if __name__ == "__main__":
    main(sys.argv[1:])
