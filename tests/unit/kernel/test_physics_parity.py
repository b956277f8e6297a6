"""The compiled simulator gives the pure-Python reference's floats, bit for bit, at every step.

Each scenario flies a :class:`~bfsitl.physics.Simulator` and a
:class:`~bfsitl.kernel.simulator.KernelSimulator` side by side, doing the same thing to both,
and compares after every step the state, the ideal accelerometer, the contact and rest flags
and (where the scenario reads them: it may skip steps, or read twice) the sensor readings,
as bytes: -0.0 and 0.0 differ, as would two NaNs of different payload.  Between them the
scenarios take every branch of the step: parked at rest and taking off, random commands
(clamped below 0 and above 1), hard and sliding landings, tip-overs onto the top corners,
wind and gusts, noisy sensors with GPS wander, drift and offsets, resets to a tilted pose
with velocity, the hold, motor faults, sensor and wind changes mid-flight, several step
lengths, and invalid inputs (the same SimInputError text, nothing changed).
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import random
import struct
from collections.abc import Callable
from typing import Any

import pytest

from bfsitl.errors import KernelUnavailableError
from bfsitl.physics import IRIS, GeoPoint, SensorConfig, Simulator, Wind

try:
    from bfsitl.kernel.compiler import load_kernel

    load_kernel()
except KernelUnavailableError as exc:  # pragma: no cover - machines without a C compiler
    pytest.skip(f"the compiled kernel cannot be built here: {exc}", allow_module_level=True)

from bfsitl.kernel.simulator import KernelSimulator  # noqa: E402

HOVER = IRIS.hover_command
STATE_NAMES = ("time", "p.n", "p.e", "p.d", "v.n", "v.e", "v.d", "q.w", "q.x", "q.y", "q.z",
               "w.p", "w.q", "w.r", "om1", "om2", "om3", "om4", "sf.x", "sf.y", "sf.z",
               "wind.n", "wind.e", "wind.d", "altitude", "agl", "time_s", "thrust1",
               "thrust2", "thrust3", "thrust4")
READING_NAMES = ("time", "gyro.x", "gyro.y", "gyro.z", "f.x", "f.y", "f.z", "q.w", "q.x",
                 "q.y", "q.z", "pressure", "p.n", "p.e", "p.d", "v.n", "v.e", "v.d", "lon",
                 "lat", "alt", "v.e", "v.n", "v.u")


def _state_floats(sim: Any) -> tuple[float, ...]:
    s = sim.state
    return (s.time_s, *s.position_ned_m, *s.velocity_ned_m_s, *s.quaternion_wxyz,
            *s.angular_velocity_frd_rad_s, *s.motor_speeds_rad_s,
            *sim.specific_force_frd_m_s2, *sim.wind_ned_m_s, sim.altitude_m, sim.agl_m,
            sim.time_s, *sim.motor_thrust)


def _reading_floats(r: Any) -> tuple[float, ...]:
    return (r.time_s, *r.gyro_frd_rad_s, *r.specific_force_frd_m_s2, *r.quaternion_wxyz,
            r.pressure_pa, *r.position_ned_m, *r.velocity_ned_m_s, *r.geodetic,
            *r.velocity_enu_m_s)


def _bits(values: tuple[float, ...]) -> bytes:
    assert all(type(v) is float for v in values), [type(v) for v in values]
    return struct.pack(f"{len(values)}d", *values)


def _first_difference(names: tuple[str, ...], a: tuple[float, ...], b: tuple[float, ...]) -> str:
    out = [f"{name}: {x!r} (python) != {y!r} (kernel)"
           for name, x, y in zip(names, a, b, strict=True) if _bits((x,)) != _bits((y,))]
    return "; ".join(out[:6])


def _outcome(call: Callable[[], Any]) -> tuple[str, str] | None:
    try:
        call()
    except Exception as exc:  # noqa: BLE001 - the same exception, whatever it is
        return (type(exc).__name__, str(exc))
    return None


class Pair:
    """A reference and a kernel simulator, driven alike and compared after each action."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.py = Simulator(*args, **kwargs)
        self.k = KernelSimulator(*args, **kwargs)
        self.steps = 0
        self.check("construction")

    def check(self, where: str) -> None:
        a, b = _state_floats(self.py), _state_floats(self.k)
        assert _bits(a) == _bits(b), f"{where}: {_first_difference(STATE_NAMES, a, b)}"
        flags = (self.py.on_ground, self.py.at_rest, self.py.held, self.py.state.on_ground)
        assert flags == (self.k.on_ground, self.k.at_rest, self.k.held, self.k.state.on_ground), \
            where
        assert self.py.specific_force_frd_m_s2 == self.k.specific_force_frd_m_s2

    def read(self, where: str) -> None:
        ra, rb = _outcome(self.py.read_sensors), _outcome(self.k.read_sensors)
        assert ra == rb, where
        if ra is not None:
            return
        a, b = _reading_floats(self.py.read_sensors()), _reading_floats(self.k.read_sensors())
        assert _bits(a) == _bits(b), f"{where}: {_first_difference(READING_NAMES, a, b)}"
        assert self.k.read_sensors() is self.k.read_sensors()  # cached until the next step

    def step(self, motors: Any, dt_s: float = 0.001, read: bool = True) -> None:
        self.py.step(motors, dt_s)
        self.k.step(motors, dt_s)
        self.steps += 1
        where = f"step {self.steps} (t={self.py.time_s:.4f}, motors {motors}, dt {dt_s})"
        self.check(where)
        if read:
            self.read(where)

    def run(self, motors: Any, n: int, dt_s: float = 0.001, read: bool = True) -> None:
        for _ in range(n):
            self.step(motors, dt_s, read)

    def both(self, method: str, *args: Any, **kwargs: Any) -> tuple[str, str] | None:
        """Call a method on both; the same outcome (or the same error) and the same state."""
        a = _outcome(lambda: getattr(self.py, method)(*args, **kwargs))
        b = _outcome(lambda: getattr(self.k, method)(*args, **kwargs))
        assert a == b, f"{method}{args}{kwargs}: {a} (python) != {b} (kernel)"
        self.check(f"after {method}{args}{kwargs}")
        return a


