"""Every frame convention of the embedded physics, in one place.

Conventions (``docs/firmware-facts.md#fdm-frames``, ``docs/firmware-facts.md#model-choices``):

* world: **NED** (north, east, down), origin on the ground at the home point, metres;
* body: **FRD** (forward, right, down), origin at the centre of mass;
* attitude: Hamilton unit quaternion ``(w, x, y, z)`` rotating body-FRD vectors into world-NED:
  ``v_ned = R(q) v_frd``; that is exactly what the 4.6.0 SITL takes as its attitude;
* Euler angles: aerospace ZYX (yaw, then pitch, then roll), pitch **nose up** positive.
  Betaflight itself reports pitch nose *down* positive: see :func:`betaflight_attitude_deg`;
* ENU (east, north, up) exists only for the ``-DUSE_GPS`` firmware build's velocity;
* Betaflight's internal sensor frame is FLU; the SITL converts the FRD gyro as (x, -y, -z) and
  negates all three accelerometer axes (``sitl.c updateState``); :func:`betaflight_gyro_raw`
  and :func:`betaflight_acc_raw` predict what the firmware then reports over MSP.

The vehicle's inner loop inlines ``R(q) v`` products for speed, always with the matrix from
:func:`rotation_matrix`; no other module defines a convention of its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import Quat, Vec3

#: Matrix as nine floats, row-major: (R00, R01, R02, R10, ..., R22).
Matrix3 = tuple[float, float, float, float, float, float, float, float, float]

#: WGS-84 equatorial radius.  Betaflight's navigation maths assumes the same sphere
#: (``EARTH_ANGLE_TO_CM`` 1.113195 cm per 1e-7 degree = 6378137 m * pi / 180), so distances the
#: firmware computes from our latitude/longitude match the NED metres we integrated.
EARTH_RADIUS_M = 6378137.0

#: Firmware scales (``sitl.c``): gyro 16.4 LSB per deg/s, accelerometer 256 LSB per g.
BETAFLIGHT_GYRO_LSB_PER_RAD_S = 16.4 * 57.2958
BETAFLIGHT_ACC_LSB_PER_M_S2 = 256.0 / STANDARD_GRAVITY_M_S2


@dataclass(frozen=True, slots=True)
class GeoPoint:
    """A geodetic position: latitude and longitude in degrees, altitude above mean sea level.

    Attributes:
        lat_deg: Latitude in degrees, north positive; within +-89 (the flat-earth conversion
            between NED metres and degrees breaks down at the poles).
        lon_deg: Longitude in degrees, east positive; within +-180.
        alt_m: Altitude above mean sea level in metres.

    Raises:
        SimInputError: A value is not finite or out of its range.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float = 0.0

    def __post_init__(self) -> None:
        if not all(math.isfinite(v) for v in (self.lat_deg, self.lon_deg, self.alt_m)):
            raise SimInputError(f"GeoPoint: values must be finite, got {self!r}")
        if not -89.0 <= self.lat_deg <= 89.0:
            raise SimInputError(
                f"GeoPoint: latitude {self.lat_deg} deg is outside +-89 deg, where the "
                f"flat-earth NED <-> geodetic conversion breaks down"
            )
        if not -180.0 <= self.lon_deg <= 180.0:
            raise SimInputError(f"GeoPoint: longitude {self.lon_deg} deg is outside +-180 deg")


# ---- quaternions -------------------------------------------------------------------------------


