"""A vehicle as a pilot describes it (:class:`VehicleSpec`: mass, frame, props, the motor
maker's thrust table, motor lag), and the physics it becomes (:func:`quad_params`).

The embedded physics models each motor as Gazebo's IRIS does: a speed controller driving a
rotor of inertia ``I_r`` toward ``command x top speed``, thrust ``k_T w^2`` less the blades'
axial inflow, drag torque ``k_Q w^2``.  From a pilot's figures:

* ``k_T`` = full-throttle static thrust / (full-throttle speed)^2: the thrust table's top row
  (a static bench test is what the model's zero-inflow thrust is).
* ``k_Q`` = ``yaw_torque_per_thrust_mm`` x ``k_T``: the prop's torque over its thrust.
* The speed controller's gain is ``I_r / motor_time_constant``, with no damping and no torque
  limit in reach: the physics moves the rotor speed toward the command's steady speed as a
  first-order lag of that time constant.  The command that holds full speed is raised by the
  drag torque the controller must overcome, so the steady speed is concave in the command:
  half the command gives about a third of the full thrust, as measured thrust tables of small
  motors show (between 0.3 and 0.5).
* The blades' pitch angle is the prop's geometric pitch at three quarters of its radius, where
  the blade element sits.
* The skids: a box from the frame's motor square, sinking 1.4 mm under the quad's weight
  (as IRIS's does), damped and with the friction of IRIS.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import QuadParams, Vec3

#: Betaflight's default quad-X with props in, as IRIS: M1 rear right CW, M2 front right CCW,
#: M3 rear left CCW, M4 front left CW.
PROPS_IN_SPIN_CCW = (False, True, True, False)
#: How far the skids sink under the quad's weight (IRIS's 3000 N/m per corner).
RESTING_SAG_M = 0.0014
#: IRIS's contact damping ratio and friction (physics/params.py says why).
CONTACT_DAMPING_RATIO = 1.5
FRICTION_COEFFICIENT = 1.0
#: The LiftDrag element's stall angle of IRIS: it caps the thrust gained in a descent.
BLADE_STALL_RAD = 1.4
#: The blade element sits at three quarters of the prop's radius.
BLADE_ELEMENT_RADIUS_SHARE = 0.75
INCH_M = 0.0254


@dataclass(frozen=True, slots=True)
class VehicleSpec:
    """A quad-X as a pilot knows it; every figure with its unit in its name.

    Attributes:
        name: What ``--vehicle`` calls it (``5inch-freestyle``).
        description: The build in a line: frame, motors, props, battery.
        mass_g: All-up weight, battery included.
        wheelbase_mm: Diagonal motor-to-motor distance (the frame's size).
        inertia_kg_m2: Moments of inertia about roll, pitch, yaw (FRD) through the centre
            of mass.
        prop_diameter_in: Propeller diameter, inches.
        prop_pitch_in: Propeller pitch, inches.
        max_thrust_g: One motor's static thrust at full throttle, grams (the thrust table).
        max_rpm: One motor's speed at full throttle, revolutions per minute (the same row).
        motor_time_constant_ms: How fast a motor's speed follows its command (63 %).
        yaw_torque_per_thrust_mm: A prop's drag torque over its thrust, millimetres (N m per
            N x 1000): what yaws the quad.
        rotor_inertia_kg_m2: One prop with the motor's bell about the spin axis.
        drag_linear_n_s_per_m: Body drag proportional to airspeed, per body axis.
        drag_quadratic_n_s2_per_m2: Body drag proportional to airspeed squared (1/2 rho Cd A),
            per body axis.
        com_to_skids_mm: From the centre of mass down to what rests on the ground.
        com_to_top_mm: From the centre of mass up to the top of the frame.
        rotors_above_com_mm: How far the props' plane is above the centre of mass.
        sources: Where each figure comes from, by field name.
    """

    name: str
    description: str
    mass_g: float
    wheelbase_mm: float
    inertia_kg_m2: Vec3
    prop_diameter_in: float
    prop_pitch_in: float
    max_thrust_g: float
    max_rpm: float
    motor_time_constant_ms: float
    yaw_torque_per_thrust_mm: float
    rotor_inertia_kg_m2: float
    drag_linear_n_s_per_m: Vec3
    drag_quadratic_n_s2_per_m2: Vec3
    com_to_skids_mm: float
    com_to_top_mm: float
    rotors_above_com_mm: float = 10.0
    sources: dict[str, str] = field(default_factory=dict)

    @property
    def thrust_to_weight(self) -> float:
        """Four motors' full static thrust over the weight."""
        return 4.0 * self.max_thrust_g / self.mass_g

    @property
    def max_speed_rad_s(self) -> float:
        return self.max_rpm * 2.0 * math.pi / 60.0


