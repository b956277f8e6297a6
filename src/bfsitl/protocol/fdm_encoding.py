"""Turn a sensor reading (physics frames) into the fdm_packet one firmware generation expects.

The physics speaks one language (body FRD, world NED, :mod:`bfsitl.physics.frames`); each SITL
generation reads the fdm packet its own way (``FdmConvention`` in
:mod:`bfsitl.protocol.firmware_profile`).
This module is the only place where the two meet. Whatever the generation, the firmware must
end up with the same physically consistent sensors, because master estimates its attitude from
them (a mirrored accelerometer axis fights the gyro there):

* gyro: Betaflight's own body rates are FLU, i.e. ``(x, -y, -z)`` of FRD (4.6 stores
  ``(x, -y, -z)`` of what it gets, so FRD goes out as it is); each generation's signs are
  undone here so that the firmware's gyro is the same;
* accelerometer: Betaflight's is the specific force in FLU; both generations negate all three
  fdm axes, so ``(-x, y, z)`` of the FRD specific force goes out;
* attitude quaternion: FRD -> NED as it is (4.6), or the Gazebo plugin's form (master);
* barometer: the pressure field (4.6), or the altitude in ``position_xyz[2]`` (master), made
  from the same (noisy) pressure with the firmware's own standard-atmosphere formula so both
  see the same barometer;
* GPS: (longitude, latitude, altitude) and ENU velocity on GPS builds, mirrored around home
  where the firmware mirrors around its first fix.
"""

from __future__ import annotations

import math

from bfsitl.physics.constants import SEA_LEVEL_PRESSURE_PA
from bfsitl.physics.frames import GeoPoint, quat_multiply
from bfsitl.physics.params import Quat, Vec3
from bfsitl.physics.sensors import SensorReading
from bfsitl.protocol.firmware_profile import (
    AltitudeSource,
    FdmConvention,
    FirmwareProfile,
    QuaternionConvention,
)
from bfsitl.protocol.sitl_packets import FdmPacket

_FDM_FORMAT = FdmPacket.FORMAT

#: Betaflight's body rates from FRD rates: FLU (the 4.6 SITL makes exactly this of FRD).
BETAFLIGHT_GYRO_FROM_FRD = (1, -1, -1)
#: Betaflight's accelerometer from the FRD specific force: FLU as well.
BETAFLIGHT_ACC_FROM_FRD = (1, -1, -1)

_HALF_SQRT2 = math.sqrt(0.5)
#: Rotation by -90 deg about z: undoes master's ENU -> NWU turn (sitl.c ``Rz(pi/2)``).
_RZ_MINUS_90: Quat = (_HALF_SQRT2, 0.0, 0.0, -_HALF_SQRT2)
#: Master's inverse standard atmosphere (sitl.c: P = 101325 (1 - 2.25577e-5 h)^5.25588).
_LAPSE_PER_M = 2.25577e-5
_EXPONENT = 5.25588

#: A latitude/longitude the master SITL reads as "GPS lost" (out of range: the update is
#: skipped and the fix goes stale, master sitl.c).
GPS_LOST_LON_LAT = (999.0, 999.0)


def gazebo_quaternion(q_ned_frd: Quat) -> Quat:
    """The quaternion master's Gazebo bridge turns back into this FRD -> NED attitude.

    The firmware takes the packet's q, negates y and z (undoing a conjugation by Rx(pi)) and
    multiplies by Rz(pi/2) on the left to get its FLU-body -> NWU-world attitude. Going back:
    FLU -> NWU is FRD -> NED conjugated by Rx(pi) (negate y, z); multiply by Rz(-pi/2); negate
    y and z again.
    """
    w, x, y, z = q_ned_frd
    nwu_flu = (w, x, -y, -z)
    pw, px, py, pz = quat_multiply(_RZ_MINUS_90, nwu_flu)
    return (pw, px, -py, -pz)


def altitude_for_pressure_m(pressure_pa: float) -> float:
    """The altitude master's formula turns into ``pressure_pa`` (its exact inverse)."""
    ratio = max(pressure_pa, 1.0) / SEA_LEVEL_PRESSURE_PA
    return (1.0 - ratio ** (1.0 / _EXPONENT)) / _LAPSE_PER_M


