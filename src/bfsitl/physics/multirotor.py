"""Quadrotor rigid body: motors, rotor forces and torques, drag, gravity, wind, ground contact.

The model is Gazebo-IRIS parity (``docs/firmware-facts.md#iris-model``,
``docs/firmware-facts.md#iris-motors``) with these choices, each made for the 1 ms step and a
plain-CPython budget (measured 5-8 us per step airborne, 20-30 us while the contact is active,
on a noisy 2-core VM; ``benchmarks/physics.py``):

* **Motors**: first-order lag towards the speed the Gazebo joint P controller settles at,
  updated exactly (``1 - exp(-h/tau)``, tau = 0.82 ms) and slew-limited by the +-2.5 N m motor
  torque clamp.  The rotor's spin-up reaction ``I_r dOmega/dt`` is applied to the frame (on
  IRIS it dominates transient yaw), as is the rotor gyroscopic torque.
* **Rotors**: T = k_T Omega^2, Q = k_Q Omega^2, with the LiftDrag elements' axial-inflow
  term linearised: climbing at v through the disc lowers the angle of attack by
  v / (Omega r), so T = k_T Omega (Omega - v / (r a0)), capped at stall.
* **Integrator**: one force evaluation per step.  Symplectic (semi-implicit) Euler for
  translation (v first, then p with the new v: bounded energy error, no drift in a hover or on
  the contact springs); an explicit midpoint step for Euler's equations (plain Euler pumps
  energy into a free rotation: O(h^2) per step, 2.5 %/s at 20 rad/s); the exponential map of
  the step's mean body rate for the quaternion, renormalised (the end-of-step rate drifted the
  angular momentum 1000x more in the tumbling test).  RK4 (the first design's integrator,
  ``docs/firmware-facts.md#model-choices``) would cost four force evaluations and buys nothing
  here: the motors, the only fast states, are integrated exactly, and the rigid body's own time
  scales are tens of milliseconds.  Measured: energy 2e-7 and angular momentum 1e-6 relative
  over a minute of tumbling, |q| - 1 below 1e-15.
* **Ground contact** (``docs/firmware-facts.md#model-choices``): spring-dampers at the eight
  corners of the Gazebo collision box (the four bottom ones are the skids), with Coulomb
  friction.  The ground only pushes, so the damper cannot act on the way out; the vertical mode
  is damped at 1.5 x critical so that no landing rebounds (``QuadParams.contact_damping_ratio``).
  While a corner touches, the step is split into sub-steps: the contact's rotational modes are
  ~30x lighter than the vertical one, and an explicit damper that is stable for them at 1 ms
  could not damp the vertical one.  Below the sliding limit friction is a stiff viscous "stick"
  sized to the sub-step, so it can neither chatter nor go unstable at impact.
* **Rest**: a spring-damper alone holds a resting quad only approximately (the viscous stick
  lets a sustained sideways load creep).  So when the vehicle sits on all four skids, slow and
  unaccelerated, and the ground can carry the applied force and torque (normal load > 0,
  centre of pressure inside the skids, friction within mu N), the body is frozen: velocities
  exactly zero, the accelerometer exactly R^T (0, 0, -g).  It is released the moment those
  conditions fail (e.g. thrust exceeds weight), so take-off needs no special case.  This is
  static friction, with exact sensors and almost no cost while parked.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.physics.atmosphere import isa_pressure_pa
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.contact import GroundContact
from bfsitl.physics.frames import (
    GeodeticProjection,
    GeoPoint,
    quat_from_euler_deg,
    quat_integrate,
    quat_normalize,
)
from bfsitl.physics.params import IRIS, Motors, QuadParams, Quat, SimInputError, Vec3
from bfsitl.physics.sensors import SensorConfig, SensorModel, SensorReading
from bfsitl.physics.wind import Wind, WindField

#: Explicit contact sub-steps are sized so (damping rate x sub-step) stays below this, and the
#: friction stick takes at most as much again: together under 1, so contact velocities decay
#: without changing sign from one sub-step to the next (IRIS at 1 ms: 4 sub-steps).
CONTACT_RATE_STEP = 0.5
#: Longest step we accept: beyond it the motor and contact models are not meant to be used.
MAX_STEP_S = 0.02
#: A reset may press the contact box at most this far into the ground.  Deeper, the springs
#: would launch the vehicle (docs/firmware-facts.md#model-choices).
MAX_RESET_PENETRATION_M = 0.05



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


class Simulator(GroundContact):
    """One quadrotor in a NED world whose ground plane is z = 0 at the home point.

    ``step(motors, dt_s)`` advances by ``dt_s`` holding the four servo_packet commands
    (Betaflight order M1..M4, 0..1, clamped) constant; ``read_sensors()`` returns what the IMU
    and barometer report at the new time.  ``seed`` makes sensor noise and gusts repeatable.
    """

    __slots__ = (
        "params", "sensor_config", "wind", "home", "_seed", "_thrust_scale",
        # state
        "_t", "_t_err", "_p", "_v", "_q", "_w", "_om", "_om_dot",
        "_resting", "_held", "_touching", "_on_skids", "_sf_world", "_reading",
        # helpers and cached constants
        "_sensors", "_wind", "_geo", "_dt", "_alpha", "_n_sub", "_stick",
        "_m", "_inv_m", "_j", "_g", "_rotors", "_kf", "_kq", "_ir", "_inflow_inv_m",
        "_stall_ratio", "_inflow", "_drive", "_b_motor", "_damp", "_tau_max",
        "_lin", "_quad", "_box", "_k", "_c", "_mu", "_reach", "_rate", "_w_t",
    )
    # The state's types (the slots above hold them).
    _t: float
    _p: Vec3
    _v: Vec3
    _q: Quat
    _w: Vec3
    _sf_world: Vec3
    _reading: SensorReading | None

    def __init__(
        self,
        params: QuadParams = IRIS,
        sensors: SensorConfig | None = None,
        wind: Wind | None = None,
        home: GeoPoint | None = None,
        seed: int = 0,
    ) -> None:
        self.params = params
        self.sensor_config = sensors if sensors is not None else SensorConfig()
        self.wind = wind
        self.home = home if home is not None else GeoPoint(0.0, 0.0, 0.0)
        self._seed = seed
        self._sensors = SensorModel(self.sensor_config, seed)
        self._wind = WindField(wind, seed) if wind is not None else None
        #: Each rotor's thrust and drag torque as a fraction of a healthy one's.
        self._thrust_scale = (1.0, 1.0, 1.0, 1.0)
        self._geo = GeodeticProjection(self.home)
        self._cache_constants(params)
        self._dt = -1.0
        self._alpha = 0.0
        self._n_sub = 1
        self._stick = 0.0
        self._t = 0.0
        self._t_err = 0.0
        self._held = False
        self.reset()

    # ---- set-up ---------------------------------------------------------------------------

    def _cache_constants(self, p: QuadParams) -> None:
        self._m = p.mass_kg
        self._inv_m = 1.0 / p.mass_kg
        self._j = p.inertia_kg_m2
        self._g = STANDARD_GRAVITY_M_S2
        # Per rotor: (x, y, spin sign +1 CCW); the hub height does not enter the model (thrust
        # is along body z, and no in-plane rotor force is modelled).
        self._rotors = tuple(
            (pos[0], pos[1], 1.0 if ccw else -1.0)
            for pos, ccw in zip(p.rotor_positions_frd_m, p.rotor_spin_ccw, strict=True)
        )
        self._kf = p.thrust_coefficient_n_per_rad2_s2
        self._kq = p.torque_coefficient_nm_per_rad2_s2
        self._ir = p.rotor_inertia_kg_m2
        self._inflow = p.axial_inflow
        self._inflow_inv_m = 1.0 / (p.blade_radius_m * p.blade_pitch_rad)
        self._stall_ratio = p.blade_stall_rad / p.blade_pitch_rad
        self._drive = p.motor_p_gain_nm_s_per_rad * p.motor_command_speed_rad_s
        self._b_motor = p.motor_p_gain_nm_s_per_rad + p.rotor_damping_nm_s_per_rad
        self._damp = p.rotor_damping_nm_s_per_rad
        self._tau_max = p.motor_torque_limit_nm
        self._lin = p.drag_linear_n_s_per_m
        self._quad = p.drag_quadratic_n_s2_per_m2
        ax, ay, zb, zt = p.contact_half_x_m, p.contact_half_y_m, p.contact_bottom_m, p.contact_top_m
        self._box = (ax, ay, zb, zt)
        self._k = p.contact_stiffness_n_per_m
        self._c = p.contact_damping_n_s_per_m
        self._mu = p.friction_coefficient
        self._reach = math.sqrt(ax * ax + ay * ay + max(zb, -zt) ** 2)
        jx, jy, jz = p.inertia_kg_m2
        # Fastest contact damping rate (1/s): vertical, roll and pitch modes on four corners.
        c4 = 4.0 * self._c
        self._rate = max(c4 / p.mass_kg, c4 * ay * ay / jx, c4 * ax * ax / jy)
        # Largest inverse effective mass of a corner pushed sideways (1/kg): sets the stick.
        self._w_t = 1.0 / p.mass_kg + max(zb * zb / jy + ay * ay / jz, zb * zb / jx + ax * ax / jz)

    def _set_step(self, dt_s: float) -> None:
        p = self.params
        self._dt = dt_s
        self._alpha = -math.expm1(-dt_s / p.motor_time_constant_s)
        self._n_sub = max(1, math.ceil(dt_s * self._rate / CONTACT_RATE_STEP))
        h_sub = dt_s / self._n_sub
        # Viscous stick per corner: four corners together remove at most CONTACT_RATE_STEP of
        # a corner's sideways velocity per sub-step (so never overshoot into chatter).
        self._stick = CONTACT_RATE_STEP / (4.0 * self._w_t * h_sub)

    # ---- public state ---------------------------------------------------------------------

    @property
    def time_s(self) -> float:
        """Simulated time (s) since construction (``reset`` leaves it alone)."""
        return self._t

    @property
    def altitude_m(self) -> float:
        """Height of the centre of mass above the ground plane (m, up positive)."""
        return -self._p[2]

    agl_m = altitude_m

    @property
    def on_ground(self) -> bool:
        """True while any corner of the contact box touches the ground."""
        return self._resting or self._touching > 0

    @property
    def at_rest(self) -> bool:
        """True while parked on the skids under static friction (the body is frozen)."""
        return self._resting

    @property
    def held(self) -> bool:
        return self._held

    @property
    def wind_ned_m_s(self) -> Vec3:
        """Current air velocity (constant + gust), m/s NED."""
        return self._wind.current() if self._wind is not None else (0.0, 0.0, 0.0)

    @property
    def state(self) -> VehicleState:
        om = self._om
        return VehicleState(
            self._t, self._p, self._v, self._q, self._w, (om[0], om[1], om[2], om[3]),
            self.on_ground,
        )

    @property
    def specific_force_frd_m_s2(self) -> Vec3:
        """What an ideal accelerometer reads now, body FRD: no noise, no bias, and no draw
        from the sensors' random generator (watching leaves the flight as it is)."""
        return _rotate_inverse(self._q, self._sf_world)

    # ---- control ----------------------------------------------------------------------------

    def hold(self, enabled: bool = True) -> None:
        """Freeze the pose (a test stand): stepping then only advances time and the motors.

        While held, readings report the pose and the velocities last given to :meth:`reset`
        (zero unless set), and the accelerometer reads R^T (0, 0, -g) as if a hand held the
        vehicle.  Releasing continues the dynamics from that state.
        """
        self._held = bool(enabled)
        self._sf_world = (0.0, 0.0, -self._g) if self._held else self._sf_world
        self._reading = None

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
        """
        if quaternion_wxyz is not None:
            if roll_deg or pitch_deg or yaw_deg:
                raise SimInputError("reset: give quaternion_wxyz or Euler angles, not both")
            q = quat_normalize(_vec4(quaternion_wxyz, "quaternion_wxyz"))
        else:
            q = quat_normalize(quat_from_euler_deg(
                *_vector((roll_deg, pitch_deg, yaw_deg), 3, "roll/pitch/yaw_deg")))
        velocity = _vec3(velocity_ned_m_s, "velocity_ned_m_s")
        rates = _vec3(angular_velocity_frd_rad_s, "angular_velocity_frd_rad_s")
        speeds = _vector(motor_speeds_rad_s, 4, "motor_speeds_rad_s")
        if min(speeds) < 0:
            raise SimInputError(f"reset: motor speeds must be >= 0 rad/s, got {speeds}")
        lowest = self._lowest_corner_m(q)
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
        self._q, self._p, self._v, self._w = q, position, velocity, rates
        self._om = list(speeds)
        self._om_dot = [0.0, 0.0, 0.0, 0.0]
        bottom, top = self._corners_touching()
        self._touching = bottom + top
        self._on_skids = bottom == 4 and top == 0
        self._resting = self._on_skids and not any(self._v) and not any(self._w)
        if self._resting or self._held:
            self._sf_world = (0.0, 0.0, -self._g)
        else:
            fb, _ = self._applied_wrench((0.0, 0.0, 0.0))
            self._sf_world = _rotate(self._q, fb, self._inv_m)
        self._reading = None

    # ---- the step -----------------------------------------------------------------------------

    def step(self, motors: Motors, dt_s: float) -> None:
        """Advance ``dt_s`` seconds with the motor commands held (zero-order hold, as Gazebo)."""
        u1, u2, u3, u4 = check_step_input(motors, dt_s)
        if dt_s != self._dt:
            self._set_step(dt_s)
        self._update_motors((u1, u2, u3, u4), dt_s)
        # Kahan-compensated clock: a million 1 ms steps still read 1000.000 s.
        y = dt_s - self._t_err
        t = self._t + y
        self._t_err = (t - self._t) - y
        self._t = t
        self._reading = None
        if self._wind is not None:
            self._wind.advance(dt_s)
        if self._held:
            return
        wind = self._wind.current() if self._wind is not None else (0.0, 0.0, 0.0)
        fb, mb = self._applied_wrench(wind)
        if self._resting:
            if self._rest_holds(fb, mb, 1.0):
                return
            self._resting = False
        if self._contact_possible(dt_s):
            n_sub = self._n_sub
            h = dt_s / n_sub
            sx = sy = sz = 0.0
            for _ in range(n_sub):
                ax, ay, az = self._substep(h, fb, mb, True)
                sx += ax
                sy += ay
                sz += az
            inv = 1.0 / n_sub
            self._sf_world = (sx * inv, sy * inv, sz * inv)
            if self._on_skids and self._at_rest_now(fb, mb):
                self._resting = True
                self._v = self._w = (0.0, 0.0, 0.0)
                self._sf_world = (0.0, 0.0, -self._g)
        else:
            self._touching = 0
            self._on_skids = False
            self._sf_world = self._substep(dt_s, fb, mb, False)

    def _update_motors(self, commands: Motors, h: float) -> None:
        """Exact first-order lag to the P controller's steady speed, within the torque clamp."""
        drive, b, kq = self._drive, self._b_motor, self._kq
        damp, tau_max = self._damp, self._tau_max
        alpha, inv_ir_h, inv_h = self._alpha, h / self._ir, 1.0 / h
        om, om_dot = self._om, self._om_dot
        four_kq = 4.0 * kq
        for i in range(4):
            u = commands[i]
            u = 0.0 if u < 0.0 else (1.0 if u > 1.0 else u)
            d = drive * u
            target = 2.0 * d / (b + math.sqrt(b * b + four_kq * d)) if d > 0.0 else 0.0
            o = om[i]
            delta = (target - o) * alpha
            load = damp * o + kq * o * o
            up = (tau_max - load) * inv_ir_h
            if delta > up:
                delta = up
            else:
                down = (-tau_max - load) * inv_ir_h
                if delta < down:
                    delta = down
            if o + delta < 0.0:
                delta = -o
            om[i] = o + delta
            om_dot[i] = delta * inv_h

    def _applied_wrench(self, wind: Vec3) -> tuple[Vec3, Vec3]:
        """Body-frame force and torque of rotors and drag (everything but gravity and ground)."""
        w, x, y, z = self._q
        xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
        wx, wy, wz = w * x, w * y, w * z
        vx, vy, vz = self._v[0] - wind[0], self._v[1] - wind[1], self._v[2] - wind[2]
        # Air velocity in body axes: R^T v.
        bx = (1.0 - 2.0 * (yy + zz)) * vx + 2.0 * (xy + wz) * vy + 2.0 * (xz - wy) * vz
        by = 2.0 * (xy - wz) * vx + (1.0 - 2.0 * (xx + zz)) * vy + 2.0 * (yz + wx) * vz
        bz = 2.0 * (xz + wy) * vx + 2.0 * (yz - wx) * vy + (1.0 - 2.0 * (xx + yy)) * vz
        p, q, r = self._w
        kf, kq, ir = self._kf, self._kq, self._ir
        thrust = mx = my = mz = 0.0
        inflow, inflow_inv_m, stall = self._inflow, self._inflow_inv_m, self._stall_ratio
        om, om_dot = self._om, self._om_dot
        scale = self._thrust_scale
        for i in range(4):
            rx, ry, s = self._rotors[i]
            o = om[i]
            if inflow:
                # Axial air speed up through the disc: -(v_body + omega x r) . z_body.
                v_axial = -(bz + p * ry - q * rx)
                t = kf * o * (o - v_axial * inflow_inv_m)
                cap = kf * o * o * stall
                t = 0.0 if t < 0.0 else (cap if t > cap else t)
            else:
                t = kf * o * o
            k = scale[i]
            t *= k
            thrust += t
            mx -= ry * t
            my += rx * t
            mz += s * (k * kq * o * o + ir * om_dot[i])
        # (The rotors' gyroscopic torque is not here: Euler's equations in _substep carry the
        # rotors' spin momentum in the body's angular momentum.)
        lin, quad = self._lin, self._quad
        speed = math.sqrt(bx * bx + by * by + bz * bz)
        fx = -(lin[0] + quad[0] * speed) * bx
        fy = -(lin[1] + quad[1] * speed) * by
        fz = -(lin[2] + quad[2] * speed) * bz - thrust
        return (fx, fy, fz), (mx, my, mz)

    def _substep(self, h: float, fb: Vec3, mb: Vec3, contact: bool) -> Vec3:
        """Integrate the rigid body over h; returns the world specific force applied (m/s^2)."""
        w, x, y, z = self._q
        xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
        qwx, qwy, qwz = w * x, w * y, w * z
        r00, r01, r02 = 1.0 - 2.0 * (yy + zz), 2.0 * (xy - qwz), 2.0 * (xz + qwy)
        r10, r11, r12 = 2.0 * (xy + qwz), 1.0 - 2.0 * (xx + zz), 2.0 * (yz - qwx)
        r20, r21, r22 = 2.0 * (xz - qwy), 2.0 * (yz + qwx), 1.0 - 2.0 * (xx + yy)
        fx, fy, fz = fb
        mx, my, mz = mb
        inv_m = self._inv_m
        ax = (r00 * fx + r01 * fy + r02 * fz) * inv_m
        ay = (r10 * fx + r11 * fy + r12 * fz) * inv_m
        az = (r20 * fx + r21 * fy + r22 * fz) * inv_m
        if contact:
            cfx, cfy, cfz, cmx, cmy, cmz = self._contact(
                r00, r01, r02, r10, r11, r12, r20, r21, r22)
            ax += cfx * inv_m
            ay += cfy * inv_m
            az += cfz * inv_m
            mx += cmx
            my += cmy
            mz += cmz
        px, py, pz = self._p
        vx, vy, vz = self._v
        vx += ax * h
        vy += ay * h
        vz += (az + self._g) * h
        self._v = (vx, vy, vz)
        self._p = (px + vx * h, py + vy * h, pz + vz * h)
        # Euler's equations, explicit midpoint: J dw/dt = M - w x (J w + h_rotor z), where
        # h_rotor = -I_r sum(s Omega) is the rotors' spin momentum along body z (a CCW rotor's
        # points up, -z); w x h_rotor z is their gyroscopic torque.
        jx, jy, jz = self._j
        hr = -self._ir * (self._om[0] * self._rotors[0][2] + self._om[1] * self._rotors[1][2]
                          + self._om[2] * self._rotors[2][2] + self._om[3] * self._rotors[3][2])
        p0, q0, r0 = p, q, r = self._w
        lx, ly, lz = jx * p, jy * q, jz * r + hr
        half = 0.5 * h
        pm = p + half * (mx - (q * lz - r * ly)) / jx
        qm = q + half * (my - (r * lx - p * lz)) / jy
        rm = r + half * (mz - (p * ly - q * lx)) / jz
        lx, ly, lz = jx * pm, jy * qm, jz * rm + hr
        p += h * (mx - (qm * lz - rm * ly)) / jx
        q += h * (my - (rm * lx - pm * lz)) / jy
        r += h * (mz - (pm * ly - qm * lx)) / jz
        self._w = (p, q, r)
        # Attitude: exponential map of the step's mean rate.
        self._q = quat_integrate(
            (w, x, y, z), (0.5 * (p0 + p), 0.5 * (q0 + q), 0.5 * (r0 + r)), h
        )
        return (ax, ay, az)

    # ---- sensors ------------------------------------------------------------------------------

    # ---- faults (scenarios change these mid-flight, between two steps) -------------------

    @property
    def motor_thrust(self) -> tuple[float, float, float, float]:
        """Each rotor's thrust as a fraction of a healthy one's (Betaflight order M1..M4)."""
        a, b, c, d = self._thrust_scale
        return (a, b, c, d)

    def set_motor_thrust(self, motor: int, fraction: float) -> None:
        """Motor ``motor`` (1..4, Betaflight's numbering) gives ``fraction`` of its thrust and
        drag torque at any speed: a damaged propeller or a weak motor."""
        if motor not in (1, 2, 3, 4):
            raise SimInputError(f"motor {motor} does not exist: a quad has motors 1 to 4")
        if not (math.isfinite(fraction) and 0.0 <= fraction <= 1.0):
            raise SimInputError(f"motor {motor}: thrust fraction {fraction} is outside 0..1")
        scale = list(self._thrust_scale)
        scale[motor - 1] = float(fraction)
        self._thrust_scale = (scale[0], scale[1], scale[2], scale[3])

    def set_wind(self, wind: Wind | None) -> None:
        """The wind from now on (None: still air); its gusts are drawn afresh from the run's
        seed, so a run stays repeatable."""
        self.wind = wind
        self._wind = WindField(wind, self._seed) if wind is not None else None

    def set_sensors(self, config: SensorConfig) -> None:
        """The sensor errors from now on (the noise generators go on where they were)."""
        self.sensor_config = config
        self._sensors.reconfigure(config, self._t)
        self._reading = None

    def read_sensors(self) -> SensorReading:
        """What the IMU and barometer report now (the same object until the next step)."""
        reading = self._reading
        if reading is not None:
            return reading
        q, p, v = self._q, self._p, self._v
        f = _rotate_inverse(q, self._sf_world)
        pressure = isa_pressure_pa(self.home.alt_m - p[2])
        gyro, f, pressure = self._sensors.corrupt(self._w, f, pressure, self._t)
        # The GPS's error moves only its own fields: the truth (position_ned_m) stays true.
        dn, de, dvn, dve = self._sensors.gps_error(self._t)
        reading = SensorReading(
            self._t, gyro, f, q, pressure, p, v,
            self._geo.lon_lat_alt((p[0] + dn, p[1] + de, p[2])),
            (v[1] + dve, v[0] + dvn, -v[2]),
        )
        self._reading = reading
        return reading


