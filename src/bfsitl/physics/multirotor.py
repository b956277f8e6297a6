"""The simulator: one quadrotor's rigid body, motors, rotors, drag, ground contact and sensors.

The model itself is C, in one place: ``bfsitl/kernel/physics.c`` (its opening comment gives
each choice and where it comes from, ``docs/firmware-facts.md#iris-model``).  It is built on
first use with the machine's C compiler, the one the firmware build needs anyway
(:mod:`bfsitl.kernel.compiler`), and the compiled lockstep loop steps the same structure
without returning to Python.

This module is its typed face: :class:`Simulator` checks every input and raises
:class:`SimInputError` naming what is wrong, writes the vehicle (:class:`QuadParams`), the
sensor errors (:class:`SensorConfig`) and the wind (:class:`Wind`) into the C structure, seeds
its random generators (the Mersenne Twister states of ``random.Random`` with the seed strings
below, so a seed gives the noise and gusts it always gave) and reads the state back as
:class:`VehicleState` and :class:`SensorReading`.  Frame conventions are
:mod:`bfsitl.physics.frames`'s.
"""

from __future__ import annotations

import ctypes
import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError
from bfsitl.kernel.compiler import load_kernel
from bfsitl.kernel.layout import D3, D4, READING, READING_OFFSET, STATE, Sim, kernel, seed_rng
from bfsitl.physics.atmosphere import isa_pressure_pa
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.frames import (
    GeodeticProjection,
    GeoPoint,
    quat_from_euler_deg,
    quat_normalize,
)
from bfsitl.physics.params import IRIS, Motors, QuadParams, Quat, Vec3
from bfsitl.physics.sensors import SensorConfig, SensorReading
from bfsitl.physics.wind import Wind

#: Longest step we accept: beyond it the motor and contact models are not meant to be used
#: (physics.c's MAX_STEP_S; a test reads it there).
MAX_STEP_S = 0.02
#: A reset may press the contact box at most this far into the ground.  Deeper, the springs
#: would launch the vehicle (docs/firmware-facts.md#model-choices).
MAX_RESET_PENETRATION_M = 0.05
#: The random generators' seed strings.  They keep the module's first name (bfsitl.sim): a
#: rename must not change the noise a seed gives, or no run would repeat across versions.
#: The GPS has its own generator, so switching its error on leaves the IMU's noise as it was.
SENSOR_SEED = "bfsitl.sim.sensors:{seed}"
GPS_SEED = "bfsitl.sim.sensors.gps:{seed}"
WIND_SEED = "bfsitl.sim.wind:{seed}"


@dataclass(frozen=True, slots=True)
class VehicleState:
    """The vehicle's true state.  Tuples of four are in Betaflight motor order (M1..M4)."""

    time_s: float
    position_ned_m: Vec3
    velocity_ned_m_s: Vec3
    quaternion_wxyz: Quat
    angular_velocity_frd_rad_s: Vec3
    motor_speeds_rad_s: Motors
    on_ground: bool