def quat_multiply(a: Quat, b: Quat) -> Quat:
    """Hamilton product a * b (apply b first, then a, when rotating vectors)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_conjugate(q: Quat) -> Quat:
    """Inverse rotation of a unit quaternion (world NED -> body FRD)."""
    return (q[0], -q[1], -q[2], -q[3])


def quat_normalize(q: Quat) -> Quat:
    """Unit quaternion in the same direction; refuses a zero or non-finite one."""
    w, x, y, z = q
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if not (math.isfinite(norm) and norm > 1e-12):
        raise SimInputError(f"quaternion {q!r} cannot be normalised")
    inv = 1.0 / norm
    return (w * inv, x * inv, y * inv, z * inv)


def quat_from_axis_angle(axis: Vec3, angle_rad: float) -> Quat:
    """Rotation by ``angle_rad`` about ``axis`` (right hand rule)."""
    ax, ay, az = axis
    norm = math.sqrt(ax * ax + ay * ay + az * az)
    if norm == 0.0:
        raise SimInputError("quat_from_axis_angle: the axis is zero")
    s = math.sin(0.5 * angle_rad) / norm
    return (math.cos(0.5 * angle_rad), ax * s, ay * s, az * s)


def quat_from_euler_rad(roll_rad: float, pitch_rad: float, yaw_rad: float) -> Quat:
    """Body FRD -> NED from aerospace ZYX angles (roll right, pitch nose up, yaw from north)."""
    cr, sr = math.cos(0.5 * roll_rad), math.sin(0.5 * roll_rad)
    cp, sp = math.cos(0.5 * pitch_rad), math.sin(0.5 * pitch_rad)
    cy, sy = math.cos(0.5 * yaw_rad), math.sin(0.5 * yaw_rad)
    return (
        cy * cp * cr + sy * sp * sr,
        cy * cp * sr - sy * sp * cr,
        cy * sp * cr + sy * cp * sr,
        sy * cp * cr - cy * sp * sr,
    )


def quat_from_euler_deg(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Quat:
    """:func:`quat_from_euler_rad` in degrees."""
    return quat_from_euler_rad(
        math.radians(roll_deg), math.radians(pitch_deg), math.radians(yaw_deg)
    )


def euler_from_quat_rad(q: Quat) -> Vec3:
    """Aerospace ZYX angles (roll, pitch nose-up positive, yaw) of a body FRD -> NED rotation."""
    r = rotation_matrix(q)
    sin_pitch = max(-1.0, min(1.0, -r[6]))
    return (math.atan2(r[7], r[8]), math.asin(sin_pitch), math.atan2(r[3], r[0]))


def quat_integrate(q: Quat, omega_frd_rad_s: Vec3, dt_s: float) -> Quat:
    """Attitude after turning at a constant body rate for ``dt_s``, renormalised.

    Exact for a constant rate: ``q * exp(omega dt / 2)``; the series form below is used while
    the half angle is small (< 0.1 rad, i.e. below 200 rad/s at a 1 ms step), where its error
    (< 1e-10) is far below what renormalising removes anyway.
    """
    wx, wy, wz = omega_frd_rad_s
    half_dt = 0.5 * dt_s
    hx, hy, hz = wx * half_dt, wy * half_dt, wz * half_dt
    half2 = hx * hx + hy * hy + hz * hz
    if half2 < 0.01:
        c = 1.0 - half2 * (0.5 - half2 * (1.0 / 24.0))
        s = 1.0 - half2 * (1.0 / 6.0 - half2 * (1.0 / 120.0))
    else:
        half = math.sqrt(half2)
        c = math.cos(half)
        s = math.sin(half) / half
    dw, dx, dy, dz = c, hx * s, hy * s, hz * s
    w, x, y, z = q
    nw = w * dw - x * dx - y * dy - z * dz
    nx = w * dx + x * dw + y * dz - z * dy
    ny = w * dy - x * dz + y * dw + z * dx
    nz = w * dz + x * dy - y * dx + z * dw
    inv = 1.0 / math.sqrt(nw * nw + nx * nx + ny * ny + nz * nz)
    return (nw * inv, nx * inv, ny * inv, nz * inv)


# ---- rotation matrices and vectors --------------------------------------------------------------


def rotation_matrix(q: Quat) -> Matrix3:
    """R(q), body FRD -> world NED, row-major.  Row 2 is the body axes' "down" components."""
    w, x, y, z = q
    xx, yy, zz = x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (
        1.0 - 2.0 * (yy + zz),
        2.0 * (xy - wz),
        2.0 * (xz + wy),
        2.0 * (xy + wz),
        1.0 - 2.0 * (xx + zz),
        2.0 * (yz - wx),
        2.0 * (xz - wy),
        2.0 * (yz + wx),
        1.0 - 2.0 * (xx + yy),
    )


def tilt_deg(q: Quat) -> float:
    """Degrees between the body's down axis and the world's (0 level, 180 upside down)."""
    _w, x, y, _z = q
    # Body z in world NED has z component 1 - 2(x^2 + y^2): cos(tilt).
    return math.degrees(math.acos(max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y)))))


def body_to_world(q: Quat, v_frd: Vec3) -> Vec3:
    """An FRD body vector expressed in NED."""
    r = rotation_matrix(q)
    x, y, z = v_frd
    return (
        r[0] * x + r[1] * y + r[2] * z,
        r[3] * x + r[4] * y + r[5] * z,
        r[6] * x + r[7] * y + r[8] * z,
    )


def world_to_body(q: Quat, v_ned: Vec3) -> Vec3:
    """A NED world vector expressed in FRD body axes (R transposed)."""
    r = rotation_matrix(q)
    x, y, z = v_ned
    return (
        r[0] * x + r[3] * y + r[6] * z,
        r[1] * x + r[4] * y + r[7] * z,
        r[2] * x + r[5] * y + r[8] * z,
    )


def gravity_specific_force_frd(q: Quat) -> Vec3:
    """What an accelerometer reads when something holds the vehicle still: R^T (0, 0, -g)."""
    r = rotation_matrix(q)
    g = STANDARD_GRAVITY_M_S2
    return (-g * r[6], -g * r[7], -g * r[8])


def frd_to_flu(v: Vec3) -> Vec3:
    """FRD <-> FLU (its own inverse): Betaflight's and Gazebo's body frame."""
    return (v[0], -v[1], -v[2])


def ned_to_enu(v: Vec3) -> Vec3:
    """NED -> ENU, the velocity frame of the ``-DUSE_GPS`` firmware build."""
    return (v[1], v[0], -v[2])


def enu_to_ned(v: Vec3) -> Vec3:
    """ENU -> NED."""
    return (v[1], v[0], -v[2])


# ---- geodetic ----------------------------------------------------------------------------------


