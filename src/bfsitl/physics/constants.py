"""Physical constants, in one place: everything from the physics to the controllers and the FC
client uses these, so no two modules can disagree on them."""

from __future__ import annotations

#: Standard gravity (CGPM 1901), m/s^2: what Betaflight's 1 g and the simulator's gravity mean.
STANDARD_GRAVITY_M_S2 = 9.80665
#: The ISA sea-level pressure, Pa: zero altitude for the barometer and the firmware alike.
SEA_LEVEL_PRESSURE_PA = 101325.0
