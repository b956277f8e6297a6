"""The C structures of the physics (``physics.h``) as ctypes sees them, and its functions typed.

:class:`Sim` mirrors ``bk_sim`` field for field, :class:`Rng` ``bk_rng`` and :class:`Reading`
``bk_reading``.  ``tests/unit/kernel/test_layout.py`` reads the header and fails when a field's
name, type, length or order differ here, and :class:`Kernel` refuses a library whose
structure has another size.  Only :mod:`bfsitl.physics.multirotor` (the physics' Python face)
and the compiled lockstep loop's face use them.
"""

from __future__ import annotations

import ctypes
import random
import struct
from functools import lru_cache

from bfsitl.errors import KernelUnavailableError

D2 = ctypes.c_double * 2
D3 = ctypes.c_double * 3
D4 = ctypes.c_double * 4
_I32 = ctypes.c_int32
_DOUBLE = ctypes.c_double


class Rng(ctypes.Structure):
    """``bk_rng``: a random.Random's state (MT19937's words and position, gauss's cache)."""

    _fields_ = [
        ("mt", ctypes.c_uint32 * 624),
        ("index", _I32),
        ("has_gauss_next", _I32),
        ("gauss_next", _DOUBLE),
    ]


class Reading(ctypes.Structure):
    """``bk_reading``: SensorReading's fields, 24 doubles."""

    _fields_ = [
        ("time_s", _DOUBLE),
        ("gyro_frd_rad_s", D3),
        ("specific_force_frd_m_s2", D3),
        ("quaternion_wxyz", D4),
        ("pressure_pa", _DOUBLE),
        ("position_ned_m", D3),
        ("velocity_ned_m_s", D3),
        ("geodetic", D3),
        ("velocity_enu_m_s", D3),
    ]


class Sim(ctypes.Structure):
    """``bk_sim``, field for field (the header says what each holds)."""

    _fields_ = [
        # the vehicle's state: t .. om_dot are read as one block (STATE)
        ("t", _DOUBLE),
        ("p", D3),
        ("v", D3),
        ("q", D4),
        ("w", D3),
        ("om", D4),
        ("sf_world", D3),
        ("om_dot", D4),
        ("t_err", _DOUBLE),
        ("thrust_scale", D4),
        ("resting", _I32),
        ("held", _I32),
        ("touching", _I32),
        ("on_skids", _I32),
        ("n_sub", _I32),
        ("reading_valid", _I32),
        ("reading_gen", ctypes.c_uint64),
        ("freeze_at_rest", _I32),
        ("padding", _I32),
        # the vehicle, written before bk_init
        ("mass_kg", _DOUBLE),
        ("inertia_kg_m2", D3),
        ("rotor_xy_frd_m", D2 * 4),
        ("rotor_spin_ccw", _I32 * 4),
        ("thrust_coefficient", _DOUBLE),
        ("torque_coefficient", _DOUBLE),
        ("rotor_inertia_kg_m2", _DOUBLE),
        ("motor_command_speed_rad_s", _DOUBLE),
        ("motor_p_gain_nm_s_per_rad", _DOUBLE),
        ("motor_torque_limit_nm", _DOUBLE),
        ("rotor_damping_nm_s_per_rad", _DOUBLE),
        ("motor_time_constant_s", _DOUBLE),
        ("blade_radius_m", _DOUBLE),
        ("blade_pitch_rad", _DOUBLE),
        ("blade_stall_rad", _DOUBLE),
        ("axial_inflow", _I32),
        ("padding2", _I32),
        ("drag_linear_n_s_per_m", D3),
        ("drag_quadratic_n_s2_per_m2", D3),
        ("contact_box_m", D4),
        ("contact_stiffness_n_per_m", _DOUBLE),
        ("contact_damping_n_s_per_m", _DOUBLE),
        ("friction_coefficient", _DOUBLE),
        ("gravity_m_s2", _DOUBLE),
        # the step's cache
        ("dt", _DOUBLE),
        ("alpha", _DOUBLE),
        ("stick", _DOUBLE),
        # derived from the vehicle by bk_init
        ("m", _DOUBLE),
        ("inv_m", _DOUBLE),
        ("j", D3),
        ("g", _DOUBLE),
        ("rotors", D3 * 4),
        ("kf", _DOUBLE),
        ("kq", _DOUBLE),
        ("ir", _DOUBLE),
        ("inflow_inv_m", _DOUBLE),
        ("stall_ratio", _DOUBLE),
        ("drive", _DOUBLE),
        ("b_motor", _DOUBLE),
        ("damp", _DOUBLE),
        ("tau_max", _DOUBLE),
        ("lin", D3),
        ("quad", D3),
        ("box", D4),
        ("k", _DOUBLE),
        ("c", _DOUBLE),
        ("mu", _DOUBLE),
        ("reach", _DOUBLE),
        ("rate", _DOUBLE),
        ("w_t", _DOUBLE),
        ("inflow", _I32),
        ("wind_on", _I32),
        # home and its projection
        ("home_lon", _DOUBLE),
        ("home_lat", _DOUBLE),
        ("home_alt", _DOUBLE),
        ("deg_per_east", _DOUBLE),
        ("deg_per_north", _DOUBLE),
        # wind
        ("wind_base", D3),
        ("wind_std", _DOUBLE),
        ("wind_tau", _DOUBLE),
        ("gust", D3),
        ("wind_dt", _DOUBLE),
        ("wind_decay", _DOUBLE),
        ("wind_kick", _DOUBLE),
        # sensor errors
        ("ideal", _I32),
        ("gps_errors", _I32),
        ("has_gps_time", _I32),
        ("has_drift_origin", _I32),
        ("gyro_std", _DOUBLE),
        ("gyro_bias", D3),
        ("accel_std", _DOUBLE),
        ("accel_bias", D3),
        ("baro_std", _DOUBLE),
        ("baro_bias", _DOUBLE),
        ("baro_drift", _DOUBLE),
        ("gps_drift_std", _DOUBLE),
        ("gps_drift_time", _DOUBLE),
        ("gps_noise_std", _DOUBLE),
        ("gps_vel_std", _DOUBLE),
        ("gps_offset", D2),
        ("gps_drift", D2),
        ("gps_time", _DOUBLE),
        ("drift_origin", _DOUBLE),
        ("wind_rng", Rng),
        ("rng", Rng),
        ("gps_rng", Rng),
        ("reading", Reading),
    ]