# ---- helpers --------------------------------------------------------------------------------


def _rotate(q: Quat, v: Vec3, scale: float = 1.0) -> Vec3:
    w, x, y, z = q
    a, b, c = v[0] * scale, v[1] * scale, v[2] * scale
    return (
        (1.0 - 2.0 * (y * y + z * z)) * a + 2.0 * (x * y - w * z) * b + 2.0 * (x * z + w * y) * c,
        2.0 * (x * y + w * z) * a + (1.0 - 2.0 * (x * x + z * z)) * b + 2.0 * (y * z - w * x) * c,
        2.0 * (x * z - w * y) * a + 2.0 * (y * z + w * x) * b + (1.0 - 2.0 * (x * x + y * y)) * c,
    )


def _rotate_inverse(q: Quat, v: Vec3) -> Vec3:
    w, x, y, z = q
    a, b, c = v
    return (
        (1.0 - 2.0 * (y * y + z * z)) * a + 2.0 * (x * y + w * z) * b + 2.0 * (x * z - w * y) * c,
        2.0 * (x * y - w * z) * a + (1.0 - 2.0 * (x * x + z * z)) * b + 2.0 * (y * z + w * x) * c,
        2.0 * (x * z + w * y) * a + 2.0 * (y * z - w * x) * b + (1.0 - 2.0 * (x * x + y * y)) * c,
    )


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
    step's input (the reference's checks; the compiled kernel's face raises the same)."""
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
