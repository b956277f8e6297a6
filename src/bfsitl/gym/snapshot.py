"""One look at the flight for a learning step: what the FC reports (one MSP round trip, the
GPS in the same batch on a GPS build) beside the simulated truth.

Frames: positions and velocities are north, east, up from where the vehicle stood at arming;
body rates and specific force are in Betaflight's FLU body axes (x forward, y left, z up:
``(x, -y, -z)`` of the physics' FRD), for the FC's gyro and accelerometer and for the truth
alike, so the two observations read the same way.  Roll is positive right wing down and pitch
positive nose down, as MSP_ATTITUDE has them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.mission.session import FlightSession
from bfsitl.mission.vehicle import FlightSample, Vehicle
from bfsitl.protocol import messages as msg

Vec3 = tuple[float, float, float]
Vec4 = tuple[float, float, float, float]

#: MSP_MOTOR reports pulse widths; 1000..2000 us is 0..1.
_MOTOR_MIN_US, _MOTOR_SPAN_US = 1000.0, 1000.0


@dataclass(frozen=True, slots=True)
class FcView:
    """What a companion computer on a real quad reads from the FC."""

    roll_rad: float
    pitch_rad: float  # positive nose down
    yaw_rad: float  # heading, clockwise from north
    rates_flu_rad_s: Vec3  # MSP_RAW_IMU gyro
    accel_flu_m_s2: Vec3  # MSP_RAW_IMU accelerometer (specific force: +g up at rest)
    accel_up_m_s2: float  # the same made vertical, gravity removed (0 at rest)
    alt_m: float  # MSP_ALTITUDE, zeroed at arming
    climb_m_s: float  # MSP_ALTITUDE vario
    north_m: float  # the FC's GPS made local (0 without a GPS: see has_gps)
    east_m: float
    v_north_m_s: float
    v_east_m_s: float
    has_gps: bool
    motors: Vec4  # MSP_MOTOR, 0..1
    armed: bool
    arming_blockers: tuple[str, ...]
    flight_modes: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class TrueView:
    """The simulated state, in the same frames."""

    north_m: float
    east_m: float
    alt_m: float
    v_north_m_s: float
    v_east_m_s: float
    v_up_m_s: float
    roll_rad: float
    pitch_rad: float
    yaw_rad: float
    rates_flu_rad_s: Vec3
    accel_flu_m_s2: Vec3
    motors: Vec4
    tilt_deg: float
    on_ground: bool

    def as_dict(self) -> dict[str, object]:
        return {name: getattr(self, name) for name in self.__slots__}


@dataclass(frozen=True, slots=True)
class Snapshot:
    time_s: float
    fc: FcView
    truth: TrueView


def watch_fc(vehicle: Vehicle) -> None:
    """Have every sample of ``vehicle`` carry what :func:`fc_view` reads besides the sample's
    own replies (MSP_MOTOR, and MSP_RAW_GPS on a GPS build), in the same round trip."""
    vehicle.read_with_samples(msg.Motor, *((msg.RawGps,) if vehicle.has_gps else ()))


def fc_view(vehicle: Vehicle, sample: FlightSample) -> FcView:
    """What the FC reported in ``sample``: the observation's only source in training
    (``observation="fc"``) and when a trained policy flies a SITL or a board.  The motors
    and the GPS come from the sample's round trip when :func:`watch_fc` asked for them,
    else from one more exchange."""
    north = east = v_north = v_east = 0.0
    with_gps = vehicle.has_gps
    if with_gps:
        gps = vehicle.gps_position(sample)
        north, east, v_north, v_east = (gps.north_m, gps.east_m, gps.v_north_m_s, gps.v_east_m_s)
    motors_us = vehicle.reading(msg.Motor, sample).motors_us
    return FcView(
        roll_rad=math.radians(sample.roll_deg),
        pitch_rad=math.radians(sample.pitch_deg),
        yaw_rad=math.radians(sample.yaw_deg),  # the middle of MSP_ATTITUDE's whole degree
        rates_flu_rad_s=sample.fc_gyro_flu_rad_s,
        accel_flu_m_s2=sample.fc_accel_flu_m_s2,
        accel_up_m_s2=sample.fc_accel_up_m_s2,
        alt_m=sample.fc_alt_m,
        climb_m_s=sample.fc_climb_m_s,
        north_m=north,
        east_m=east,
        v_north_m_s=v_north,
        v_east_m_s=v_east,
        has_gps=with_gps,
        motors=tuple(  # type: ignore[arg-type]
            min(1.0, max(0.0, (us - _MOTOR_MIN_US) / _MOTOR_SPAN_US)) for us in motors_us[:4]
        ),
        armed=sample.armed,
        arming_blockers=sample.arming_blockers,
        flight_modes=sample.flight_modes,
    )


def read_snapshot(vehicle: FlightSession, *, arm_ned_m: Vec3) -> Snapshot:
    """The FC's view (one MSP round trip: :func:`fc_view` of a sample) and the truth now;
    ``arm_ned_m`` is where the vehicle stood at arming (the truth's origin)."""
    watch_fc(vehicle)
    sample = vehicle.sample()
    return Snapshot(sample.time_s, fc_view(vehicle, sample), true_view(vehicle, arm_ned_m))


def true_view(vehicle: FlightSession, arm_ned_m: Vec3) -> TrueView:
    """The simulator's state in the snapshot's frames (no sensor is read: the physics' noise
    generators are the bridge's alone, so watching does not change the flight)."""
    simulator = vehicle.simulator
    if simulator is None:
        raise RuntimeError("the environment needs bfsitl's embedded physics")
    state = simulator.state
    truth = vehicle.backend.truth()
    assert truth is not None
    north, east, down = state.position_ned_m
    vn, ve, vd = state.velocity_ned_m_s
    p, q, r = state.angular_velocity_frd_rad_s
    fx, fy, fz = simulator.specific_force_frd_m_s2
    roll, pitch, yaw = (math.radians(a) for a in truth.attitude_deg)
    return TrueView(
        north_m=north - arm_ned_m[0],
        east_m=east - arm_ned_m[1],
        alt_m=arm_ned_m[2] - down,
        v_north_m_s=vn,
        v_east_m_s=ve,
        v_up_m_s=-vd,
        roll_rad=roll,
        pitch_rad=pitch,
        yaw_rad=yaw,
        rates_flu_rad_s=(p, -q, -r),
        accel_flu_m_s2=(fx, -fy, -fz),
        motors=truth.motors,
        tilt_deg=truth.tilt_deg,
        on_ground=truth.on_ground,
    )
