"""The compiled simulator: :class:`bfsitl.physics.Simulator`'s numbers, computed in C.

:class:`KernelSimulator` has the reference simulator's constructor, properties and methods
and gives the same floats, bit for bit, at every step (``tests/unit/kernel``).  The state and
the arithmetic live in a C structure (``physics.h``); Python keeps only what a caller asks back
(the parameters, the sensor configuration, the wind) and the input checks.

The checks and the constants are the reference's own: each KernelSimulator holds a private
reference :class:`~bfsitl.physics.Simulator` that it never steps.  It validates ``reset`` and
``set_motor_thrust`` (so the errors are word for word the same), and it computed the cached
constants, the home projection and the seeded random generators (the sensors' two and the
wind's, with the gust the wind draws at construction) that are copied into C.  The C side
carries on those generators' sequences (CPython's Mersenne Twister and ``gauss``).
"""

from __future__ import annotations

import ctypes
import random
import struct
from functools import lru_cache
from typing import Any

from bfsitl.kernel.compiler import load_kernel
from bfsitl.physics.atmosphere import isa_pressure_pa
from bfsitl.physics.frames import GeoPoint
from bfsitl.physics.multirotor import (
    Simulator,
    VehicleState,
    _rotate_inverse,
    check_step_input,
)
from bfsitl.physics.params import IRIS, Motors, QuadParams, Quat, SimInputError, Vec3
from bfsitl.physics.sensors import SensorConfig, SensorModel, SensorReading
from bfsitl.physics.wind import Wind, WindField

_D2 = ctypes.c_double * 2
_D3 = ctypes.c_double * 3
_D4 = ctypes.c_double * 4
_I32 = ctypes.c_int32


class _Rng(ctypes.Structure):
    """``bk_rng``: a random.Random's state."""

    _fields_ = [
        ("mt", ctypes.c_uint32 * 624),
        ("index", _I32),
        ("has_gauss_next", _I32),
        ("gauss_next", ctypes.c_double),
    ]


class _Reading(ctypes.Structure):
    """``bk_reading``: SensorReading's fields, 24 doubles."""

    _fields_ = [
        ("time_s", ctypes.c_double),
        ("gyro_frd_rad_s", _D3),
        ("specific_force_frd_m_s2", _D3),
        ("quaternion_wxyz", _D4),
        ("pressure_pa", ctypes.c_double),
        ("position_ned_m", _D3),
        ("velocity_ned_m_s", _D3),
        ("geodetic", _D3),
        ("velocity_enu_m_s", _D3),
    ]


