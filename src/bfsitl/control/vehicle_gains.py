"""Gains for another vehicle: the controllers' defaults were tuned on IRIS; for another quad
they are carried over so that, in thrust, the controller does what it did on IRIS.

With ``s = (hover_us - 1000) / (1545 - 1000)`` (the quad's hover stick against IRIS's,
:mod:`bfsitl.vehicles.throttle`) a stick level ``L`` becomes ``1000 + (L - 1000) s`` and a gain
in microseconds per unit becomes ``gain x s``: both move the thrust by the same share of the
hover thrust as on IRIS.  The climb feedforward also carries the blades' inflow: thrust lost
per m/s of climb is ``g / (w R theta)`` of acceleration at the hover (rotor speed ``w``, blade
element radius ``R``, pitch ``theta``), 0.875 m/s^2 per m/s on IRIS.  On IRIS itself every
factor is exactly 1, so its defaults are unchanged to the bit.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.vehicles.throttle import (
    IRIS_HOVER_THROTTLE_US,
    THROTTLE_LOW_US,
    hover_throttle_us,
)

#: The top of the throttle stick: a level carried over stays on the stick.
THROTTLE_HIGH_US = 2000.0
#: Stick levels (microseconds of stick).
_LEVELS = frozenset(
    {
        "hover_guess_us",
        "hover_min_us",
        "hover_max_us",
        "hover_base_us",
        "hover_us",
        "throttle_min_us",
        "throttle_max_us",
    }
)
#: Gains and amounts in microseconds of stick (per m, per m/s, per s...).
_AMOUNTS = frozenset(
    {
        "spool_rate_us_s",
        "alt_ki",
        "rate_kp",
        "rate_ki",
        "accel_ff_us",
        "ground_windup_us",
        "kp",
        "ki",
        "kd",
        "integral_limit",
        "climb_us",
    }
)
#: Gains that also carry the rotor inflow's damping.
_INFLOW = frozenset({"climb_ff_us"})


def _inflow_damping_m_s2_per_m_s(quad: QuadParams) -> float:
    """Upward acceleration lost per m/s of climb at the hover, from the blades' inflow."""
    blade_speed_m_s = quad.hover_rotor_speed_rad_s * quad.blade_radius_m
    return STANDARD_GRAVITY_M_S2 / (blade_speed_m_s * quad.blade_pitch_rad)


def vehicle_gains(gains_type: type, quad: QuadParams) -> dict[str, float]:
    """The defaults of ``gains_type`` carried over to ``quad`` (empty for IRIS).

    Args:
        gains_type: A controller's gains dataclass (``FusedGains``, ``LandingGains``...).
        quad: The vehicle flown.

    Returns:
        Gain name to value, for the gains that change; pass them as overrides.
    """
    if quad == IRIS:
        return {}
    scale = (hover_throttle_us(quad) - THROTTLE_LOW_US) / (IRIS_HOVER_THROTTLE_US - THROTTLE_LOW_US)
    inflow = _inflow_damping_m_s2_per_m_s(quad) / _inflow_damping_m_s2_per_m_s(IRIS)
    defaults: Any = gains_type()
    out: dict[str, float] = {}
    for field in dataclasses.fields(defaults):
        value = getattr(defaults, field.name)
        if field.name in _LEVELS:
            level_us = THROTTLE_LOW_US + (value - THROTTLE_LOW_US) * scale
            out[field.name] = min(level_us, THROTTLE_HIGH_US)
        elif field.name in _AMOUNTS:
            out[field.name] = value * scale
        elif field.name in _INFLOW:
            out[field.name] = value * scale * inflow
    return out
