"""Mode boxes ("flight modes" and AUX switch functions) of Betaflight 4.6.

Three numberings exist and mixing them up is the classic bug:

* the **permanent id** (``boxes[]`` in ``msp/msp_box.c:48-105``) is what MSP_BOXIDS,
  MSP_MODE_RANGES and MSP_SET_MODE_RANGE carry; it never changes between versions;
* the internal ``boxId_e`` (``fc/rc_modes.h:30-86``) orders the BOXNAMES/BOXIDS lists;
* the **position in the BOXIDS list** indexes the flight-mode bits of MSP_STATUS
  (``packFlightModeFlags``, ``msp_box.c:402-418``). The list only holds the boxes active at boot
  (features, sensors), so bit 4 is FAILSAFE on the stock SITL but something else elsewhere.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum


class BoxId(IntEnum):
    """Permanent box ids (msp/msp_box.c:48-105); names follow the firmware's ``BOX*`` enum."""

    ARM = 0
    ANGLE = 1
    HORIZON = 2
    ALTHOLD = 3
    ANTIGRAVITY = 4
    MAG = 5
    HEADFREE = 6
    HEADADJ = 7
    CAMSTAB = 8
    POSHOLD = 11
    PASSTHRU = 12
    BEEPERON = 13
    LEDLOW = 15
    CALIB = 17
    OSD = 19
    TELEMETRY = 20
    SERVO1 = 23
    SERVO2 = 24
    SERVO3 = 25
    BLACKBOX = 26
    FAILSAFE = 27
    AIRMODE = 28
    BOX3D = 29
    FPVANGLEMIX = 30
    BLACKBOXERASE = 31
    CAMERA1 = 32
    CAMERA2 = 33
    CAMERA3 = 34
    CRASHFLIP = 35
    PREARM = 36
    BEEPGPSCOUNT = 37
    VTXPITMODE = 39
    USER1 = 40
    USER2 = 41
    USER3 = 42
    USER4 = 43
    PIDAUDIO = 44
    PARALYZE = 45
    GPSRESCUE = 46
    ACROTRAINER = 47
    VTXCONTROLDISABLE = 48
    LAUNCHCONTROL = 49
    MSPOVERRIDE = 50
    STICKCOMMANDDISABLE = 51
    BEEPERMUTE = 52
    READY = 53
    LAPTIMERRESET = 54
    CHIRP = 55


#: Names as MSP_BOXNAMES sends them (msp_box.c:48-105). USER1..4 may be renamed on the FC
#: (``box_user_1_name``); only BOXNAMES shows the custom name.
BOX_NAMES: dict[int, str] = {
    BoxId.ARM: "ARM",
    BoxId.ANGLE: "ANGLE",
    BoxId.HORIZON: "HORIZON",
    BoxId.ALTHOLD: "ALTHOLD",
    BoxId.ANTIGRAVITY: "ANTI GRAVITY",
    BoxId.MAG: "MAG",
    BoxId.HEADFREE: "HEADFREE",
    BoxId.HEADADJ: "HEADADJ",
    BoxId.CAMSTAB: "CAMSTAB",
    BoxId.POSHOLD: "POS HOLD",
    BoxId.PASSTHRU: "PASSTHRU",
    BoxId.BEEPERON: "BEEPER",
    BoxId.LEDLOW: "LEDLOW",
    BoxId.CALIB: "CALIB",
    BoxId.OSD: "OSD DISABLE",
    BoxId.TELEMETRY: "TELEMETRY",
    BoxId.SERVO1: "SERVO1",
    BoxId.SERVO2: "SERVO2",
    BoxId.SERVO3: "SERVO3",
    BoxId.BLACKBOX: "BLACKBOX",
    BoxId.FAILSAFE: "FAILSAFE",
    BoxId.AIRMODE: "AIR MODE",
    BoxId.BOX3D: "3D DISABLE",
    BoxId.FPVANGLEMIX: "FPV ANGLE MIX",
    BoxId.BLACKBOXERASE: "BLACKBOX ERASE",
    BoxId.CAMERA1: "CAMERA CONTROL 1",
    BoxId.CAMERA2: "CAMERA CONTROL 2",
    BoxId.CAMERA3: "CAMERA CONTROL 3",
    BoxId.CRASHFLIP: "FLIP OVER AFTER CRASH",
    BoxId.PREARM: "PREARM",
    BoxId.BEEPGPSCOUNT: "GPS BEEP SATELLITE COUNT",
    BoxId.VTXPITMODE: "VTX PIT MODE",
    BoxId.USER1: "USER1",
    BoxId.USER2: "USER2",
    BoxId.USER3: "USER3",
    BoxId.USER4: "USER4",
    BoxId.PIDAUDIO: "PID AUDIO",
    BoxId.PARALYZE: "PARALYZE",
    BoxId.GPSRESCUE: "GPS RESCUE",
    BoxId.ACROTRAINER: "ACRO TRAINER",
    BoxId.VTXCONTROLDISABLE: "VTX CONTROL DISABLE",
    BoxId.LAUNCHCONTROL: "LAUNCH CONTROL",
    BoxId.MSPOVERRIDE: "MSP OVERRIDE",
    BoxId.STICKCOMMANDDISABLE: "STICK COMMANDS DISABLE",
    BoxId.BEEPERMUTE: "BEEPER MUTE",
    BoxId.READY: "READY",
    BoxId.LAPTIMERRESET: "LAP TIMER RESET",
    BoxId.CHIRP: "CHIRP",
}
#: Boxes 4.6 does not have (the enum above is 4.6's, checked against its source): master's
#: AUTOPILOT's permanent id (master's msp/msp_box.c): a flight-plan mission, which is also
#: how master flies GPS Rescue.
AUTOPILOT_BOX_ID = 56
LATER_BOX_NAMES: dict[int, str] = {AUTOPILOT_BOX_ID: "AUTOPILOT"}