def quad_params(spec: VehicleSpec) -> QuadParams:
    """The embedded physics' parameters of ``spec`` (the module doc says how each is made).

    Raises:
        SimInputError: A figure the physics cannot use (it names the field).
    """
    g = STANDARD_GRAVITY_M_S2
    mass_kg = spec.mass_g / 1000.0
    top_speed = spec.max_speed_rad_s
    k_thrust = spec.max_thrust_g / 1000.0 * g / top_speed**2
    k_torque = spec.yaw_torque_per_thrust_mm / 1000.0 * k_thrust
    p_gain = spec.rotor_inertia_kg_m2 / (spec.motor_time_constant_ms / 1000.0)
    # At full command the controller holds top speed against the prop's drag torque.
    command_speed = top_speed + k_torque * top_speed**2 / p_gain
    arm_m = spec.wheelbase_mm / 2000.0
    corner_m = arm_m / math.sqrt(2.0)
    rotor_z = -spec.rotors_above_com_mm / 1000.0
    radius_m = spec.prop_diameter_in * INCH_M / 2.0
    element_m = BLADE_ELEMENT_RADIUS_SHARE * radius_m
    pitch_rad = math.atan(spec.prop_pitch_in * INCH_M / (2.0 * math.pi * element_m))
    return QuadParams(
        name=spec.name,
        mass_kg=mass_kg,
        inertia_kg_m2=spec.inertia_kg_m2,
        rotor_positions_frd_m=(
            (-corner_m, corner_m, rotor_z),  # M1 rear right
            (corner_m, corner_m, rotor_z),  # M2 front right
            (-corner_m, -corner_m, rotor_z),  # M3 rear left
            (corner_m, -corner_m, rotor_z),  # M4 front left
        ),
        rotor_spin_ccw=PROPS_IN_SPIN_CCW,
        thrust_coefficient_n_per_rad2_s2=k_thrust,
        torque_coefficient_nm_per_rad2_s2=k_torque,
        rotor_inertia_kg_m2=spec.rotor_inertia_kg_m2,
        motor_command_speed_rad_s=command_speed,
        motor_p_gain_nm_s_per_rad=p_gain,
        # Out of reach: the speed follows its command as a pure first-order lag.
        motor_torque_limit_nm=2.0 * p_gain * command_speed,
        rotor_damping_nm_s_per_rad=0.0,
        blade_radius_m=element_m,
        blade_pitch_rad=pitch_rad,
        blade_stall_rad=max(BLADE_STALL_RAD, 2.0 * pitch_rad),
        axial_inflow=True,
        drag_linear_n_s_per_m=spec.drag_linear_n_s_per_m,
        drag_quadratic_n_s2_per_m2=spec.drag_quadratic_n_s2_per_m2,
        contact_half_x_m=corner_m,
        contact_half_y_m=corner_m,
        contact_bottom_m=spec.com_to_skids_mm / 1000.0,
        contact_top_m=-spec.com_to_top_mm / 1000.0,
        contact_stiffness_n_per_m=mass_kg * g / (4.0 * RESTING_SAG_M),
        contact_damping_ratio=CONTACT_DAMPING_RATIO,
        friction_coefficient=FRICTION_COEFFICIENT,
    )
