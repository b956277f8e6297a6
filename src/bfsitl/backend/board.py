"""A real flight controller as a backend: wall time, no truth, nothing to disturb, and the
accelerometer scale of its own sensor.

Betaflight reports MSP_RAW_IMU's accelerometer in the sensor's LSB (``acc.accADC``,
msp.c:1139-1146) and does not say what 1 g is.  A SITL's virtual IMU reads 256 per g; the
usual board IMUs at +-16 g (MPU6000, BMI270, ICM426xx) 2048; +-8 g parts 4096.  At rest the
reading's magnitude *is* 1 g, so the scale is measured when the board connects: the nearest
of the known scales, refused when the reading is far from all of them (the board is moving,
or its accelerometer is not calibrated).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from bfsitl.backend.base import SITL_IMU, Backend, ImuScale
from bfsitl.errors import BoardSetupError

#: acc_1G values Betaflight's accelerometer drivers set, LSB per g.
KNOWN_ACC_1G_LSB = (256, 512, 1024, 2048, 4096, 8192, 16384)
#: How far from a known scale a reading at rest may be (a tilted, vibrating or slightly
#: miscalibrated board is still well inside).
ACC_1G_TOLERANCE = 0.2


def imu_scale_at_rest(readings: Sequence[tuple[int, int, int]]) -> ImuScale:
    """The accelerometer scale from raw readings taken at rest (see the module docstring).

    256 LSB per g is the SITL's virtual IMU (a SITL reached through the serial bridge), whose
    truncation is added back as for a simulated session.
    """
    if not readings:
        raise BoardSetupError("no accelerometer reading to measure the IMU's scale from")
    magnitude = sum(math.sqrt(x * x + y * y + z * z) for x, y, z in readings) / len(readings)
    nearest = min(KNOWN_ACC_1G_LSB, key=lambda lsb: abs(math.log(max(magnitude, 1e-9) / lsb)))
    if abs(magnitude / nearest - 1.0) > ACC_1G_TOLERANCE:
        raise BoardSetupError(
            f"the FC's accelerometer reads {magnitude:.0f} LSB at rest, far from every scale "
            f"Betaflight uses ({', '.join(map(str, KNOWN_ACC_1G_LSB))} per g): keep the "
            f"board still and calibrate its accelerometer (the Configurator's Setup tab), "
            f"then connect again"
        )
    if nearest == SITL_IMU.acc_1g_lsb:
        return SITL_IMU
    return ImuScale(float(nearest))


class BoardBackend(Backend):
    """What is under a real FC, as far as bfsitl knows: its clock is the wall's, its state
    is unknown, and the one thing measured is its accelerometer's scale."""

    def __init__(self, imu: ImuScale) -> None:
        super().__init__()
        self.imu = imu

    @classmethod
    def measured(
        cls, read_acc_raw: Callable[[], tuple[int, int, int]], samples: int = 5
    ) -> BoardBackend:
        """A board backend whose IMU scale is measured from ``samples`` readings at rest."""
        return cls(imu_scale_at_rest([read_acc_raw() for _ in range(samples)]))