#: Permanent ids in internal ``boxId_e`` order (fc/rc_modes.h:30-86): the order of the BOXNAMES
#: and BOXIDS lists (and so of the STATUS mode bits) once inactive boxes are left out.
INTERNAL_ORDER: tuple[BoxId, ...] = (
    BoxId.ARM, BoxId.ANGLE, BoxId.HORIZON, BoxId.MAG, BoxId.ALTHOLD, BoxId.HEADFREE, BoxId.CHIRP,
    BoxId.PASSTHRU, BoxId.FAILSAFE, BoxId.POSHOLD, BoxId.GPSRESCUE, BoxId.ANTIGRAVITY,
    BoxId.HEADADJ, BoxId.CAMSTAB, BoxId.BEEPERON, BoxId.LEDLOW, BoxId.CALIB, BoxId.OSD,
    BoxId.TELEMETRY, BoxId.SERVO1, BoxId.SERVO2, BoxId.SERVO3, BoxId.BLACKBOX, BoxId.AIRMODE,
    BoxId.BOX3D, BoxId.FPVANGLEMIX, BoxId.BLACKBOXERASE, BoxId.CAMERA1, BoxId.CAMERA2,
    BoxId.CAMERA3, BoxId.CRASHFLIP, BoxId.PREARM, BoxId.BEEPGPSCOUNT, BoxId.VTXPITMODE,
    BoxId.PARALYZE, BoxId.USER1, BoxId.USER2, BoxId.USER3, BoxId.USER4, BoxId.PIDAUDIO,
    BoxId.ACROTRAINER, BoxId.VTXCONTROLDISABLE, BoxId.LAUNCHCONTROL, BoxId.MSPOVERRIDE,
    BoxId.STICKCOMMANDDISABLE, BoxId.BEEPERMUTE, BoxId.READY, BoxId.LAPTIMERRESET,
)  # fmt: skip

#: MSP_BOXIDS of the stock 4.6.0 SITL (measured: docs/firmware-facts.md#box-ids). Handy for fakes.
SITL_DEFAULT_BOX_IDS: tuple[int, ...] = (
    0, 1, 2, 6, 27, 7, 13, 19, 26, 30, 32, 33, 34, 36, 45, 49, 51, 52, 53,
)  # fmt: skip


def box_name(permanent_id: int) -> str:
    """Display name of a permanent box id; ids unknown to 4.6 become ``UNKNOWN_<id>``."""
    return BOX_NAMES.get(permanent_id) or LATER_BOX_NAMES.get(
        permanent_id, f"UNKNOWN_{permanent_id}"
    )


def decode_flight_modes(flight_mode_flags: int, box_ids: Sequence[int]) -> tuple[str, ...]:
    """Names of the active modes in a STATUS flight-mode mask.

    Bit ``i`` belongs to ``box_ids[i]`` (the MSP_BOXIDS list read from the same boot), not to
    permanent id ``i``. A set bit past the end of the list means the list is stale (read before
    a reboot that changed features); it is reported as ``UNKNOWN_BIT_<i>`` rather than dropped.
    """
    if flight_mode_flags < 0:
        raise ValueError(f"flight-mode mask must be non-negative, got {flight_mode_flags}")
    names: list[str] = []
    for bit in range(flight_mode_flags.bit_length()):
        if not flight_mode_flags >> bit & 1:
            continue
        names.append(box_name(box_ids[bit]) if bit < len(box_ids) else f"UNKNOWN_BIT_{bit}")
    return tuple(names)
