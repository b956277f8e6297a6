"""The virtual IMU and barometer, and how their readings become an fdm_packet.

Readings are in the physics' frames (``docs/firmware-facts.md#fdm-frames``); how each firmware
generation wants them in the fdm packet is :mod:`bfsitl.sim.fdm_encoding`'s job:

* gyro: body rates in FRD, rad/s;
* accelerometer: **specific force** in FRD, m/s^2 (the sum of non-gravitational forces over
  the mass): level at rest (0, 0, -9.80665), ~0 in free fall;
* quaternion (w, x, y, z) body FRD -> world NED, unit length;
* pressure: ISA at the IMU's altitude above mean sea level, Pa;
* position/velocity: NED metres and m/s, and the same as (longitude, latitude, altitude) and
  ENU m/s for the firmware's virtual GPS.

Noise and bias are off by default (Gazebo's IRIS has none) and, when configured, come from a
seeded generator so that a run is repeatable.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from bfsitl.physics.params import Quat, SimInputError, Vec3


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """Additive sensor errors: a constant bias plus white Gaussian noise per reading.

    Standard deviations are per sample (per physics step), not densities; see
    :meth:`typical_mems` for a conversion from datasheet-style densities.
    """

    gyro_noise_std_rad_s: float = 0.0
    gyro_bias_rad_s: Vec3 = (0.0, 0.0, 0.0)
    accel_noise_std_m_s2: float = 0.0
    accel_bias_m_s2: Vec3 = (0.0, 0.0, 0.0)
    baro_noise_std_pa: float = 0.0
    baro_bias_pa: float = 0.0
    #: GPS horizontal error per axis: a slow wander (first-order Gauss-Markov, standard
    #: deviation ``gps_drift_std_m``, correlation time ``gps_drift_time_s``: what a receiver
    #: without corrections shows over a minute) plus white noise per reading; and white
    #: noise on its horizontal velocity.  The vertical is left alone (the barometer and the
    #: master build's altitude come from the same field).
    gps_drift_std_m: float = 0.0
    gps_drift_time_s: float = 30.0
    gps_noise_std_m: float = 0.0
    gps_velocity_noise_std_m_s: float = 0.0
    #: The barometer's bias grows by this much per second from when the configuration takes
    #: effect (a drifting sensor warming up; negative pascals read as climbing).
    baro_drift_pa_s: float = 0.0
    #: A fixed error on the GPS position, metres north and east (a glitch: a jump when it is
    #: switched on mid-flight).
    gps_offset_ne_m: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        stds = {
            "gyro_noise_std_rad_s": self.gyro_noise_std_rad_s,
            "accel_noise_std_m_s2": self.accel_noise_std_m_s2,
            "baro_noise_std_pa": self.baro_noise_std_pa,
            "gps_drift_std_m": self.gps_drift_std_m,
            "gps_noise_std_m": self.gps_noise_std_m,
            "gps_velocity_noise_std_m_s": self.gps_velocity_noise_std_m_s,
        }
        if not (math.isfinite(self.gps_drift_time_s) and self.gps_drift_time_s > 0):
            raise SimInputError(f"SensorConfig: gps_drift_time_s must be > 0, "
                                f"got {self.gps_drift_time_s}")
        for name, value in stds.items():
            if not (math.isfinite(value) and value >= 0):
                raise SimInputError(f"SensorConfig: {name} must be >= 0, got {value}")
        for name, vector in (("gyro_bias_rad_s", self.gyro_bias_rad_s),
                             ("accel_bias_m_s2", self.accel_bias_m_s2)):
            if len(vector) != 3 or not all(math.isfinite(v) for v in vector):
                raise SimInputError(f"SensorConfig: {name} must be 3 finite numbers, "
                                    f"got {vector!r}")
        for name, number in (("baro_bias_pa", self.baro_bias_pa),
                             ("baro_drift_pa_s", self.baro_drift_pa_s)):
            if not math.isfinite(number):
                raise SimInputError(f"SensorConfig: {name} must be finite, got {number}")
        if len(self.gps_offset_ne_m) != 2 or not all(math.isfinite(v)
                                                     for v in self.gps_offset_ne_m):
            raise SimInputError(f"SensorConfig: gps_offset_ne_m must be 2 finite numbers, "
                                f"got {self.gps_offset_ne_m!r}")

    @property
    def is_ideal(self) -> bool:
        """True when every error is zero: readings are the exact state."""
        return (
            self.gyro_noise_std_rad_s == 0.0 and self.accel_noise_std_m_s2 == 0.0
            and self.baro_noise_std_pa == 0.0 and self.baro_bias_pa == 0.0
            and self.baro_drift_pa_s == 0.0
            and not any(self.gyro_bias_rad_s) and not any(self.accel_bias_m_s2)
            and not self.has_gps_error
        )

    @property
    def has_gps_error(self) -> bool:
        return (self.gps_drift_std_m > 0.0 or self.gps_noise_std_m > 0.0
                or self.gps_velocity_noise_std_m_s > 0.0 or any(self.gps_offset_ne_m))

    def with_typical_gps(self) -> SensorConfig:
        """These errors plus a GPS receiver's without corrections in open sky: 0.15 m of
        wander per axis over 30 s, 3 cm of noise per reading, 5 cm/s on the velocity
        (orders of magnitude from u-blox M8/M10 class modules; a benchmark's "realistic GPS
        noise")."""
        from dataclasses import replace

        return replace(self, gps_drift_std_m=0.15, gps_drift_time_s=30.0, gps_noise_std_m=0.03,
                       gps_velocity_noise_std_m_s=0.05)

    @classmethod
    def typical_mems(cls, sample_rate_hz: float = 1000.0) -> SensorConfig:
        """PX4's gazebo-classic iris IMU noise densities, sampled at ``sample_rate_hz``.

        Gyro 1.8665e-4 rad/s/sqrt(Hz), accelerometer 1.86e-3 m/s^2/sqrt(Hz)
        (docs/firmware-facts.md#px4-iris);
        white noise per sample = density * sqrt(rate).  Baro: 3 Pa (~25 cm), a typical MEMS
        barometer's RMS noise.  No bias: Betaflight calibrates neither in SITL.
        """
        root = math.sqrt(sample_rate_hz)
        return cls(
            gyro_noise_std_rad_s=1.8665e-4 * root,
            accel_noise_std_m_s2=1.86e-3 * root,
            baro_noise_std_pa=3.0,
        )


@dataclass(frozen=True, slots=True)
class SensorReading:
    """What the virtual sensors report at ``time_s`` (see the module docstring for frames)."""

    time_s: float
    gyro_frd_rad_s: Vec3
    specific_force_frd_m_s2: Vec3
    quaternion_wxyz: Quat
    pressure_pa: float
    position_ned_m: Vec3
    velocity_ned_m_s: Vec3
    #: (longitude deg, latitude deg, altitude m MSL): the order the -DUSE_GPS SITL reads.
    geodetic: Vec3
    velocity_enu_m_s: Vec3


#: What the GPS error adds without one.
_NO_GPS_ERROR = (0.0, 0.0, 0.0, 0.0)


class SensorModel:
    """Adds the configured bias and noise to true values; ideal sensors pass them through.

    The generator is seeded from the simulator's seed (a string seed is hashed with SHA-512 by
    :mod:`random`, so the sequence does not depend on ``PYTHONHASHSEED``).
    """

    __slots__ = ("config", "_ideal", "_gps_errors", "_rng", "_gps_rng", "_gps_drift",
                 "_gps_time_s", "_drift_origin_s")

    def __init__(self, config: SensorConfig, seed: int) -> None:
        self.config = config
        self._ideal = config.is_ideal
        # Read every step: the configuration's properties are worked out once.
        self._gps_errors = config.has_gps_error
        # The seed strings keep the module's first name (bfsitl.sim): a rename must not change
        # the noise a seed gives, or no run would repeat across versions.
        self._rng = random.Random(f"bfsitl.sim.sensors:{seed}")
        # Its own generator: switching the GPS error on leaves the IMU's noise as it was.
        self._gps_rng = random.Random(f"bfsitl.sim.sensors.gps:{seed}")
        self._gps_drift = (0.0, 0.0)
        self._gps_time_s: float | None = None
        self._drift_origin_s: float | None = None

    def reconfigure(self, config: SensorConfig, time_s: float) -> None:
        """New errors from ``time_s`` on (a fault injected mid-flight); the generators go on
        where they were, so a run stays repeatable, and a drift starts from zero then."""
        self.config = config
        self._ideal = config.is_ideal
        self._gps_errors = config.has_gps_error
        self._drift_origin_s = time_s

    def gps_error(self, time_s: float) -> tuple[float, float, float, float]:
        """(north m, east m, north m/s, east m/s) to add to the GPS at ``time_s``."""
        if not self._gps_errors:
            return _NO_GPS_ERROR
        c = self.config
        gauss = self._gps_rng.gauss
        if c.gps_drift_std_m == 0.0:
            self._gps_drift = (0.0, 0.0)
        elif self._gps_time_s is None:
            # Start anywhere in the wander's spread, as a receiver that has been on a while.
            self._gps_drift = (gauss(0.0, c.gps_drift_std_m), gauss(0.0, c.gps_drift_std_m))
        elif time_s > self._gps_time_s:
            keep = math.exp(-(time_s - self._gps_time_s) / c.gps_drift_time_s)
            kick = c.gps_drift_std_m * math.sqrt(1.0 - keep * keep)
            self._gps_drift = (keep * self._gps_drift[0] + kick * gauss(0.0, 1.0),
                               keep * self._gps_drift[1] + kick * gauss(0.0, 1.0))
        self._gps_time_s = time_s
        pn, vn = c.gps_noise_std_m, c.gps_velocity_noise_std_m_s
        on, oe = c.gps_offset_ne_m
        return (self._gps_drift[0] + on + (gauss(0.0, pn) if pn else 0.0),
                self._gps_drift[1] + oe + (gauss(0.0, pn) if pn else 0.0),
                gauss(0.0, vn) if vn else 0.0, gauss(0.0, vn) if vn else 0.0)

    def corrupt(self, gyro: Vec3, specific_force: Vec3, pressure_pa: float,
                time_s: float = 0.0) -> tuple[Vec3, Vec3, float]:
        """Measured (gyro, specific force, pressure) from true ones at ``time_s``."""
        if self._ideal:
            return gyro, specific_force, pressure_pa
        c = self.config
        if c.baro_drift_pa_s:
            if self._drift_origin_s is None:
                self._drift_origin_s = time_s
            pressure_pa += c.baro_drift_pa_s * (time_s - self._drift_origin_s)
        gauss = self._rng.gauss
        gs, acs, ps = c.gyro_noise_std_rad_s, c.accel_noise_std_m_s2, c.baro_noise_std_pa
        gb, ab = c.gyro_bias_rad_s, c.accel_bias_m_s2
        if gs > 0.0:
            gyro = (gyro[0] + gb[0] + gauss(0.0, gs), gyro[1] + gb[1] + gauss(0.0, gs),
                    gyro[2] + gb[2] + gauss(0.0, gs))
        else:
            gyro = (gyro[0] + gb[0], gyro[1] + gb[1], gyro[2] + gb[2])
        if acs > 0.0:
            specific_force = (
                specific_force[0] + ab[0] + gauss(0.0, acs),
                specific_force[1] + ab[1] + gauss(0.0, acs),
                specific_force[2] + ab[2] + gauss(0.0, acs),
            )
        else:
            specific_force = (specific_force[0] + ab[0], specific_force[1] + ab[1],
                              specific_force[2] + ab[2])
        pressure_pa = pressure_pa + c.baro_bias_pa + (gauss(0.0, ps) if ps > 0.0 else 0.0)
        return gyro, specific_force, pressure_pa
