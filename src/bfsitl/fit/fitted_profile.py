"""A vehicle profile from a fit: what the log gave, over a base profile for what it cannot.

A log gives ratios, not the parts: thrust over mass, and each axis' angular acceleration per
unit of thrust.  With the mass the user states they become the profile's figures:

* ``max_thrust_g`` = thrust-to-weight x mass / 4;
* ``motor_time_constant_ms``: the motors' lag;
* roll and pitch inertia = one rotor's full thrust x its arm (the base's frame) / the axis'
  effectiveness;
* yaw inertia = the prop's torque per thrust (the base's prop) x one rotor's full thrust / the
  yaw effectiveness: a log cannot tell a stiffer yaw from a lighter one;
* the rotor inertia: what keeps the base's thrust curve shape with the fitted thrust and lag
  (the physics ties them: ``beta = torque per thrust x full thrust x lag / (rotor inertia x
  top speed)``), the shape the thrust was read with (:mod:`bfsitl.fit.thrust`).

Everything else (frame, props, top speed, drag, skids) is the base's, and ``[sources]`` says
which figure came from where.
"""

from __future__ import annotations

import dataclasses
import math

from bfsitl.fit.motor_model import curve_beta
from bfsitl.fit.rotation import RotationFit
from bfsitl.fit.thrust import ThrustFit
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.vehicles import VehicleSpec, quad_params, shipped_profiles


def closest_base(mass_g: float) -> VehicleSpec:
    """The shipped profile nearest in mass (on a log scale: 300 g is nearer 650 g than 100 g)."""
    return min(shipped_profiles().values(), key=lambda s: abs(math.log(s.mass_g / mass_g)))


def arm_m(spec: VehicleSpec) -> float:
    """A rotor's lever on roll and on pitch: half the wheelbase over the square root of two."""
    return spec.wheelbase_mm / 2000.0 / math.sqrt(2.0)


def fitted_spec(
    base: VehicleSpec,
    *,
    name: str,
    mass_g: float,
    label: str,
    rotation: RotationFit,
    thrust: ThrustFit,
) -> VehicleSpec:
    """The profile of the fitted quad (the module doc says how each figure is made)."""
    g = STANDARD_GRAVITY_M_S2
    max_thrust_g = thrust.thrust_to_weight.value * mass_g / 4.0
    full_thrust_n = max_thrust_g / 1000.0 * g
    torque_per_thrust_m = base.yaw_torque_per_thrust_mm / 1000.0
    # A yaw the log does not show (its effectiveness within noise of zero) keeps the base's.
    yaw_inertia = (
        torque_per_thrust_m * full_thrust_n / abs(rotation.yaw.effectiveness.value)
        if rotation.yaw_identified
        else base.inertia_kg_m2[2]
    )
    inertia = (
        full_thrust_n * arm_m(base) / rotation.roll.effectiveness.value,
        full_thrust_n * arm_m(base) / rotation.pitch.effectiveness.value,
        yaw_inertia,
    )
    top_speed = base.max_speed_rad_s
    tau_s = rotation.time_constant_s
    # The physics ties the curve's shape to the rotor inertia; the ratio was read with the
    # base's shape, so the rotor inertia keeps it.
    rotor_inertia = torque_per_thrust_m * full_thrust_n * tau_s / (thrust.beta * top_speed)
    rotor_source = (
        f"kept the thrust curve's shape of {base.name} (beta {thrust.beta:.3g}) with the fitted "
        "thrust and lag"
    )
    fitted = f"fitted from {label}"
    sources = {key: f"{base.name}'s: {text}" for key, text in base.sources.items()}
    sources.update(
        {
            "mass_g": "stated by the user (a log cannot give it)",
            "max_thrust_g": f"{fitted}: thrust-to-weight "
            f"{thrust.thrust_to_weight.value:.2f} +- {thrust.thrust_to_weight.std:.2f} x mass / 4",
            "motor_time_constant_ms": f"{fitted}: {tau_s * 1000:.1f} ms",
            "inertia_kg_m2": f"{fitted}: effectiveness roll "
            f"{rotation.roll.effectiveness.value:.0f}, pitch "
            f"{rotation.pitch.effectiveness.value:.0f}, yaw "
            + (
                f"{abs(rotation.yaw.effectiveness.value):.1f}"
                if rotation.yaw_identified
                else f"not shown by the log ({base.name}'s yaw inertia kept)"
            )
            + f" rad/s^2 per rotor's full thrust, with {base.name}'s arm and prop torque",
            "rotor_inertia_kg_m2": rotor_source,
        }
    )
    return dataclasses.replace(
        base,
        name=name,
        description=f"fitted from {label} over {base.name}; {mass_g:g} g",
        mass_g=mass_g,
        max_thrust_g=_significant(max_thrust_g),
        motor_time_constant_ms=_significant(tau_s * 1000.0),
        inertia_kg_m2=(
            _significant(inertia[0]),
            _significant(inertia[1]),
            _significant(inertia[2]),
        ),
        rotor_inertia_kg_m2=_significant(rotor_inertia),
        sources=sources,
    )


def _significant(value: float, digits: int = 4) -> float:
    """``value`` to ``digits`` significant digits: a fit's figures are not known closer."""
    return float(f"{value:.{digits - 1}e}")


def effectiveness_of(spec: VehicleSpec) -> tuple[float, float, float]:
    """Each axis' angular acceleration per unit of one rotor's thrust share in ``spec``'s
    physics (rad/s^2): what a fit of its flight should find (the inverse of the rules above)."""
    full_thrust_n = spec.max_thrust_g / 1000.0 * STANDARD_GRAVITY_M_S2
    ixx, iyy, izz = spec.inertia_kg_m2
    return (
        full_thrust_n * arm_m(spec) / ixx,
        full_thrust_n * arm_m(spec) / iyy,
        spec.yaw_torque_per_thrust_mm / 1000.0 * full_thrust_n / izz,
    )


def spec_beta(spec: VehicleSpec) -> float:
    """The thrust curve's shape the physics gives ``spec`` (the inverse of the rule above)."""
    return curve_beta(quad_params(spec))