# ---- on the ground ---------------------------------------------------------------------------


def test_parked_at_rest_then_take_off_climb_and_land_again():
    pair = Pair(IRIS, seed=3)
    assert pair.k.at_rest and pair.k.on_ground
    pair.run((0.0, 0.0, 0.0, 0.0), 200)
    pair.run((0.3, 0.3, 0.3, 0.3), 200)  # spinning up: still at rest
    assert pair.k.at_rest
    # The right-hand rotors alone: the centre of pressure leaves the skids, it tips.
    pair.run((0.7, 0.7, 0.0, 0.0), 150)
    assert not pair.k.at_rest
    pair.both("reset")
    pair.run((0.62, 0.62, 0.62, 0.62), 1500)
    assert not pair.k.on_ground
    pair.run((HOVER, HOVER + 0.01, HOVER, HOVER - 0.01), 300)
    pair.run((0.45, 0.45, 0.45, 0.45), 2000)  # comes down hard: it flips onto its top
    pair.run((0.0, 0.0, 0.0, 0.0), 500, read=False)
    assert pair.k.on_ground and not pair.k.at_rest
    # A gentle drop settles on the skids and freezes.
    pair.both("reset", (0.0, 0.0, -0.5), yaw_deg=20.0, velocity_ned_m_s=(0.3, 0.0, 0.5))
    pair.run((0.2, 0.2, 0.2, 0.2), 800)
    assert pair.k.at_rest
    # Parked level but moving or turning: not at rest until friction has stopped it.
    pair.both("reset", None, velocity_ned_m_s=(0.5, 0.0, 0.0))
    assert not pair.k.at_rest
    pair.run((0.0, 0.0, 0.0, 0.0), 300)
    pair.both("reset", None, angular_velocity_frd_rad_s=(0.0, 0.0, 2.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 300)
    pair.both("reset", None, velocity_ned_m_s=(0.0, 0.0, -0.2),
              angular_velocity_frd_rad_s=(0.0, 0.3, 0.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 300)
    pair.both("reset", None, angular_velocity_frd_rad_s=(-0.3, 0.0, 0.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 300)
    # Landing while spinning about yaw.
    pair.both("reset", (0.0, 0.0, -0.3), angular_velocity_frd_rad_s=(0.0, 0.0, 6.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 600)


def test_hard_sliding_and_tilted_landings():
    pair = Pair(IRIS, sensors=SensorConfig.typical_mems(), seed=7)
    pair.both("reset", (0.0, 0.0, -3.0), roll_deg=20.0, pitch_deg=-10.0, yaw_deg=30.0,
              velocity_ned_m_s=(3.0, -1.0, 6.0), angular_velocity_frd_rad_s=(0.5, -1.0, 2.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 1200)
    # A tilted pose parked on its lowest corners, nothing moving: the friction sees exactly
    # zero sliding speed.
    pair.both("reset", None, roll_deg=35.0, yaw_deg=-120.0)
    pair.run((0.1, 0.0, 0.1, 0.0), 600)
    # Sliding in fast, nearly level.
    pair.both("reset", (0.0, 0.0, -0.5), velocity_ned_m_s=(-8.0, 5.0, 2.0),
              motor_speeds_rad_s=(400.0, 420.0, 380.0, 400.0))
    pair.run((0.2, 0.2, 0.2, 0.2), 1500, read=False)


def test_tip_overs_onto_the_top_corners():
    pair = Pair(IRIS, seed=11)
    # Upside down, dropped: the top face's corners take the landing.
    pair.both("reset", (0.0, 0.0, -0.6), roll_deg=180.0, velocity_ned_m_s=(0.0, 0.0, 2.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 800)
    # On its side, tumbling.
    pair.both("reset", None, roll_deg=88.0, angular_velocity_frd_rad_s=(4.0, 0.0, 1.0))
    pair.run((0.0, 0.0, 0.0, 0.0), 600)
    # Flipping over on landing with full power on one side.
    pair.both("reset", (0.0, 0.0, -0.4), pitch_deg=50.0, velocity_ned_m_s=(0.0, 0.0, 3.0))
    pair.run((1.0, 0.0, 1.0, 0.0), 400)
    pair.run((0.0, 0.0, 0.0, 0.0), 800, read=False)


def test_slippery_ground_and_other_vehicle_parameters():
    params = dataclasses.replace(IRIS, axial_inflow=False, friction_coefficient=0.05,
                                 contact_damping_ratio=0.3, mass_kg=1.2)
    home = GeoPoint(47.3977, 8.5456, 488.0)
    pair = Pair(params, wind=Wind((12.0, -6.0, 0.0)), home=home, seed=2)
    pair.run((0.0, 0.0, 0.0, 0.0), 600)  # the wind pushes it along the ice
    pair.run((0.9, 0.9, 0.9, 0.9), 600)
    pair.run((0.3, 0.3, 0.3, 0.3), 800, read=False)


# ---- in the air ------------------------------------------------------------------------------


def test_random_commands_with_noisy_sensors_and_gps():
    sensors = dataclasses.replace(SensorConfig.typical_mems().with_typical_gps(),
                                  gyro_bias_rad_s=(0.01, -0.02, 0.003),
                                  accel_bias_m_s2=(0.1, 0.0, -0.05), baro_bias_pa=4.0,
                                  gps_offset_ne_m=(0.7, -0.3), baro_drift_pa_s=0.3)
    pair = Pair(IRIS, sensors=sensors, home=GeoPoint(-33.0, 151.0, 30.0), seed=123)
    pair.both("reset", (5.0, -3.0, -20.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    rng = random.Random(99)
    for i in range(2500):
        motors = tuple(HOVER + rng.uniform(-0.3, 0.3) for _ in range(4))
        if i % 97 == 0:
            motors = (-0.5, 1.7, 0.0, 1.0)  # clamped to 0..1
        pair.step(motors, read=i % 3 != 1)  # a reading skipped now and then: no draw then


def test_fast_climbs_dives_and_tumbles_take_the_inflow_limits_and_the_large_angle_step():
    pair = Pair(IRIS, seed=4)
    # Diving fast onto spinning rotors: the descent thrust gain stalls at its cap.
    pair.both("reset", (0.0, 0.0, -300.0), velocity_ned_m_s=(0.0, 0.0, 25.0),
              motor_speeds_rad_s=(500.0,) * 4)
    pair.run((0.8, 0.8, 0.8, 0.8), 300)
    # Climbing fast on slow rotors: the thrust would go negative and is clamped at zero.
    pair.both("reset", (0.0, 0.0, -100.0), velocity_ned_m_s=(0.0, 0.0, -30.0),
              motor_speeds_rad_s=(50.0,) * 4)
    pair.run((0.0, 0.1, 0.0, 0.1), 300)
    # Tumbling fast with long steps: the exact exponential map (half angle > 0.1 rad).
    pair.both("reset", (0.0, 0.0, -200.0), angular_velocity_frd_rad_s=(60.0, -20.0, 35.0))
    pair.run((1.0, 0.0, 0.0, 1.0), 200, dt_s=0.004)
    pair.run((0.5, 0.5, 0.5, 0.5), 50, dt_s=0.02)


def test_wind_gusts_and_changes_mid_flight():
    pair = Pair(IRIS, wind=Wind((3.0, -2.0, 0.5), gust_std_m_s=1.5, gust_time_constant_s=0.5),
                seed=21)
    pair.run((0.0, 0.0, 0.0, 0.0), 300)
    pair.run((0.7, 0.7, 0.7, 0.7), 700)
    pair.both("set_wind", Wind.from_direction(8.0, 45.0, gust_std_m_s=3.0))
    pair.run((HOVER, HOVER, HOVER, HOVER), 500)
    pair.both("set_wind", None)
    pair.run((HOVER, HOVER, HOVER, HOVER), 200)
    pair.both("set_wind", Wind((0.0, 5.0, 0.0)))  # constant: no gust draws
    pair.run((HOVER, HOVER, HOVER, HOVER), 200, dt_s=0.0005)
    pair.both("set_wind", Wind((1.0, 1.0, 0.0), gust_std_m_s=0.5))
    pair.run((0.4, 0.4, 0.4, 0.4), 800, dt_s=0.002)
    assert pair.k.wind == pair.py.wind


def test_sensor_changes_mid_flight_drift_offsets_and_repeated_reads():
    pair = Pair(IRIS, seed=5)
    pair.both("reset", (0.0, 0.0, -10.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    hover = (HOVER,) * 4
    pair.run(hover, 200)
    pair.both("set_sensors", SensorConfig(baro_drift_pa_s=-2.5, gps_offset_ne_m=(3.0, -1.5)))
    pair.read("after set_sensors")
    pair.read("read twice")
    pair.run(hover, 300)
    pair.both("set_sensors", SensorConfig(gps_noise_std_m=0.5, gps_velocity_noise_std_m_s=0.2,
                                          accel_bias_m_s2=(0.0, 0.2, 0.0)))
    pair.run(hover, 300)
    pair.both("set_sensors", SensorConfig.typical_mems().with_typical_gps())
    pair.run(hover, 300, read=False)
    pair.run(hover, 300)
    # A reset changes no time: the GPS wander does not move, its noise is drawn again.
    pair.both("reset", (0.0, 0.0, -5.0), yaw_deg=90.0)
    pair.read("after reset")
    # Hovering over home (north and east exactly 0), every GPS error term shows in the fix.
    pair.both("set_sensors", SensorConfig(gyro_bias_rad_s=(0.1, 0.0, 0.0), baro_bias_pa=-3.0,
                                          gps_drift_std_m=1.0, gps_drift_time_s=2.0,
                                          gps_offset_ne_m=(0.25, 0.5), gps_noise_std_m=0.1))
    pair.run(hover, 300)
    pair.both("set_sensors", SensorConfig())
    pair.run(hover, 100)
    assert pair.k.sensor_config == pair.py.sensor_config


def test_resets_holds_motor_faults_and_step_lengths():
    pair = Pair(IRIS, sensors=SensorConfig.typical_mems(), seed=8)
    pair.run((0.7, 0.7, 0.7, 0.7), 500)
    pair.both("reset", (0.0, 0.0, -15.0), quaternion_wxyz=(0.9, 0.2, -0.3, 0.1),
              velocity_ned_m_s=(2.0, -1.0, 0.5), angular_velocity_frd_rad_s=(0.3, 0.2, -0.4),
              motor_speeds_rad_s=(300.0, 310.0, 320.0, 330.0))
    pair.run((HOVER,) * 4, 300, dt_s=0.0005)
    pair.both("hold")
    pair.read("held")
    pair.run((0.9, 0.1, 0.5, 0.3), 200)
    pair.both("hold", False)
    pair.run((HOVER,) * 4, 300)
    pair.both("set_motor_thrust", 2, 0.6)
    pair.run((HOVER,) * 4, 400, dt_s=0.004)
    pair.both("set_motor_thrust", 4, 0.0)
    pair.run((HOVER,) * 4, 300)
    pair.both("set_motor_thrust", 2, 1.0)
    pair.both("set_motor_thrust", 4, 1)
    pair.run((0.6,) * 4, 200, dt_s=0.003)
    pair.run((0.6,) * 4, 100, dt_s=0.001)
    # Held while parked, then let go; put somewhere else while held.
    pair.both("reset")
    pair.both("hold", True)
    pair.run((0.8,) * 4, 100)
    pair.both("hold", False)
    pair.run((0.8,) * 4, 300)
    pair.both("hold", 1)
    pair.both("reset", (0.0, 0.0, -3.0), roll_deg=10.0, velocity_ned_m_s=(1.0, 0.0, 0.0))
    pair.run((0.8,) * 4, 50)
    pair.both("hold", 0)
    pair.run((0.8,) * 4, 100)
    assert pair.k.motor_thrust == pair.py.motor_thrust


# ---- invalid inputs ----------------------------------------------------------------------------


@pytest.mark.parametrize(("motors", "dt_s"), [
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
])
def test_invalid_steps_raise_the_same_error_and_change_nothing(motors, dt_s):
    pair = Pair(IRIS, sensors=SensorConfig.typical_mems(), wind=Wind((1.0, 0.0, 0.0), 1.0),
                seed=1)
    pair.run((0.7,) * 4, 30)
    assert pair.both("step", motors, dt_s) is not None
    pair.run((0.7,) * 4, 30)  # and the generators went on alike


def test_other_number_types_step_alike():
    pair = Pair(IRIS, seed=1)
    pair.run([1, 0, True, 0.5], 20)
    pair.run((1e308, 1e308, 1e308, 1e308), 20)  # the sum overflows; each command is finite
    pair.run((0.6, 0.6, 0.6, 0.6), 20, dt_s=0.02)


@pytest.mark.parametrize(("method", "args", "kwargs"), [
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
])
def test_invalid_resets_and_faults_raise_the_same_error_and_change_nothing(method, args, kwargs):
    pair = Pair(IRIS, sensors=SensorConfig.typical_mems().with_typical_gps(), seed=6)
    pair.run((0.7,) * 4, 30)
    assert pair.both(method, *args, **kwargs) is not None
    pair.run((0.7,) * 4, 30)


def test_a_drifting_barometer_from_the_start():
    pair = Pair(IRIS, sensors=SensorConfig(baro_drift_pa_s=1.5, baro_noise_std_pa=0.5), seed=2)
    pair.run((0.0,) * 4, 100, read=False)
    pair.run((0.0,) * 4, 100)


def test_below_the_atmosphere_model_the_readings_fail_alike():
    pair = Pair(IRIS, home=GeoPoint(0.0, 0.0, -1000.5), seed=2)
    assert pair.both("read_sensors") is not None
    pair.run((0.7,) * 4, 600, read=False)
    pair.read("lifted off into the model")


def test_leaving_the_atmosphere_model_raises_the_same_error_without_a_draw():
    pair = Pair(IRIS, sensors=SensorConfig.typical_mems().with_typical_gps(),
                home=GeoPoint(10.0, 20.0, 19995.0), seed=9)
    pair.both("reset", (0.0, 0.0, -4.0), motor_speeds_rad_s=(IRIS.hover_rotor_speed_rad_s,) * 4)
    pair.run((0.75,) * 4, 400)
    pair.run((0.75,) * 4, 200, read=False)  # through 20 km MSL: the readings would fail
    assert pair.both("read_sensors") is not None
    pair.both("reset", (0.0, 0.0, -1.0))
    pair.run((0.0,) * 4, 50)


# ---- the C face --------------------------------------------------------------------------------


class _Reading(ctypes.Structure):
    _fields_ = [("values", ctypes.c_double * 24)]


def test_stepping_through_the_c_api_gives_the_same_flight():
    """What the compiled lockstep loop does: bk_read_sensors, bk_step, bk_time_s on the
    pointer; Python then sees that state."""
    sim = KernelSimulator(IRIS, sensors=SensorConfig.typical_mems().with_typical_gps(),
                          wind=Wind((2.0, 0.0, 0.0), 1.0), seed=12)
    ref = Simulator(IRIS, sensors=SensorConfig.typical_mems().with_typical_gps(),
                    wind=Wind((2.0, 0.0, 0.0), 1.0), seed=12)
    lib = sim.kernel_library
    step = lib["bk_step"]
    step.restype, step.argtypes = ctypes.c_int, [ctypes.c_void_p, ctypes.c_double * 4,
                                                 ctypes.c_double]
    read = lib["bk_read_sensors"]
    read.restype, read.argtypes = ctypes.POINTER(_Reading), [ctypes.c_void_p]
    time_s = lib["bk_time_s"]
    time_s.restype, time_s.argtypes = ctypes.c_double, [ctypes.c_void_p]
    rng = random.Random(1)
    for i in range(600):
        motors = tuple(0.6 + rng.uniform(-0.1, 0.1) for _ in range(4))
        reading = read(sim.kernel_pointer)
        assert tuple(reading.contents.values) == _reading_floats(ref.read_sensors())
        assert ctypes.addressof(read(sim.kernel_pointer).contents) == \
            ctypes.addressof(reading.contents)  # the same until the next step
        if i % 50 == 0:  # Python reads the reading C computed: no second draw
            assert _reading_floats(sim.read_sensors()) == _reading_floats(ref.read_sensors())
        assert step(sim.kernel_pointer, (ctypes.c_double * 4)(*motors), 0.001) == 0
        ref.step(motors, 0.001)
        assert time_s(sim.kernel_pointer) == ref.time_s
        assert _bits(_state_floats(sim)) == _bits(_state_floats(ref))
    bad = (ctypes.c_double * 4)(0.5, math.nan, 0.5, 0.5)
    before = _state_floats(sim)
    assert step(sim.kernel_pointer, bad, 0.001) != 0
    assert step(sim.kernel_pointer, (ctypes.c_double * 4)(0.5, 0.5, 0.5, 0.5), 0.05) != 0
    assert _bits(_state_floats(sim)) == _bits(before)


def test_the_kernel_simulator_answers_what_the_package_asks():
    sim = KernelSimulator(seed=3)
    assert sim.params is IRIS
    assert sim.home == GeoPoint(0.0, 0.0, 0.0)
    assert sim.wind is None and sim.wind_ned_m_s == (0.0, 0.0, 0.0)
    assert sim.sensor_config == SensorConfig()
    assert isinstance(sim.kernel_pointer, int) and sim.kernel_pointer
    assert sim.agl_m == sim.altitude_m
    assert sim.motor_thrust == (1.0, 1.0, 1.0, 1.0)