#: t, p, v, q, w, om, sf_world, om_dot: the state in one read.
STATE = struct.Struct("25d")
READING = struct.Struct("24d")
READING_OFFSET: int = Sim.reading.offset


class Kernel:
    """The library's physics functions with their C types (private function objects: another
    user of the same library may type its own)."""

    def __init__(self, library: ctypes.CDLL) -> None:
        if library.bk_sim_size() != ctypes.sizeof(Sim):
            raise KernelUnavailableError(
                "the compiled physics' bk_sim and its ctypes mirror (bfsitl.kernel.layout) "
                "differ in size: the two were changed apart"
            )
        self.library = library
        pointer = ctypes.c_void_p
        self.init = library["bk_init"]
        self.init.restype = None
        self.init.argtypes = [pointer]
        self.start_wind = library["bk_start_wind"]
        self.start_wind.restype = None
        self.start_wind.argtypes = [pointer]
        self.lowest_corner_m = library["bk_lowest_corner_m"]
        self.lowest_corner_m.restype = _DOUBLE
        self.lowest_corner_m.argtypes = [pointer, D4]
        self.step = library["bk_step4"]
        self.step.restype = ctypes.c_int
        self.step.argtypes = [pointer, _DOUBLE, _DOUBLE, _DOUBLE, _DOUBLE, _DOUBLE]
        self.read = library["bk_read_sensors"]
        self.read.restype = pointer
        self.read.argtypes = [pointer]
        self.reset = library["bk_reset"]
        self.reset.restype = None
        self.reset.argtypes = [pointer, D4, D3, D3, D3, D4]
        self.hold = library["bk_hold"]
        self.hold.restype = None
        self.hold.argtypes = [pointer, ctypes.c_int]


@lru_cache(maxsize=4)
def kernel(library: ctypes.CDLL) -> Kernel:
    return Kernel(library)


def seed_rng(target: Rng, name: str) -> None:
    """Start ``target`` where ``random.Random(name)`` starts (a string seed is hashed with
    SHA-512, so the sequence does not depend on ``PYTHONHASHSEED``)."""
    _version, words, gauss_next = random.Random(name).getstate()
    target.mt[:] = words[:624]
    target.index = words[624]
    target.has_gauss_next = gauss_next is not None
    target.gauss_next = gauss_next if gauss_next is not None else 0.0