class Simulator:
    """One quadrotor in a NED world whose ground plane is z = 0 at the home point.

    ``step(motors, dt_s)`` advances by ``dt_s`` holding the four servo_packet commands
    (Betaflight order M1..M4, 0..1, clamped) constant; ``read_sensors()`` returns what the IMU
    and barometer report at the new time.  ``seed`` makes sensor noise and gusts repeatable.
    ``kernel_pointer`` is the address of the C structure (for C code that steps it, such as
    the compiled lockstep loop): every property reads that structure, so whoever stepped it,
    Python sees the same vehicle.

    Args:
        params: The vehicle: mass, inertia, rotors, motors, drag and contact (Gazebo's IRIS
            unless told otherwise).
        sensors: The sensors' errors; None is exact sensors.
        wind: The wind and its gusts; None is still air.
        home: Where the take-off point is on the earth (the GPS and the barometer's altitude
            are reckoned from it); None is 0 deg, 0 deg at sea level.
        seed: Seeds the sensor noise and the gusts: the same seed gives the same flight.

    Raises:
        KernelUnavailableError: The physics cannot be built here (no C compiler); the
            message says what to install.
        SimInputError: A parameter the model cannot use.
    """

    __slots__ = (
        "params",
        "sensor_config",
        "wind",
        "home",
        "_seed",
        "_kernel",
        "_sim",
        "_ptr",
        "_step",
        "_read",
        "_time",
        "_valid",
        "_gen",
        "_reading",
        "_reading_gen",
    )

    def __init__(
        self,
        params: QuadParams = IRIS,
        sensors: SensorConfig | None = None,
        wind: Wind | None = None,
        home: GeoPoint | None = None,
        seed: int = 0,
    ) -> None:
        self._kernel = kernel(load_kernel())
        self.params = params
        self.sensor_config = sensors if sensors is not None else SensorConfig()
        self.wind = wind
        self.home = home if home is not None else GeoPoint(0.0, 0.0, 0.0)
        self._seed = seed
        self._sim = sim = Sim()
        self._ptr: int = ctypes.addressof(sim)
        self._step = self._kernel.step
        self._read = self._kernel.read
        self._time = ctypes.c_double.from_buffer(sim, Sim.t.offset)
        self._valid = ctypes.c_int32.from_buffer(sim, Sim.reading_valid.offset)
        self._gen = ctypes.c_uint64.from_buffer(sim, Sim.reading_gen.offset)
        self._reading: SensorReading | None = None
        self._reading_gen = -1
        self._write_vehicle(params)
        sim.thrust_scale[:] = (1.0, 1.0, 1.0, 1.0)
        self._write_home(self.home)
        self._start_wind(wind)
        self._write_sensor_config(self.sensor_config)
        seed_rng(sim.rng, SENSOR_SEED.format(seed=seed))
        seed_rng(sim.gps_rng, GPS_SEED.format(seed=seed))
        self.reset()

    # ---- set-up ---------------------------------------------------------------------------

    def _write_vehicle(self, p: QuadParams) -> None:
        sim = self._sim
        sim.mass_kg, sim.inertia_kg_m2[:] = p.mass_kg, p.inertia_kg_m2
        for i, (position, ccw) in enumerate(
            zip(p.rotor_positions_frd_m, p.rotor_spin_ccw, strict=True)
        ):
            sim.rotor_xy_frd_m[i][:] = (position[0], position[1])
            sim.rotor_spin_ccw[i] = bool(ccw)
        sim.thrust_coefficient = p.thrust_coefficient_n_per_rad2_s2
        sim.torque_coefficient = p.torque_coefficient_nm_per_rad2_s2
        sim.rotor_inertia_kg_m2 = p.rotor_inertia_kg_m2
        sim.motor_command_speed_rad_s = p.motor_command_speed_rad_s
        sim.motor_p_gain_nm_s_per_rad = p.motor_p_gain_nm_s_per_rad
        sim.motor_torque_limit_nm = p.motor_torque_limit_nm
        sim.rotor_damping_nm_s_per_rad = p.rotor_damping_nm_s_per_rad
        sim.motor_time_constant_s = p.motor_time_constant_s
        sim.blade_radius_m, sim.blade_pitch_rad = p.blade_radius_m, p.blade_pitch_rad
        sim.blade_stall_rad, sim.axial_inflow = p.blade_stall_rad, bool(p.axial_inflow)
        sim.drag_linear_n_s_per_m[:] = p.drag_linear_n_s_per_m
        sim.drag_quadratic_n_s2_per_m2[:] = p.drag_quadratic_n_s2_per_m2
        sim.contact_box_m[:] = (
            p.contact_half_x_m,
            p.contact_half_y_m,
            p.contact_bottom_m,
            p.contact_top_m,
        )
        sim.contact_stiffness_n_per_m = p.contact_stiffness_n_per_m
        sim.contact_damping_n_s_per_m = p.contact_damping_n_s_per_m
        sim.friction_coefficient = p.friction_coefficient
        sim.gravity_m_s2 = STANDARD_GRAVITY_M_S2
        self._kernel.init(self._ptr)

    def _write_home(self, home: GeoPoint) -> None:
        sim, projection = self._sim, GeodeticProjection(home)
        sim.home_lon, sim.home_lat = float(home.lon_deg), float(home.lat_deg)
        sim.home_alt = float(home.alt_m)
        sim.deg_per_east = projection.deg_per_east_m
        sim.deg_per_north = projection.deg_per_north_m

    def _start_wind(self, wind: Wind | None) -> None:
        sim = self._sim
        if wind is None:
            sim.wind_on = 0
            return
        sim.wind_base[:] = wind.velocity_ned_m_s
        sim.wind_std, sim.wind_tau = wind.gust_std_m_s, wind.gust_time_constant_s
        seed_rng(sim.wind_rng, WIND_SEED.format(seed=self._seed))
        self._kernel.start_wind(self._ptr)

    def _write_sensor_config(self, config: SensorConfig) -> None:
        sim = self._sim
        sim.ideal, sim.gps_errors = config.is_ideal, config.has_gps_error
        sim.gyro_std, sim.gyro_bias[:] = config.gyro_noise_std_rad_s, config.gyro_bias_rad_s
        sim.accel_std, sim.accel_bias[:] = config.accel_noise_std_m_s2, config.accel_bias_m_s2
        sim.baro_std, sim.baro_bias = config.baro_noise_std_pa, config.baro_bias_pa
        sim.baro_drift = config.baro_drift_pa_s
        sim.gps_drift_std, sim.gps_drift_time = config.gps_drift_std_m, config.gps_drift_time_s
        sim.gps_noise_std = config.gps_noise_std_m
        sim.gps_vel_std = config.gps_velocity_noise_std_m_s
        sim.gps_offset[:] = config.gps_offset_ne_m
        sim.reading_valid = 0

    # ---- the compiled side ----------------------------------------------------------------

    @property
    def kernel_pointer(self) -> int:
        """Address of the C ``bk_sim`` (alive as long as this object)."""
        return self._ptr

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

    def kinematics(self) -> tuple[float, Vec3, Vec3, Quat]:
        """(time, position NED, velocity NED, attitude quaternion) of :attr:`state` in one
        read, without the rest: what a truth sample at every control step needs."""
        s = STATE.unpack_from(self._sim)
        return s[0], (s[1], s[2], s[3]), (s[4], s[5], s[6]), (s[7], s[8], s[9], s[10])

    @property
    def state(self) -> VehicleState:
        s = STATE.unpack_from(self._sim)
        return VehicleState(
            s[0],
            (s[1], s[2], s[3]),
            (s[4], s[5], s[6]),
            (s[7], s[8], s[9], s[10]),
            (s[11], s[12], s[13]),
            (s[14], s[15], s[16], s[17]),
            self.on_ground,
        )

    @property
    def specific_force_frd_m_s2(self) -> Vec3:
        """What an ideal accelerometer reads now, body FRD: no noise, no bias, and no draw
        from the sensors' random generator (watching leaves the flight as it is)."""
        s = STATE.unpack_from(self._sim)
        w, x, y, z = s[7], s[8], s[9], s[10]
        a, b, c = s[18], s[19], s[20]
        # R(q)^T f, as physics.c's rotate_inverse computes it for the reading.
        return (
            (1.0 - 2.0 * (y * y + z * z)) * a
            + 2.0 * (x * y + w * z) * b
            + 2.0 * (x * z - w * y) * c,
            2.0 * (x * y - w * z) * a
            + (1.0 - 2.0 * (x * x + z * z)) * b
            + 2.0 * (y * z + w * x) * c,
            2.0 * (x * z + w * y) * a
            + 2.0 * (y * z - w * x) * b
            + (1.0 - 2.0 * (x * x + y * y)) * c,
        )

    # ---- control ----------------------------------------------------------------------------

    def hold(self, enabled: bool = True) -> None:
        """Freeze the pose (a test stand): stepping then only advances time and the motors.

        While held, readings report the pose and the velocities last given to :meth:`reset`
        (zero unless set), and the accelerometer reads R^T (0, 0, -g) as if a hand held the
        vehicle.  Releasing continues the dynamics from that state.

        Args:
            enabled: True holds, False releases.
        """
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
        """Put the vehicle somewhere.  Omitted arguments take their initial values.

        ``position_ned_m=None`` parks it on the ground below home, resting on its lowest
        corner(s) at their static sag (level: on the skids, at rest from the first step).
        The attitude is ``quaternion_wxyz`` (FRD -> NED, normalised here) or Euler angles in
        degrees (roll right, pitch nose up, yaw from north), not both.  Time is unchanged;
        :meth:`hold` stays as it was.

        Args:
            position_ned_m: The centre of mass, metres north, east and down of home; None
                parks it on the ground as said above.
            quaternion_wxyz: The attitude as a quaternion from the body (FRD) to NED.
            roll_deg: Roll, degrees, right wing down positive.
            pitch_deg: Pitch, degrees, nose up positive.
            yaw_deg: Heading, degrees clockwise from north.
            velocity_ned_m_s: Velocity in NED, metres per second.
            angular_velocity_frd_rad_s: Body rates (roll, pitch, yaw), radians per second.
            motor_speeds_rad_s: Each rotor's speed, radians per second (M1..M4).

        Raises:
            SimInputError: Both attitudes given, a value not finite, a negative motor speed,
                or a position that puts the vehicle into the ground.
        """
        if quaternion_wxyz is not None:
            if roll_deg or pitch_deg or yaw_deg:
                raise SimInputError("reset: give quaternion_wxyz or Euler angles, not both")
            q = quat_normalize(_vec4(quaternion_wxyz, "quaternion_wxyz"))
        else:
            q = quat_normalize(
                quat_from_euler_deg(
                    *_vector((roll_deg, pitch_deg, yaw_deg), 3, "roll/pitch/yaw_deg")
                )
            )
        velocity = _vec3(velocity_ned_m_s, "velocity_ned_m_s")
        rates = _vec3(angular_velocity_frd_rad_s, "angular_velocity_frd_rad_s")
        speeds = _vector(motor_speeds_rad_s, 4, "motor_speeds_rad_s")
        if min(speeds) < 0:
            raise SimInputError(f"reset: motor speeds must be >= 0 rad/s, got {speeds}")
        lowest = self._kernel.lowest_corner_m(self._ptr, D4(*q))
        if position_ned_m is None:
            position = (0.0, 0.0, self.params.resting_sag_m - lowest)
        else:
            position = _vec3(position_ned_m, "position_ned_m")
            depth = position[2] + lowest
            if depth > MAX_RESET_PENETRATION_M:
                raise SimInputError(
                    f"reset: position_ned_m {position} puts the contact box {depth:.3f} m into "
                    f"the ground; at this attitude the CoM must be at least {lowest:.3f} m up "
                    f"(z <= {-lowest:.3f}).  position_ned_m=None parks it on the ground."
                )
        # Everything checked: only now change the state.
        self._kernel.reset(self._ptr, D4(*q), D3(*position), D3(*velocity), D3(*rates), D4(*speeds))

    # ---- the step -----------------------------------------------------------------------------

    def step(self, motors: Motors, dt_s: float) -> None:
        """Advance ``dt_s`` seconds with the motor commands held (zero-order hold, as Gazebo).

        Args:
            motors: The four commands of a servo packet, Betaflight order M1..M4, 0 to 1
                (clamped).
            dt_s: Seconds to advance; positive and at most the model's longest step.

        Raises:
            SimInputError: The commands or the step are not numbers it can use.
        """
        try:
            u1, u2, u3, u4 = motors
            refused = self._step(self._ptr, u1, u2, u3, u4, dt_s)
        except (TypeError, ValueError, ctypes.ArgumentError):
            refused = 1
        if refused:
            self._step_checked(motors, dt_s)

    def _step_checked(self, motors: object, dt_s: object) -> None:
        """The checks, with the error that names what is wrong; then the step as floats."""
        u1, u2, u3, u4 = check_step_input(motors, dt_s)  # type: ignore[arg-type]
        if self._step(self._ptr, float(u1), float(u2), float(u3), float(u4), float(dt_s)):  # type: ignore[arg-type]
            raise SimInputError(f"step: the physics refused motors {motors!r} and dt_s {dt_s!r}")

    # ---- faults (scenarios change these mid-flight, between two steps) -------------------

    @property
    def motor_thrust(self) -> tuple[float, float, float, float]:
        """Each rotor's thrust as a fraction of a healthy one's (Betaflight order M1..M4)."""
        a, b, c, d = self._sim.thrust_scale
        return (a, b, c, d)

    def set_motor_thrust(self, motor: int, fraction: float) -> None:
        """Motor ``motor`` gives ``fraction`` of its thrust and drag torque at any speed: a
        damaged propeller or a weak motor.

        Args:
            motor: The motor, 1 to 4 in Betaflight's numbering.
            fraction: Its share of a healthy motor's thrust, 0 (dead) to 1 (healthy).

        Raises:
            SimInputError: No such motor, or a fraction outside 0 to 1.
        """
        if motor not in (1, 2, 3, 4):
            raise SimInputError(f"motor {motor} does not exist: a quad has motors 1 to 4")
        if not (math.isfinite(fraction) and 0.0 <= fraction <= 1.0):
            raise SimInputError(f"motor {motor}: thrust fraction {fraction} is outside 0..1")
        self._sim.thrust_scale[motor - 1] = float(fraction)

    def set_vehicle(self, params: QuadParams) -> None:
        """Another vehicle from now on, in the state this one is in (pose, velocities, rotor
        speeds, time, wind, sensors): a learner's hand that swaps the quad between episodes
        without restarting the firmware.  Put it somewhere with :meth:`reset` next; a quad
        resting on the ground would otherwise rest at the old one's sag.

        Args:
            params: The new vehicle.
        """
        self.params = params
        self._write_vehicle(params)
        # The next reading's specific force is the new vehicle's (its mass and rotors).
        self._sim.reading_valid = 0

    def set_wind(self, wind: Wind | None) -> None:
        """The wind from now on; its gusts are drawn afresh from the run's seed, so a run
        stays repeatable.

        Args:
            wind: The wind and its gusts; None is still air.
        """
        self.wind = wind
        self._start_wind(wind)

    def set_sensors(self, config: SensorConfig) -> None:
        """The sensor errors from now on (the noise generators go on where they were, and a
        drift starts from zero now).

        Args:
            config: The errors to apply.
        """
        self.sensor_config = config
        sim = self._sim
        self._write_sensor_config(config)
        sim.drift_origin = sim.t
        sim.has_drift_origin = 1

    # ---- sensors ------------------------------------------------------------------------------

    def read_sensors(self) -> SensorReading:
        """What the IMU and barometer report now (the same object until the next step)."""
        reading = self._reading
        if reading is not None and self._valid.value and self._gen.value == self._reading_gen:
            return reading
        if not self._read(self._ptr):
            # Outside the ISA model: its error says where the vehicle went.
            isa_pressure_pa(self.home.alt_m - self._sim.p[2])
            raise SimInputError("read_sensors: the physics refused the altitude")
        r = READING.unpack_from(self._sim, READING_OFFSET)
        reading = SensorReading(
            r[0],
            (r[1], r[2], r[3]),
            (r[4], r[5], r[6]),
            (r[7], r[8], r[9], r[10]),
            r[11],
            (r[12], r[13], r[14]),
            (r[15], r[16], r[17]),
            (r[18], r[19], r[20]),
            (r[21], r[22], r[23]),
        )
        self._reading = reading
        self._reading_gen = self._gen.value
        return reading