class FdmEncoder:
    """Encodes readings for one firmware profile; ``gps_lost`` sends the loss sentinel."""

    __slots__ = ("profile", "fdm", "home", "gps_lost", "_gyro_k", "_acc_k")

    def __init__(self, profile: FirmwareProfile, home: GeoPoint) -> None:
        self.profile = profile
        self.fdm: FdmConvention = profile.fdm
        self.home = home
        self.gps_lost = False
        signs = self.fdm.gyro_fc_signs
        self._gyro_k = tuple(b * s for b, s in zip(BETAFLIGHT_GYRO_FROM_FRD, signs, strict=True))
        signs = self.fdm.acc_fc_signs
        self._acc_k = tuple(b * s for b, s in zip(BETAFLIGHT_ACC_FROM_FRD, signs, strict=True))

    @property
    def gyro_factors(self) -> tuple[int, ...]:
        """What each FRD gyro axis is multiplied by for this generation."""
        return self._gyro_k

    @property
    def acc_factors(self) -> tuple[int, ...]:
        """What each FRD specific-force axis is multiplied by for this generation."""
        return self._acc_k

    def pack(self, reading: SensorReading, timestamp_s: float) -> bytes:
        """``encode(reading, timestamp_s).pack()``, the same bytes, without the packet object
        (the lockstep exchange packs one every simulated millisecond)."""
        gyro, accel, q, position, velocity = self._fields(reading)
        pressure = reading.pressure_pa
        values = (timestamp_s, *gyro, *accel, *q, *velocity, *position, pressure)
        if len(values) != 18 or not math.isfinite(sum(values)) or pressure <= 0:
            # Let the packet say which field is wrong.
            return self.encode(reading, timestamp_s).pack()
        return _FDM_FORMAT.pack(*values)

    def encode(self, reading: SensorReading, timestamp_s: float) -> FdmPacket:
        gyro, accel, q, position, velocity = self._fields(reading)
        return FdmPacket(timestamp_s, gyro, accel, q, velocity, position, reading.pressure_pa)

    def _fields(self, reading: SensorReading) -> tuple[Vec3, Vec3, Quat, Vec3, Vec3]:
        """(gyro, accelerometer, quaternion, position, velocity) as the firmware reads them."""
        g, a = reading.gyro_frd_rad_s, reading.specific_force_frd_m_s2
        gk, ak = self._gyro_k, self._acc_k
        gyro: Vec3 = (g[0] * gk[0], g[1] * gk[1], g[2] * gk[2])
        accel: Vec3 = (a[0] * ak[0], a[1] * ak[1], a[2] * ak[2])
        q = reading.quaternion_wxyz
        if self.fdm.quaternion is QuaternionConvention.GAZEBO:
            q = gazebo_quaternion(q)
        position, velocity = self._position_velocity(reading)
        return gyro, accel, q, position, velocity

    def _position_velocity(self, reading: SensorReading) -> tuple[Vec3, Vec3]:
        fdm = self.fdm
        if fdm.altitude is AltitudeSource.POSITION_Z_UP:
            # The barometer and the GPS altitude both come from here; made from the sensor's
            # pressure so that noise and bias configured for the barometer apply alike.
            altitude_m = altitude_for_pressure_m(reading.pressure_pa)
        else:
            altitude_m = reading.geodetic[2]
        if not self.profile.has_gps:
            # Unread without GPS but for master's altitude: NED metres, as Gazebo sends.
            north, east, down = reading.position_ned_m
            up_or_down = altitude_m if fdm.altitude is AltitudeSource.POSITION_Z_UP else down
            return (north, east, up_or_down), reading.velocity_ned_m_s
        lon, lat, _ = reading.geodetic
        if self.gps_lost and fdm.gps_loss_sentinel:
            lon, lat = GPS_LOST_LON_LAT
        elif fdm.gps_mirrored_about_first_fix:
            # The firmware mirrors around the first fix it receives, which is home (the
            # vehicle rests there when the bridge starts): send the mirror image of the truth.
            lon = 2.0 * self.home.lon_deg - lon
            lat = 2.0 * self.home.lat_deg - lat
        return (lon, lat, altitude_m), reading.velocity_enu_m_s
