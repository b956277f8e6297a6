"""ISA pressure for the virtual barometer, and the altitude Betaflight computes back from it.

The 4.6.0 SITL's only altitude source is the fdm ``pressure`` field
(``docs/firmware-facts.md#barometer``): it truncates it to whole pascals (~8.3 cm) and converts
with ``pressureToAltitude``.  We send the International Standard Atmosphere troposphere pressure
at the IMU's altitude above mean sea level, which matches the gz-sensors air-pressure model
Gazebo uses to 0.02 Pa at 100 m (``docs/firmware-facts.md#atmosphere``).
"""

from __future__ import annotations

import math

from bfsitl.errors import SimInputError
from bfsitl.physics.constants import SEA_LEVEL_PRESSURE_PA

#: ISA sea-level pressure (Pa).
#: Troposphere lapse rate over sea-level temperature: 0.0065 K/m / 288.15 K.
_LAPSE_OVER_T0_PER_M = 2.25577e-5
#: g M / (R L) for the troposphere.
_PRESSURE_EXPONENT = 5.25588
#: Betaflight's inverse (``sensors/barometer.c pressureToAltitude``).
_BETAFLIGHT_EXPONENT = 0.190295
_BETAFLIGHT_SCALE_M = 44330.0

#: The troposphere formula is only meaningful up to 11 km; we allow some margin either side.
MIN_ALTITUDE_M = -1000.0
MAX_ALTITUDE_M = 20000.0


def isa_pressure_pa(altitude_msl_m: float) -> float:
    """Static pressure (Pa) at an altitude above mean sea level: 101325 (1 - 2.25577e-5 h)^5.25588.

    Raises :class:`SimInputError` outside -1 km .. 20 km (a vehicle that got there has left
    any flight the SITL can make sense of; the firmware would get a nonsense baro).
    """
    if not MIN_ALTITUDE_M <= altitude_msl_m <= MAX_ALTITUDE_M:
        raise SimInputError(
            f"ISA pressure: altitude {altitude_msl_m:.1f} m MSL is outside "
            f"{MIN_ALTITUDE_M:.0f}..{MAX_ALTITUDE_M:.0f} m (the vehicle left the atmosphere "
            f"model: check home altitude and the flight)"
        )
    base = 1.0 - _LAPSE_OVER_T0_PER_M * altitude_msl_m
    return SEA_LEVEL_PRESSURE_PA * base**_PRESSURE_EXPONENT


def betaflight_altitude_m(pressure_pa: float) -> float:
    """Altitude Betaflight derives from a pressure (before subtracting its ground reference).

    The firmware first truncates the fdm double to an int32, as :func:`firmware_pressure_pa`.
    """
    if pressure_pa <= 0 or not math.isfinite(pressure_pa):
        raise SimInputError(f"pressure must be > 0 Pa, got {pressure_pa}")
    ratio = pressure_pa / SEA_LEVEL_PRESSURE_PA
    return (1.0 - ratio**_BETAFLIGHT_EXPONENT) * _BETAFLIGHT_SCALE_M


def firmware_pressure_pa(pressure_pa: float) -> int:
    """The whole pascals the SITL keeps of the fdm pressure (``virtualBaroSet((int32_t)P)``)."""
    return int(pressure_pa)