class _Sim(ctypes.Structure):
    """``bk_sim`` of physics.h, field for field."""

    _fields_ = [
        # the vehicle's state: t .. om_dot are read as one block (_STATE)
        ("t", ctypes.c_double), ("p", _D3), ("v", _D3), ("q", _D4), ("w", _D3), ("om", _D4),
        ("sf_world", _D3), ("om_dot", _D4), ("t_err", ctypes.c_double), ("thrust_scale", _D4),
        ("resting", _I32), ("held", _I32), ("touching", _I32), ("on_skids", _I32),
        ("n_sub", _I32), ("reading_valid", _I32), ("reading_gen", ctypes.c_uint64),
        # Simulator._set_step's cache
        ("dt", ctypes.c_double), ("alpha", ctypes.c_double), ("stick", ctypes.c_double),
        # Simulator._cache_constants
        ("m", ctypes.c_double), ("inv_m", ctypes.c_double), ("j", _D3), ("g", ctypes.c_double),
        ("rotors", _D3 * 4), ("kf", ctypes.c_double), ("kq", ctypes.c_double),
        ("ir", ctypes.c_double), ("inflow_inv_m", ctypes.c_double),
        ("stall_ratio", ctypes.c_double), ("drive", ctypes.c_double),
        ("b_motor", ctypes.c_double), ("damp", ctypes.c_double), ("tau_max", ctypes.c_double),
        ("lin", _D3), ("quad", _D3), ("box", _D4), ("k", ctypes.c_double),
        ("c", ctypes.c_double), ("mu", ctypes.c_double), ("reach", ctypes.c_double),
        ("rate", ctypes.c_double), ("w_t", ctypes.c_double), ("motor_tau", ctypes.c_double),
        ("inflow", _I32), ("wind_on", _I32),
        # home and its projection
        ("home_lon", ctypes.c_double), ("home_lat", ctypes.c_double),
        ("home_alt", ctypes.c_double), ("deg_per_east", ctypes.c_double),
        ("deg_per_north", ctypes.c_double),
        # WindField
        ("wind_base", _D3), ("wind_std", ctypes.c_double), ("wind_tau", ctypes.c_double),
        ("gust", _D3), ("wind_dt", ctypes.c_double), ("wind_decay", ctypes.c_double),
        ("wind_kick", ctypes.c_double),
        # SensorModel
        ("ideal", _I32), ("gps_errors", _I32), ("has_gps_time", _I32),
        ("has_drift_origin", _I32),
        ("gyro_std", ctypes.c_double), ("gyro_bias", _D3), ("accel_std", ctypes.c_double),
        ("accel_bias", _D3), ("baro_std", ctypes.c_double), ("baro_bias", ctypes.c_double),
        ("baro_drift", ctypes.c_double), ("gps_drift_std", ctypes.c_double),
        ("gps_drift_time", ctypes.c_double), ("gps_noise_std", ctypes.c_double),
        ("gps_vel_std", ctypes.c_double), ("gps_offset", _D2),
        ("gps_drift", _D2), ("gps_time", ctypes.c_double), ("drift_origin", ctypes.c_double),
        ("wind_rng", _Rng), ("rng", _Rng), ("gps_rng", _Rng),
        ("reading", _Reading),
    ]


#: The fields whose offsets bk_sim_offset(0, 1, ...) reports, in its order.
_CHECKED_OFFSETS = ("t", "om_dot", "thrust_scale", "resting", "reading_gen", "dt", "m",
                    "rotors", "motor_tau", "inflow", "home_lon", "wind_base", "ideal",
                    "gyro_std", "gps_drift", "wind_rng", "rng", "gps_rng", "reading")
#: t, p, v, q, w, om, sf_world, om_dot: the state in one read.
_STATE = struct.Struct("25d")
_READING = struct.Struct("24d")
_READING_OFFSET: int = _Sim.reading.offset


class _Kernel:
    """The library's functions with their C types (private function objects: another user of
    the same library may type its own)."""

    def __init__(self, library: ctypes.CDLL) -> None:
        if library.bk_sim_size() != ctypes.sizeof(_Sim):
            raise RuntimeError("bk_sim and its ctypes mirror differ in size")
        offset = library["bk_sim_offset"]
        offset.restype = ctypes.c_size_t
        offset.argtypes = [ctypes.c_int]
        for index, name in enumerate(_CHECKED_OFFSETS):
            if offset(index) != getattr(_Sim, name).offset:
                raise RuntimeError(f"bk_sim and its ctypes mirror differ at {name}")
        self.library = library
        pointer, double = ctypes.c_void_p, ctypes.c_double
        self.step = library["bk_step4"]
        self.step.restype = ctypes.c_int
        self.step.argtypes = [pointer, double, double, double, double, double]
        self.read = library["bk_read_sensors"]
        self.read.restype = pointer
        self.read.argtypes = [pointer]
        self.reset = library["bk_reset"]
        self.reset.restype = None
        self.reset.argtypes = [pointer, _D4, _D3, _D3, _D3, _D4]
        self.hold = library["bk_hold"]
        self.hold.restype = None
        self.hold.argtypes = [pointer, ctypes.c_int]


@lru_cache(maxsize=4)
def _kernel(library: ctypes.CDLL) -> _Kernel:
    return _Kernel(library)


def _copy_rng(target: _Rng, source: random.Random) -> None:
    _version, words, gauss_next = source.getstate()
    target.mt[:] = words[:624]
    target.index = words[624]
    target.has_gauss_next = gauss_next is not None
    target.gauss_next = gauss_next if gauss_next is not None else 0.0