class GeodeticProjection:
    """The flat-earth projection of :func:`ned_to_geodetic`, with its scales computed once.

    The simulator converts every step; this saves the trigonometry and the GeoPoint checks.
    Its scales (degrees per metre north and east) are what the physics' C projection uses.
    """

    __slots__ = ("home", "deg_per_north_m", "deg_per_east_m")

    def __init__(self, home: GeoPoint) -> None:
        self.home = home
        self.deg_per_north_m = math.degrees(1.0 / EARTH_RADIUS_M)
        self.deg_per_east_m = math.degrees(
            1.0 / (EARTH_RADIUS_M * math.cos(math.radians(home.lat_deg)))
        )

    def lon_lat_alt(self, position_ned_m: Vec3) -> Vec3:
        """(longitude deg, latitude deg, altitude m MSL): the order a -DUSE_GPS SITL reads."""
        home = self.home
        return (
            home.lon_deg + position_ned_m[1] * self.deg_per_east_m,
            home.lat_deg + position_ned_m[0] * self.deg_per_north_m,
            home.alt_m - position_ned_m[2],
        )


def ned_to_geodetic(position_ned_m: Vec3, home: GeoPoint) -> GeoPoint:
    """Flat-earth (tangent plane at home) NED metres -> latitude, longitude, altitude MSL.

    lat = lat0 + N / R_E, lon = lon0 + E / (R_E cos lat0), alt = alt0 - D, the form a
    ``-DUSE_GPS`` build reads (docs/firmware-facts.md#no-gps).  Good to centimetres within a few
    kilometres of home, which is all a SITL flight covers.
    """
    lon, lat, alt = GeodeticProjection(home).lon_lat_alt(position_ned_m)
    return GeoPoint(lat, lon, alt)


def geodetic_to_ned(point: GeoPoint, home: GeoPoint) -> Vec3:
    """Inverse of :func:`ned_to_geodetic`."""
    north = math.radians(point.lat_deg - home.lat_deg) * EARTH_RADIUS_M
    east = (
        math.radians(point.lon_deg - home.lon_deg)
        * EARTH_RADIUS_M
        * math.cos(math.radians(home.lat_deg))
    )
    return (north, east, home.alt_m - point.alt_m)


# ---- what Betaflight 4.6.0 SITL makes of our conventions ---------------------------------------


def betaflight_attitude_deg(q: Quat) -> Vec3:
    """(roll, pitch, yaw) in degrees as the 4.6.0 SITL derives them from an FRD -> NED q.

    ``flight/imu.c`` with the SITL rMat patch (docs/firmware-facts.md#attitude):
    roll = atan2(R21, R22) right wing down positive, pitch = asin(R20) **nose down positive**,
    yaw = atan2(R10, R00) clockwise heading from north in [0, 360).
    """
    r = rotation_matrix(q)
    roll = math.degrees(math.atan2(r[7], r[8]))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, r[6]))))
    yaw = math.degrees(math.atan2(r[3], r[0])) % 360.0
    return (roll, pitch, yaw)


def betaflight_attitude_and_tilt_deg(q: Quat) -> tuple[Vec3, float]:
    """:func:`betaflight_attitude_deg` and :func:`tilt_deg` of one ``q`` (the same values to
    the last bit) with the rotation worked out once: a truth sample needs both."""
    w, x, y, z = q
    xx, yy = x * x, y * y
    r8 = 1.0 - 2.0 * (xx + yy)  # cos(tilt): the body's down axis on the world's
    r6 = 2.0 * (x * z - w * y)
    roll = math.degrees(math.atan2(2.0 * (y * z + w * x), r8))
    pitch = math.degrees(math.asin(max(-1.0, min(1.0, r6))))
    yaw = math.degrees(math.atan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (yy + z * z))) % 360.0
    return (roll, pitch, yaw), math.degrees(math.acos(max(-1.0, min(1.0, r8))))


def _int16(value: float) -> int:
    """C's (int16_t) cast of a double as the SITL does it: truncate, here also saturate."""
    return max(-32768, min(32767, int(value)))


def betaflight_gyro_raw(gyro_frd_rad_s: Vec3) -> tuple[int, int, int]:
    """Raw gyro LSB the SITL stores from the fdm packet: FLU, 16.4 LSB per deg/s, truncated.

    MSP_RAW_IMU reports the filtered gyro, which can read one LSB lower (491 was measured for
    30 deg/s, where this gives 492: docs/firmware-facts.md#sign-table).
    """
    x, y, z = frd_to_flu(gyro_frd_rad_s)
    k = BETAFLIGHT_GYRO_LSB_PER_RAD_S
    return (_int16(x * k), _int16(y * k), _int16(z * k))


def betaflight_acc_raw(accel_sent_m_s2: Vec3) -> tuple[int, int, int]:
    """Raw accelerometer LSB from the fdm accel field: the SITL negates all axes, 256 LSB/g."""
    k = -BETAFLIGHT_ACC_LSB_PER_M_S2
    return tuple(_int16(a * k) for a in accel_sent_m_s2)  # type: ignore[return-value]
