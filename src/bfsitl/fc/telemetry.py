"""One consistent snapshot of the FC's flight state (:class:`Telemetry`), taken in one
MSP_MULTIPLE_MSP round trip, and what it means: armed, the blockers, the flight modes, the
vertical acceleration."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from bfsitl.errors import MspDecodeError
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.protocol import messages as msg
from bfsitl.protocol.arming import decode_arming_flags
from bfsitl.protocol.boxes import decode_flight_modes
from bfsitl.protocol.msp_codes import MspCommand

#: What :meth:`MspClient.telemetry` asks for in one MSP_MULTIPLE_MSP round trip.
TELEMETRY_COMMANDS: tuple[int, ...] = (
    MspCommand.ATTITUDE,
    MspCommand.ALTITUDE,
    MspCommand.STATUS_EX,
    MspCommand.ANALOG,
    MspCommand.RC,
    MspCommand.MOTOR,
    MspCommand.RAW_IMU,
)


@dataclass(frozen=True, slots=True)
class Telemetry:
    """One consistent snapshot of the FC's flight state, taken in one round trip."""

    received_at_s: float
    attitude: msg.Attitude
    altitude: msg.Altitude
    status: msg.StatusEx
    analog: msg.Analog
    rc: msg.Rc
    motors: msg.Motor
    imu: msg.RawImu
    box_ids: tuple[int, ...] = field(default=())

    @property
    def armed(self) -> bool:
        return self.status.armed

    @property
    def arming_blockers(self) -> tuple[str, ...]:
        """CLI names of the flags that currently block arming (empty when it may arm)."""
        return blocker_names(self.status)

    @property
    def flight_modes(self) -> tuple[str, ...]:
        return mode_names(self.status, self.box_ids)

    def accel_up_m_s2(
        self, acc_1g_lsb: float = msg.SITL_ACC_1G_LSB, offset_lsb: float = 0.0
    ) -> float:
        """Vertical acceleration in m/s^2, up positive, gravity removed (0 at rest or hovering).

        ``acc_1g_lsb``: the SITL reports 256 LSB per g; real IMUs usually 2048 (the board's
        ``acc_1G``).  ``offset_lsb`` is added to the z reading first: a known bias of the
        source (``msg.SITL_ACC_TRUNCATION_LSB`` for the SITL).
        """
        return vertical_accel_m_s2(self.attitude, self.imu, acc_1g_lsb, offset_lsb)


def vertical_accel_m_s2(
    attitude: msg.Attitude, imu: msg.RawImu, acc_1g_lsb: float, offset_lsb: float
) -> float:
    """:meth:`Telemetry.accel_up_m_s2` from the two replies it needs."""
    # The whole specific force projected on the vertical.  Betaflight's accelerometer is
    # in FLU body axes (x forward, y left, z up; +1 g on z at rest), its pitch is positive
    # nose down and its roll positive right wing down: x points up by -sin(pitch), y by
    # sin(roll) cos(pitch), z by cos(roll) cos(pitch) (signs checked against the simulated
    # truth).  Body z alone does in still air, but a multirotor pushed by rotor drag
    # (holding position in wind) has x/y specific force that its tilt turns partly
    # vertical; ignoring it biased the altitude estimate enough to lose metres of height
    # (README, "Position").
    roll_rad = math.radians(attitude.roll_deg)
    pitch_rad = math.radians(attitude.pitch_deg)
    scale = STANDARD_GRAVITY_M_S2 / acc_1g_lsb
    ax = imu.acc_raw[0] * scale
    ay = imu.acc_raw[1] * scale
    az = (imu.acc_raw[2] + offset_lsb) * scale
    cos_pitch = math.cos(pitch_rad)
    specific_force_up_m_s2 = (
        -math.sin(pitch_rad) * ax
        + math.sin(roll_rad) * cos_pitch * ay
        + math.cos(roll_rad) * cos_pitch * az
    )
    return specific_force_up_m_s2 - STANDARD_GRAVITY_M_S2


def blocker_names(status: msg.StatusEx) -> tuple[str, ...]:
    """CLI names of the flags in ``status`` that block arming (empty when it may arm)."""
    return _blocker_names(status.arming_disable_flags, status.arming_disable_flag_count)


def mode_names(status: msg.StatusEx, box_ids: tuple[int, ...]) -> tuple[str, ...]:
    """Names of the flight modes active in ``status`` (``box_ids``: the FC's MSP_BOXIDS)."""
    return _mode_names(status.flight_mode_flags, box_ids)


# A flight's masks take a handful of values, and every control step names them: the names
# are kept per mask (both are pure functions of it).
@functools.lru_cache(maxsize=256)
def _blocker_names(mask: int, flag_count: int) -> tuple[str, ...]:
    return tuple(info.cli_name for info in decode_arming_flags(mask, flag_count))


@functools.lru_cache(maxsize=256)
def _mode_names(flags: int, box_ids: tuple[int, ...]) -> tuple[str, ...]:
    return decode_flight_modes(flags, box_ids)


def telemetry_from_payloads(
    payloads: Sequence[bytes], received_at_s: float, box_ids: tuple[int, ...]
) -> Telemetry:
    if len(payloads) != len(TELEMETRY_COMMANDS):
        raise MspDecodeError(
            f"telemetry: expected {len(TELEMETRY_COMMANDS)} sub-replies, got {len(payloads)}"
        )
    attitude, altitude, status, analog, rc, motors, imu = payloads
    return Telemetry(
        received_at_s=received_at_s,
        attitude=msg.Attitude.decode(attitude),
        altitude=msg.Altitude.decode(altitude),
        status=msg.StatusEx.decode(status),
        analog=msg.Analog.decode(analog),
        rc=msg.Rc.decode(rc),
        motors=msg.Motor.decode(motors),
        imu=msg.RawImu.decode(imu),
        box_ids=box_ids,
    )