# ---- input checks -----------------------------------------------------------------------------


def _vector(values: object, length: int, name: str) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in values)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise SimInputError(f"{name}: expected {length} numbers, got {values!r}") from None
    if len(out) != length:
        raise SimInputError(f"{name}: expected {length} numbers, got {len(out)}: {values!r}")
    if not all(math.isfinite(v) for v in out):
        raise SimInputError(f"{name}: every value must be finite, got {values!r}")
    return out


def _vec3(values: object, name: str) -> Vec3:
    x, y, z = _vector(values, 3, name)
    return (x, y, z)


def _vec4(values: object, name: str) -> Quat:
    w, x, y, z = _vector(values, 4, name)
    return (w, x, y, z)


def check_step_input(motors: Motors, dt_s: float) -> Motors:
    """The four commands of a step, or the SimInputError that names what is wrong with the
    step's input."""
    try:
        u1, u2, u3, u4 = motors
        finite = math.isfinite(u1 + u2 + u3 + u4)
    except (TypeError, ValueError):
        raise SimInputError(
            f"step: motors must be 4 numbers (Betaflight M1..M4), got {motors!r}"
        ) from None
    if not finite:
        _check_motors((u1, u2, u3, u4))
    if not 0.0 < dt_s <= MAX_STEP_S:
        raise SimInputError(f"step: dt_s must be in (0, {MAX_STEP_S}] s, got {dt_s!r}")
    return (u1, u2, u3, u4)


def _check_motors(motors: Motors) -> None:
    for index, value in enumerate(motors):
        if not math.isfinite(value):
            raise SimInputError(
                f"step: motor M{index + 1} command is {value!r}; commands must be finite "
                f"(servo_packet values 0..1)"
            )
