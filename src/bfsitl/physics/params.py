"""Vehicle and wind parameters of the embedded physics, with where every number comes from.

The default vehicle, :data:`IRIS`, reproduces the quadrotor that Betaflight's own Gazebo world
flies (``osrf/vehicle_gateway`` ``betaflight_sim/models/iris_with_standoffs/model.sdf`` and
``worlds/empty_betaflight_world.sdf``), so PID tunes and behaviours carry over between the two.
Gazebo has no motor model plugin for it: thrust and rotor torque come from ``LiftDrag`` blade
elements and the motors are joint-velocity P controllers.  The equivalent lumped numbers below
were derived from those SDF values (blade-element lift and drag of the rotors, the joint
controllers' limits) and re-checked here (see each field's comment).

Frames: body FRD (x forward, y right, z down) with its origin at the centre of mass; world NED.
Motor order everywhere in :mod:`bfsitl.sim` is Betaflight's: M1 rear-right, M2 front-right,
M3 rear-left, M4 front-left (quad-X, props in).  The servo-slot permutation of the SITL packet
belongs to the bridge (:meth:`bfsitl.protocol.sitl_packets.ServoPacket.betaflight_motors`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bfsitl.errors import SimInputError
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Motors = tuple[float, float, float, float]

#: Standard gravity (m/s^2), the value Betaflight's SITL scales the accelerometer with
#: (``sitl.c``: ``256 / 9.80665`` LSB per m/s^2) and the ISA uses.
#: Air density at sea level (kg/m^3), as the Gazebo LiftDrag elements of IRIS use it.
AIR_DENSITY_KG_M3 = 1.2041


@dataclass(frozen=True, slots=True)
class QuadParams:
    """A quad-X rigid body with four fixed-pitch rotors, Gazebo-IRIS style actuators, box contact.

    Units are in every name.  Vectors are body FRD relative to the centre of mass (CoM).
    Tuples of four are in Betaflight motor order (M1..M4).
    """

    name: str
    mass_kg: float
    #: Principal moments about the CoM (the products of inertia are zero for IRIS).
    inertia_kg_m2: Vec3
    #: Rotor hub positions relative to the CoM, FRD, per Betaflight motor M1..M4.
    rotor_positions_frd_m: tuple[Vec3, Vec3, Vec3, Vec3]
    #: True where the rotor spins counter-clockwise seen from above (its reaction yaws the frame
    #: clockwise, +r in FRD).
    rotor_spin_ccw: tuple[bool, bool, bool, bool]
    #: Static thrust T = k * omega^2 (N per (rad/s)^2).
    thrust_coefficient_n_per_rad2_s2: float
    #: Aerodynamic rotor drag torque Q = k * omega^2 (N m per (rad/s)^2).
    torque_coefficient_nm_per_rad2_s2: float
    #: Rotor (propeller) inertia about its spin axis; its spin-up reaction torque I*dOmega/dt
    #: dominates transient yaw on IRIS (docs/firmware-facts.md#iris-motors).
    rotor_inertia_kg_m2: float
    #: Rotor speed target per unit of servo_packet command (rad/s at u = 1).
    motor_command_speed_rad_s: float
    #: Motor speed controller: torque = P * (target - omega), clamped to +-limit.
    motor_p_gain_nm_s_per_rad: float
    motor_torque_limit_nm: float
    #: Viscous damping of the rotor joint (N m per rad/s); lowers the steady speed below target.
    rotor_damping_nm_s_per_rad: float
    #: Blade-element radius and zero-inflow angle of attack: climbing at v_axial lowers the
    #: blades' angle of attack by ~v_axial / (omega * radius), so thrust falls by that over the
    #: pitch (Gazebo-IRIS's dominant aerodynamic effect, docs/firmware-facts.md#iris-motors).
    blade_radius_m: float
    blade_pitch_rad: float
    #: Angle of attack at which the LiftDrag element stalls (caps the descent thrust gain).
    blade_stall_rad: float
    #: Apply the axial-inflow thrust change above (False: plain T = k * omega^2 always).
    axial_inflow: bool
    #: Body drag per body axis: F = -(linear * v + quadratic * |v| * v), v relative to the air.
    drag_linear_n_s_per_m: Vec3
    drag_quadratic_n_s2_per_m2: Vec3
    #: The contact box: corners at (+-half_x, +-half_y, bottom) and (.., .., top), FRD from CoM.
    contact_half_x_m: float
    contact_half_y_m: float
    contact_bottom_m: float
    contact_top_m: float
    #: Spring per corner, and the damping ratio of the vertical mode on the four skid corners.
    contact_stiffness_n_per_m: float
    contact_damping_ratio: float
    #: Coulomb friction coefficient between the contact box and the ground.
    friction_coefficient: float

    def __post_init__(self) -> None:
        positive = {
            "mass_kg": self.mass_kg,
            "thrust_coefficient_n_per_rad2_s2": self.thrust_coefficient_n_per_rad2_s2,
            "rotor_inertia_kg_m2": self.rotor_inertia_kg_m2,
            "motor_command_speed_rad_s": self.motor_command_speed_rad_s,
            "motor_p_gain_nm_s_per_rad": self.motor_p_gain_nm_s_per_rad,
            "motor_torque_limit_nm": self.motor_torque_limit_nm,
            "blade_radius_m": self.blade_radius_m,
            "blade_pitch_rad": self.blade_pitch_rad,
            "contact_half_x_m": self.contact_half_x_m,
            "contact_half_y_m": self.contact_half_y_m,
            "contact_bottom_m": self.contact_bottom_m,
            "contact_stiffness_n_per_m": self.contact_stiffness_n_per_m,
        }
        positive.update({f"inertia_kg_m2[{i}]": v for i, v in enumerate(self.inertia_kg_m2)})
        for name, value in positive.items():
            if not (math.isfinite(value) and value > 0):
                raise SimInputError(f"QuadParams {self.name!r}: {name} must be > 0, got {value}")
        non_negative = {
            "torque_coefficient_nm_per_rad2_s2": self.torque_coefficient_nm_per_rad2_s2,
            "rotor_damping_nm_s_per_rad": self.rotor_damping_nm_s_per_rad,
            "contact_damping_ratio": self.contact_damping_ratio,
            "friction_coefficient": self.friction_coefficient,
            **{f"drag_linear_n_s_per_m[{i}]": v for i, v in enumerate(self.drag_linear_n_s_per_m)},
            **{
                f"drag_quadratic_n_s2_per_m2[{i}]": v
                for i, v in enumerate(self.drag_quadratic_n_s2_per_m2)
            },
        }
        for name, value in non_negative.items():
            if not (math.isfinite(value) and value >= 0):
                raise SimInputError(f"QuadParams {self.name!r}: {name} must be >= 0, got {value}")
        if len(self.rotor_positions_frd_m) != 4 or len(self.rotor_spin_ccw) != 4:
            raise SimInputError(f"QuadParams {self.name!r}: needs exactly four rotors")
        if self.contact_top_m >= self.contact_bottom_m:
            raise SimInputError(
                f"QuadParams {self.name!r}: contact_top_m must be above (smaller than) "
                f"contact_bottom_m in FRD"
            )
        if self.blade_stall_rad <= self.blade_pitch_rad:
            raise SimInputError(f"QuadParams {self.name!r}: blade_stall_rad must exceed the pitch")

    # ---- derived actuator figures (docs/firmware-facts.md#iris-motors) ---------------------

    @property
    def weight_n(self) -> float:
        return self.mass_kg * STANDARD_GRAVITY_M_S2

    @property
    def motor_time_constant_s(self) -> float:
        """Small-signal lag of the rotor speed: I_r / (P + damping) (0.82 ms for IRIS)."""
        return self.rotor_inertia_kg_m2 / (
            self.motor_p_gain_nm_s_per_rad + self.rotor_damping_nm_s_per_rad
        )

    def steady_rotor_speed_rad_s(self, command: float) -> float:
        """Rotor speed the P controller settles at for a command, before the torque limit.

        Solves P * (838 u - w) = damping * w + k_Q * w^2 (torque balance on the rotor joint);
        for IRIS that is ~821.6 rad/s per unit command (838 u / 1.02,
        docs/firmware-facts.md#iris-motors).
        """
        p = self.motor_p_gain_nm_s_per_rad
        b = p + self.rotor_damping_nm_s_per_rad
        kq = self.torque_coefficient_nm_per_rad2_s2
        drive = p * self.motor_command_speed_rad_s * max(command, 0.0)
        if kq == 0.0:
            return drive / b
        # Numerically stable root of kq w^2 + b w - drive = 0.
        return 2.0 * drive / (b + math.sqrt(b * b + 4.0 * kq * drive))

    @property
    def max_rotor_speed_rad_s(self) -> float:
        """Where the clamped motor torque only balances damping and drag (620.9 rad/s for IRIS)."""
        b = self.rotor_damping_nm_s_per_rad
        kq = self.torque_coefficient_nm_per_rad2_s2
        limit = self.motor_torque_limit_nm
        if kq == 0.0:
            return math.inf if b == 0.0 else limit / b
        return 2.0 * limit / (b + math.sqrt(b * b + 4.0 * kq * limit))

    @property
    def hover_rotor_speed_rad_s(self) -> float:
        """Rotor speed at which four rotors carry the weight with no inflow."""
        return math.sqrt(self.weight_n / (4.0 * self.thrust_coefficient_n_per_rad2_s2))

    @property
    def hover_command(self) -> float:
        """The servo_packet value (0..1) that holds the vehicle in level hover (0.5417 for IRIS)."""
        omega = self.hover_rotor_speed_rad_s
        if omega >= self.max_rotor_speed_rad_s:
            raise SimInputError(f"QuadParams {self.name!r}: cannot hover (too heavy)")
        p = self.motor_p_gain_nm_s_per_rad
        torque = (
            p + self.rotor_damping_nm_s_per_rad
        ) * omega + self.torque_coefficient_nm_per_rad2_s2 * omega * omega
        return torque / (p * self.motor_command_speed_rad_s)

    # ---- derived contact figures ------------------------------------------------------------

    @property
    def contact_damping_n_s_per_m(self) -> float:
        """Damper per corner: the vertical mode on four corners gets ``contact_damping_ratio``.

        Critical damping of mass m on four springs k is 2 sqrt(4 k m), i.e. sqrt(k m) per corner.
        """
        return self.contact_damping_ratio * math.sqrt(self.contact_stiffness_n_per_m * self.mass_kg)

    @property
    def resting_sag_m(self) -> float:
        """How far the skid corners sink into the ground under the vehicle's own weight."""
        return self.weight_n / (4.0 * self.contact_stiffness_n_per_m)

    @property
    def resting_height_m(self) -> float:
        """Height of the CoM above flat ground when resting level on its skids, motors off."""
        return self.contact_bottom_m - self.resting_sag_m


# ---- the IRIS of Betaflight's Gazebo world ----------------------------------------------------
#
# model.sdf (FLU, origin at base_link): base_link 1.5 kg at the origin; imu_link 0.15 kg at the
# origin; four rotor links 0.025 kg at z = +0.023 m.  Mass 1.75 kg; CoM 0.0023/1.75 = 1.314 mm
# above the base origin.  Rotor hubs relative to the CoM are therefore 0.0217 m above it
# (FRD z = -0.0217).  The collision box (0.47 x 0.47 x 0.23 m at z = -0.08) spans FLU z from
# -0.195 to +0.035 m: FRD from the CoM +0.19631 (bottom, the skids) and -0.03369 (top).

_COM_ABOVE_BASE_M = 4 * 0.025 * 0.023 / 1.75  # rotor links' mass moment / total mass
_ROTOR_Z_FRD_M = -(0.023 - _COM_ABOVE_BASE_M)

IRIS = QuadParams(
    name="iris",
    # model.sdf: base_link 1.5 + imu_link 0.15 + 4 rotor links x 0.025 kg
    # (docs/firmware-facts.md#iris-model).
    mass_kg=1.75,
    # model.sdf inertias plus parallel-axis terms about the CoM (docs/firmware-facts.md#iris-model;
    # re-derived here: 0.008 + 1e-5 + 4*9.75e-6 + 0.025*sum(y^2 + z^2) + ... = 0.012519, and so on).
    inertia_kg_m2=(0.012519, 0.017427, 0.0238),
    # model.sdf rotor_3 (-0.13, -0.20), rotor_0 (0.13, -0.22), rotor_1 (-0.13, 0.20),
    # rotor_2 (0.13, 0.22) FLU -> FRD (x, -y, -z); servo slot 3, 0, 1, 2 = M1, M2, M3, M4
    # (sitl.c pwmCompleteMotorUpdate, docs/firmware-facts.md#motor-order).
    rotor_positions_frd_m=(
        (-0.13, 0.20, _ROTOR_Z_FRD_M),  # M1 rear right   (rotor_3)
        (0.13, 0.22, _ROTOR_Z_FRD_M),  # M2 front right  (rotor_0)
        (-0.13, -0.20, _ROTOR_Z_FRD_M),  # M3 rear left    (rotor_1)
        (0.13, -0.22, _ROTOR_Z_FRD_M),  # M4 front left   (rotor_2)
    ),
    # empty_betaflight_world.sdf: multiplier +838 (CCW, joint axis +z up) for rotor_0/1,
    # -838 (CW) for rotor_2/3 -> M1 CW, M2 CCW, M3 CCW, M4 CW (Betaflight props-in default).
    rotor_spin_ccw=(False, True, True, False),
    # LiftDrag: 2 elements x cla 4.25 x a0 0.3 x 1/2 rho 1.2041 x area 0.002 x r 0.084^2
    # = 2.1665e-5 (docs/firmware-facts.md#iris-model).
    thrust_coefficient_n_per_rad2_s2=2.1665e-5,
    # LiftDrag: 2 x r 0.084 x |cda 0.10 x a0 0.3| x 1/2 rho A r^2 = 4.282e-8
    # (docs/firmware-facts.md#iris-model).
    torque_coefficient_nm_per_rad2_s2=4.282e-8,
    # model.sdf rotor_i izz (spin axis).
    rotor_inertia_kg_m2=1.67604e-4,
    # empty_betaflight_world.sdf BetaflightPlugin <multiplier> 838
    # (docs/firmware-facts.md#iris-motors).
    motor_command_speed_rad_s=838.0,
    # empty_betaflight_world.sdf <p_gain> 0.20, <cmd_max>/<cmd_min> +-2.5
    # (docs/firmware-facts.md#iris-motors).
    motor_p_gain_nm_s_per_rad=0.2,
    motor_torque_limit_nm=2.5,
    # model.sdf rotor_i_joint <damping> 0.004.
    rotor_damping_nm_s_per_rad=0.004,
    # empty_betaflight_world.sdf LiftDrag cp (+-0.084, 0, 0), a0 0.3, alpha_stall 1.4
    # (docs/firmware-facts.md#iris-model).
    blade_radius_m=0.084,
    blade_pitch_rad=0.3,
    blade_stall_rad=1.4,
    axial_inflow=True,
    # NOT Gazebo parity (model.sdf velocity_decay 0: no body drag there).  Linear: PX4 iris
    # rotorDragCoefficient 1.75e-4 x hover rotor speed ~790 rad/s x 4 rotors ~ 0.55 N s/m,
    # horizontal only (iris.sdf.jinja, docs/firmware-facts.md#px4-iris).  Quadratic: 1/2 rho
    # Cd A with Cd ~ 1 and an estimated 0.05 m^2 side / 0.07 m^2 top area of the IRIS body and
    # arms.  Set both to zero for strict Gazebo parity.
    drag_linear_n_s_per_m=(0.55, 0.55, 0.0),
    drag_quadratic_n_s2_per_m2=(0.03, 0.03, 0.04),
    # model.sdf base_collision box 0.47 x 0.47 x 0.23 at z -0.08 (see the comment above).
    contact_half_x_m=0.235,
    contact_half_y_m=0.235,
    contact_bottom_m=0.195 + _COM_ABOVE_BASE_M,
    contact_top_m=-(0.035 - _COM_ABOVE_BASE_M),
    # 3000 N/m per corner, sag 1.4 mm (docs/firmware-facts.md#model-choices).  Damping: the
    # first design's 50 N s/m per corner (ratio 0.69) rebounds.  Even ratio 1.0 (critical in the
    # linear sense) rebounds from drops above ~1 m, because the ground only pushes: on the way
    # out the damper would have to pull, so it is clamped off and the overshoot returns.  1.5
    # (109 N s/m per corner) lands drops of 3 m (7.7 m/s) without leaving the ground again,
    # measured in the unit tests.
    contact_stiffness_n_per_m=3000.0,
    contact_damping_ratio=1.5,
    # mu = 1 (model.sdf's ODE mu 1e5 means "never slips"; 1 is enough for that;
    # docs/firmware-facts.md#model-choices).
    friction_coefficient=1.0,
)
