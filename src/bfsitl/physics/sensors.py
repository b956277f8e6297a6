"""The virtual IMU and barometer, and how their readings become an fdm_packet.

Readings are in the physics' frames (``docs/firmware-facts.md#fdm-frames``); how each firmware
generation wants them in the fdm packet is :mod:`bfsitl.protocol.fdm_encoding`'s job:

* gyro: body rates in FRD, rad/s;
* accelerometer: **specific force** in FRD, m/s^2 (the sum of non-gravitational forces over
  the mass): level at rest (0, 0, -9.80665), ~0 in free fall;
* quaternion (w, x, y, z) body FRD -> world NED, unit length;
* pressure: ISA at the IMU's altitude above mean sea level, Pa;
* position/velocity: NED metres and m/s, and the same as (longitude, latitude, altitude) and
  ENU m/s for the firmware's virtual GPS.

Noise and bias are off by default (Gazebo's IRIS has none) and, when configured, come from a
seeded generator so that a run is repeatable.  This module describes the errors and the
readings; the physics (``bfsitl/kernel/physics.c``) draws and adds them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError
from bfsitl.physics.params import Quat, Vec3


@dataclass(frozen=True, slots=True)
class SensorConfig:
    """Additive sensor errors: a constant bias plus white Gaussian noise per reading.

    Standard deviations are per sample (per physics step), not densities; see
    :meth:`typical_mems` for a conversion from datasheet-style densities.

    Attributes:
        gyro_noise_std_rad_s: The gyro's white noise, radians per second, one standard
            deviation per reading.
        gyro_bias_rad_s: The gyro's constant bias on each body axis (forward, right, down),
            radians per second.
        accel_noise_std_m_s2: The accelerometer's white noise, metres per second squared.
        accel_bias_m_s2: The accelerometer's constant bias on each body axis, metres per
            second squared.
        baro_noise_std_pa: The barometer's white noise, pascals.
        baro_bias_pa: The barometer's constant bias, pascals (negative reads as higher).
        gps_drift_std_m: The GPS position's slow wander per horizontal axis, metres (one
            standard deviation of a first-order Gauss-Markov process).
        gps_drift_time_s: The wander's correlation time, seconds.
        gps_noise_std_m: The GPS position's white noise per horizontal axis, metres.
        gps_velocity_noise_std_m_s: The GPS velocity's white noise, metres per second.
        baro_drift_pa_s: How fast the barometer's bias grows, pascals per second, from when
            the configuration takes effect.
        gps_offset_ne_m: A fixed error on the GPS position, metres north and east.

    Raises:
        SimInputError: A deviation is negative, a value is not finite, or a vector has the
            wrong length.
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
            raise SimInputError(
                f"SensorConfig: gps_drift_time_s must be > 0, got {self.gps_drift_time_s}"
            )
        for name, value in stds.items():
            if not (math.isfinite(value) and value >= 0):
                raise SimInputError(f"SensorConfig: {name} must be >= 0, got {value}")
        for name, vector in (
            ("gyro_bias_rad_s", self.gyro_bias_rad_s),
            ("accel_bias_m_s2", self.accel_bias_m_s2),
        ):
            if len(vector) != 3 or not all(math.isfinite(v) for v in vector):
                raise SimInputError(
                    f"SensorConfig: {name} must be 3 finite numbers, got {vector!r}"
                )
        for name, number in (
            ("baro_bias_pa", self.baro_bias_pa),
            ("baro_drift_pa_s", self.baro_drift_pa_s),
        ):
            if not math.isfinite(number):
                raise SimInputError(f"SensorConfig: {name} must be finite, got {number}")
        if len(self.gps_offset_ne_m) != 2 or not all(
            math.isfinite(v) for v in self.gps_offset_ne_m
        ):
            raise SimInputError(
                f"SensorConfig: gps_offset_ne_m must be 2 finite numbers, "
                f"got {self.gps_offset_ne_m!r}"
            )

    @property
    def is_ideal(self) -> bool:
        """True when every error is zero: readings are the exact state."""
        return (
            self.gyro_noise_std_rad_s == 0.0
            and self.accel_noise_std_m_s2 == 0.0
            and self.baro_noise_std_pa == 0.0
            and self.baro_bias_pa == 0.0
            and self.baro_drift_pa_s == 0.0
            and not any(self.gyro_bias_rad_s)
            and not any(self.accel_bias_m_s2)
            and not self.has_gps_error
        )

    @property
    def has_gps_error(self) -> bool:
        return (
            self.gps_drift_std_m > 0.0
            or self.gps_noise_std_m > 0.0
            or self.gps_velocity_noise_std_m_s > 0.0
            or any(self.gps_offset_ne_m)
        )

    def with_typical_gps(self) -> SensorConfig:
        """These errors plus a GPS receiver's without corrections in open sky: 0.15 m of
        wander per axis over 30 s, 3 cm of noise per reading, 5 cm/s on the velocity
        (orders of magnitude from u-blox M8/M10 class modules; a benchmark's "realistic GPS
        noise")."""
        from dataclasses import replace

        return replace(
            self,
            gps_drift_std_m=0.15,
            gps_drift_time_s=30.0,
            gps_noise_std_m=0.03,
            gps_velocity_noise_std_m_s=0.05,
        )

    @classmethod
    def typical_mems(cls, sample_rate_hz: float = 1000.0) -> SensorConfig:
        """PX4's gazebo-classic iris IMU noise densities, sampled at ``sample_rate_hz``.

        Gyro 1.8665e-4 rad/s/sqrt(Hz), accelerometer 1.86e-3 m/s^2/sqrt(Hz)
        (docs/firmware-facts.md#px4-iris);
        white noise per sample = density * sqrt(rate).  Baro: 3 Pa (~25 cm), a typical MEMS
        barometer's RMS noise.  No bias: Betaflight calibrates neither in SITL.

        Args:
            sample_rate_hz: Readings per second (the physics' step rate).

        Returns:
            Noise only: no bias and no GPS error.
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