class KernelSimulator:
    """:class:`bfsitl.physics.Simulator` with its state and step in C (same API, same bits).

    ``kernel_pointer`` is the address of the C ``bk_sim`` (for C code that steps it, such as
    the compiled lockstep loop) and ``kernel_library`` the library it belongs to.  Whoever
    steps it in C sees the same object from Python: every property reads the C state.
    Raises :class:`~bfsitl.errors.KernelUnavailableError` when the kernel cannot be built.
    """

    __slots__ = ("params", "sensor_config", "wind", "home", "_seed", "_ref", "_kernel",
                 "_sim", "_ptr", "_step", "_read", "_time", "_valid", "_gen", "_reading",
                 "_reading_gen")

    def __init__(
        self,
        params: QuadParams = IRIS,
        sensors: SensorConfig | None = None,
        wind: Wind | None = None,
        home: GeoPoint | None = None,
        seed: int = 0,
    ) -> None:
        kernel = _kernel(load_kernel())
        # The reference computes every constant and starts every generator; it is never
        # stepped, only asked to check inputs.
        ref = Simulator(params, sensors, wind, home, seed)
        self._ref = ref
        self.params = ref.params
        self.sensor_config = ref.sensor_config
        self.wind = ref.wind
        self.home = ref.home
        self._seed = seed
        self._kernel = kernel
        self._sim = sim = _Sim()
        self._ptr: int = ctypes.addressof(sim)
        self._step = kernel.step
        self._read = kernel.read
        self._time = ctypes.c_double.from_buffer(sim, _Sim.t.offset)
        self._valid = _I32.from_buffer(sim, _Sim.reading_valid.offset)
        self._gen = ctypes.c_uint64.from_buffer(sim, _Sim.reading_gen.offset)
        self._reading: SensorReading | None = None
        self._reading_gen = -1
        self._copy_constants(ref)
        sim.thrust_scale[:] = ref.motor_thrust
        sim.dt, sim.n_sub = -1.0, 1
        sim.t = sim.t_err = 0.0
        sim.held = 0
        self._load_wind(ref._wind)
        self._load_sensors(ref._sensors)
        self._load_pose()

    def _copy_constants(self, ref: Simulator) -> None:
        sim, p = self._sim, ref.params
        sim.m, sim.inv_m, sim.j[:], sim.g = ref._m, ref._inv_m, ref._j, ref._g
        for i, rotor in enumerate(ref._rotors):
            sim.rotors[i][:] = rotor
        sim.kf, sim.kq, sim.ir = ref._kf, ref._kq, ref._ir
        sim.inflow = bool(ref._inflow)
        sim.inflow_inv_m, sim.stall_ratio = ref._inflow_inv_m, ref._stall_ratio
        sim.drive, sim.b_motor, sim.damp = ref._drive, ref._b_motor, ref._damp
        sim.tau_max, sim.lin[:], sim.quad[:] = ref._tau_max, ref._lin, ref._quad
        sim.box[:] = ref._box
        sim.k, sim.c, sim.mu = ref._k, ref._c, ref._mu
        sim.reach, sim.rate, sim.w_t = ref._reach, ref._rate, ref._w_t
        sim.motor_tau = p.motor_time_constant_s
        home, geo = ref.home, ref._geo
        sim.home_lon, sim.home_lat = float(home.lon_deg), float(home.lat_deg)
        sim.home_alt = float(home.alt_m)
        sim.deg_per_east, sim.deg_per_north = geo._deg_per_east_m, geo._deg_per_north_m

    def _load_wind(self, field: WindField | None) -> None:
        sim = self._sim
        if field is None:
            sim.wind_on = 0
            return
        sim.wind_base[:] = field._base
        sim.wind_std, sim.wind_tau = field._std, field._tau
        sim.gust[:] = field._gust
        sim.wind_dt, sim.wind_decay, sim.wind_kick = field._dt, field._decay, field._kick
        _copy_rng(sim.wind_rng, field._rng)
        sim.wind_on = 1

    def _load_config(self, config: SensorConfig) -> None:
        ideal, gps_errors = config.is_ideal, config.has_gps_error
        sim = self._sim
        sim.ideal, sim.gps_errors = ideal, gps_errors
        sim.gyro_std, sim.gyro_bias[:] = config.gyro_noise_std_rad_s, config.gyro_bias_rad_s
        sim.accel_std, sim.accel_bias[:] = config.accel_noise_std_m_s2, config.accel_bias_m_s2
        sim.baro_std, sim.baro_bias = config.baro_noise_std_pa, config.baro_bias_pa
        sim.baro_drift = config.baro_drift_pa_s
        sim.gps_drift_std, sim.gps_drift_time = config.gps_drift_std_m, config.gps_drift_time_s
        sim.gps_noise_std = config.gps_noise_std_m
        sim.gps_vel_std = config.gps_velocity_noise_std_m_s
        sim.gps_offset[:] = config.gps_offset_ne_m
        sim.reading_valid = 0

    def _load_sensors(self, model: SensorModel) -> None:
        sim = self._sim
        self._load_config(model.config)
        sim.gps_drift[:] = model._gps_drift
        sim.has_gps_time = model._gps_time_s is not None
        sim.gps_time = model._gps_time_s or 0.0
        sim.has_drift_origin = model._drift_origin_s is not None
        sim.drift_origin = model._drift_origin_s or 0.0
        _copy_rng(sim.rng, model._rng)
        _copy_rng(sim.gps_rng, model._gps_rng)

    def _load_pose(self) -> None:
        """The reference's pose after its reset, into C (which works out the rest)."""
        ref = self._ref
        self._kernel.reset(self._ptr, _D4(*ref._q), _D3(*ref._p), _D3(*ref._v), _D3(*ref._w),
                           _D4(*ref._om))

    # ---- the compiled side ----------------------------------------------------------------

    @property
    def kernel_pointer(self) -> int:
        """Address of the C ``bk_sim`` (alive as long as this object)."""
        return self._ptr

    @property
    def kernel_library(self) -> ctypes.CDLL:
        return self._kernel.library

    # ---- public state ---------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Simulated time (s) since construction (``reset`` leaves it alone)."""
        return self._time.value

    @property
    def altitude_m(self) -> float:
        """Height of the centre of mass above the ground plane (m, up positive)."""
        return -self._sim.p[2]

    agl_m = altitude_m

    @property
    def on_ground(self) -> bool:
        """True while any corner of the contact box touches the ground."""
        sim = self._sim
        return bool(sim.resting) or sim.touching > 0

    @property
    def at_rest(self) -> bool:
        """True while parked on the skids under static friction (the body is frozen)."""
        return bool(self._sim.resting)

    @property
    def held(self) -> bool:
        return bool(self._sim.held)

    @property
    def wind_ned_m_s(self) -> Vec3:
        """Current air velocity (constant + gust), m/s NED."""
        sim = self._sim
        if not sim.wind_on:
            return (0.0, 0.0, 0.0)
        b, g = sim.wind_base, sim.gust
        return (b[0] + g[0], b[1] + g[1], b[2] + g[2])

    @property
    def state(self) -> VehicleState:
        s = _STATE.unpack_from(self._sim)
        return VehicleState(s[0], (s[1], s[2], s[3]), (s[4], s[5], s[6]),
                            (s[7], s[8], s[9], s[10]), (s[11], s[12], s[13]),
                            (s[14], s[15], s[16], s[17]), self.on_ground)

    @property
    def specific_force_frd_m_s2(self) -> Vec3:
        """What an ideal accelerometer reads now, body FRD (no noise, no random draw)."""
        s = _STATE.unpack_from(self._sim)
        return _rotate_inverse((s[7], s[8], s[9], s[10]), (s[18], s[19], s[20]))

    # ---- control ----------------------------------------------------------------------------

    def hold(self, enabled: bool = True) -> None:
        """Freeze the pose (a test stand): see :meth:`bfsitl.physics.Simulator.hold`."""
        self._kernel.hold(self._ptr, bool(enabled))

    def reset(
        self,
        position_ned_m: Vec3 | None = None,
        *,
        quaternion_wxyz: Quat | None = None,
        roll_deg: float = 0.0,
        pitch_deg: float = 0.0,
        yaw_deg: float = 0.0,
        velocity_ned_m_s: Vec3 = (0.0, 0.0, 0.0),
        angular_velocity_frd_rad_s: Vec3 = (0.0, 0.0, 0.0),
        motor_speeds_rad_s: Motors = (0.0, 0.0, 0.0, 0.0),
    ) -> None:
        """Put the vehicle somewhere: see :meth:`bfsitl.physics.Simulator.reset`."""
        # The reference checks everything (and raises its own errors) before changing a thing.
        self._ref.reset(position_ned_m, quaternion_wxyz=quaternion_wxyz, roll_deg=roll_deg,
                        pitch_deg=pitch_deg, yaw_deg=yaw_deg, velocity_ned_m_s=velocity_ned_m_s,
                        angular_velocity_frd_rad_s=angular_velocity_frd_rad_s,
                        motor_speeds_rad_s=motor_speeds_rad_s)
        self._load_pose()

    # ---- the step -----------------------------------------------------------------------------

    def step(self, motors: Motors, dt_s: float) -> None:
        """Advance ``dt_s`` seconds with the motor commands held (zero-order hold, as Gazebo)."""
        try:
            u1, u2, u3, u4 = motors
            refused = self._step(self._ptr, u1, u2, u3, u4, dt_s)
        except (TypeError, ValueError, ctypes.ArgumentError):
            refused = 1
        if refused:
            self._step_checked(motors, dt_s)

    def _step_checked(self, motors: Any, dt_s: Any) -> None:
        """The reference's checks (its errors, word for word), then the step as floats."""
        u1, u2, u3, u4 = check_step_input(motors, dt_s)
        if self._step(self._ptr, float(u1), float(u2), float(u3), float(u4), float(dt_s)):
            raise SimInputError(f"step: the compiled kernel refused motors {motors!r} and "
                                f"dt_s {dt_s!r}")

    # ---- faults (scenarios change these mid-flight, between two steps) -------------------

    @property
    def motor_thrust(self) -> tuple[float, float, float, float]:
        """Each rotor's thrust as a fraction of a healthy one's (Betaflight order M1..M4)."""
        a, b, c, d = self._sim.thrust_scale
        return (a, b, c, d)

    def set_motor_thrust(self, motor: int, fraction: float) -> None:
        """Motor ``motor`` (1..4) gives ``fraction`` of its thrust and drag torque."""
        self._ref.set_motor_thrust(motor, fraction)  # checks, as the reference
        self._sim.thrust_scale[motor - 1] = self._ref.motor_thrust[motor - 1]

    def set_wind(self, wind: Wind | None) -> None:
        """The wind from now on (None: still air); its gusts are drawn afresh from the run's
        seed, so a run stays repeatable."""
        self.wind = wind
        self._load_wind(WindField(wind, self._seed) if wind is not None else None)

    def set_sensors(self, config: SensorConfig) -> None:
        """The sensor errors from now on (the noise generators go on where they were)."""
        self.sensor_config = config
        sim = self._sim
        self._load_config(config)
        sim.drift_origin = sim.t
        sim.has_drift_origin = 1

    # ---- sensors ------------------------------------------------------------------------------

    def read_sensors(self) -> SensorReading:
        """What the IMU and barometer report now (the same object until the next step)."""
        reading = self._reading
        if reading is not None and self._valid.value and self._gen.value == self._reading_gen:
            return reading
        if not self._read(self._ptr):
            # Outside the ISA model: the reference's error.
            isa_pressure_pa(self.home.alt_m - self._sim.p[2])
            raise SimInputError("read_sensors: the compiled kernel refused the altitude")
        r = _READING.unpack_from(self._sim, _READING_OFFSET)
        reading = SensorReading(
            r[0], (r[1], r[2], r[3]), (r[4], r[5], r[6]), (r[7], r[8], r[9], r[10]), r[11],
            (r[12], r[13], r[14]), (r[15], r[16], r[17]), (r[18], r[19], r[20]),
            (r[21], r[22], r[23]),
        )
        self._reading = reading
        self._reading_gen = self._gen.value
        return reading
