"""Arming-disable flags of Betaflight 4.6: what each bit means and what to do about it.

MSP_STATUS / MSP_STATUS_EX report a U32 mask of the reasons the FC refuses to arm. The bit order
is ``armingDisableFlags_e`` in ``fc/runtime_config.h:42-72`` (29 flags in 4.6,
``ARMING_DISABLE_FLAGS_COUNT``; master has 30, with AUTOPILOT at 28 and ARM_SWITCH moved to 29:
MSP_STATUS sends the count, which picks the table); the names the CLI ``status`` command prints are
``armingDisableFlagNames`` in ``fc/runtime_config.c:38-68``. Older peer libraries ship stale tables
(a 4.2-era bit 20 "RPMFILTER", ARM_SWITCH at bit 21 or 25), so this table follows the 4.6 source,
and a bit it does not know becomes ``UNKNOWN_<bit>`` instead of an exception: newer firmware adds
flags, and a status display must never crash on them.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from enum import IntEnum

#: Number of arming-disable flags in 4.6 (``ARMING_DISABLE_FLAGS_COUNT``, runtime_config.h:74).
ARMING_DISABLE_FLAGS_COUNT = 29


class ArmingFlag(IntEnum):
    """Bit index of each ``ARMING_DISABLED_*`` flag (fc/runtime_config.h:42-72)."""

    NO_GYRO = 0
    FAILSAFE = 1
    RX_FAILSAFE = 2
    NOT_DISARMED = 3
    BOXFAILSAFE = 4
    RUNAWAY_TAKEOFF = 5
    CRASH_DETECTED = 6
    THROTTLE = 7
    ANGLE = 8
    BOOT_GRACE_TIME = 9
    NOPREARM = 10
    LOAD = 11
    CALIBRATING = 12
    CLI = 13
    CMS_MENU = 14
    BST = 15
    MSP = 16
    PARALYZE = 17
    GPS = 18
    RESC = 19
    DSHOT_TELEM = 20
    REBOOT_REQUIRED = 21
    DSHOT_BITBANG = 22
    ACC_CALIBRATION = 23
    MOTOR_PROTOCOL = 24
    CRASHFLIP = 25
    ALTHOLD = 26
    POSHOLD = 27
    ARM_SWITCH = 28

    @property
    def mask(self) -> int:
        return 1 << self.value


@dataclass(frozen=True)
class ArmingFlagInfo:
    """One arming-disable reason, in words a pilot at the terminal can act on."""

    bit: int
    name: str  # ArmingFlag member name (firmware enum without the ARMING_DISABLED_ prefix)
    cli_name: str  # as CLI `status` prints it ("Arming disable flags: RXLOSS ANGLE")
    meaning: str
    fix: str  # one line: what to do
    source: str = ""  # where the firmware sets it, e.g. "fc/core.c:341-345"

    @property
    def mask(self) -> int:
        return 1 << self.bit


_SOURCE = re.compile(r"\s*\(([\w./]+\.[ch]:[\d\-, ]+(?:,[^)]*)?)\)$")


def _split_source(cli_name: str, meaning: str, fix: str) -> tuple[str, str, str, str]:
    """The table cites the firmware at the end of each meaning; keep that apart from the
    words shown to the user."""
    match = _SOURCE.search(meaning)
    if match is None:
        return cli_name, meaning, fix, ""
    source = match.group(1)
    if "/" not in source.split(":")[0]:
        source = "fc/" + source
    return cli_name, meaning[: match.start()], fix, source


# (cli_name, meaning, fix) per bit; the "set where" references are fc/core.c unless noted.
_TABLE: dict[ArmingFlag, tuple[str, str, str]] = {
    ArmingFlag.NO_GYRO: (
        "NOGYRO",
        "no gyro was detected at boot (fc/init.c:674)",
        "check the gyro hardware and gyro_hardware setting, then reboot",
    ),
    ArmingFlag.FAILSAFE: (
        "FAILSAFE",
        "failsafe stage 2 is (or was just) active (flight/failsafe.c:389-420)",
        "restore a steady RC stream, wait for failsafe recovery, then turn ARM off and on",
    ),
    ArmingFlag.RX_FAILSAFE: (
        "RXLOSS",
        "no valid RC frame for 150 ms, or not yet failsafe_recovery_delay of good frames "
        "(flight/failsafe.c:168-219)",
        "send RC (UDP rc_packet on 9004 or MSP_SET_RAW_RC) continuously; in SITL start RC only "
        "after the FC answers MSP",
    ),
    ArmingFlag.NOT_DISARMED: (
        "NOT_DISARMED",
        "the RC link came back while the ARM switch was on (core.c:299-312)",
        "turn the ARM switch (AUX) off, then on again",
    ),
    ArmingFlag.BOXFAILSAFE: (
        "BOXFAILSAFE",
        "the FAILSAFE mode switch is on (core.c:317-321)",
        "turn the FAILSAFE switch (AUX) off",
    ),
    ArmingFlag.RUNAWAY_TAKEOFF: (
        "RUNAWAY",
        "runaway-takeoff prevention disarmed the craft (core.c:1190-1211)",
        "turn the ARM switch off to clear it; check motor order, direction and props",
    ),
    ArmingFlag.CRASH_DETECTED: (
        "CRASH",
        "crash recovery disarmed the craft (flight/pid.c:691)",
        "turn the ARM switch off to clear it",
    ),
    ArmingFlag.THROTTLE: (
        "THROTTLE",
        "throttle is not low (at or above min_check) (core.c:335-339)",
        "lower throttle below min_check (1050 us)",
    ),
    ArmingFlag.ANGLE: (
        "ANGLE",
        "craft tilted beyond small_angle, or attitude not established yet (core.c:341-345)",
        "feed fdm packets so the attitude is established, keep the craft level (< small_angle)",
    ),
    ArmingFlag.BOOT_GRACE_TIME: (
        "BOOTGRACE",
        "the power-on arming grace time has not elapsed (core.c:286-297)",
        "wait 5 s of FC time after boot (pwr_on_arm_grace)",
    ),
    ArmingFlag.NOPREARM: (
        "NOPREARM",
        "a PREARM mode range is configured but PREARM is not active (core.c:375-381)",
        "turn the PREARM switch on before ARM (or remove the PREARM mode range)",
    ),
    ArmingFlag.LOAD: (
        "LOAD",
        "too many late scheduler tasks (only with USE_LATE_TASK_STATISTICS) (core.c:361-366)",
        "reduce CPU load (lower pid_process_denom rate, disable features)",
    ),
    ArmingFlag.CALIBRATING: (
        "CALIB",
        "gyro, acc, baro or mag calibration is running (core.c:369-373)",
        "keep the craft still and wait (gyro ~1.25 s, baro ~2.5 s after boot; steady fdm gyro)",
    ),
    ArmingFlag.CLI: (
        "CLI",
        "an interactive CLI session was entered (cli/cli.c:6912)",
        "an interactive CLI session blocks arming until the next reboot: save/reboot or use MSP "
        "instead",
    ),
    ArmingFlag.CMS_MENU: (
        "CMS",
        "the OSD/CMS menu is open (cms/cms.c:907)",
        "leave the CMS menu",
    ),
    ArmingFlag.BST: (
        "BST",
        "legacy TBS BST interface flag (unused in 4.6)",
        "nothing sets it in 4.6; reboot the FC",
    ),
    ArmingFlag.MSP: (
        "MSP",
        "MSP_SET_ARMING_DISABLED(1) was sent (no effect in SITL builds)",
        "send MSP_SET_ARMING_DISABLED (99) with 0",
    ),
    ArmingFlag.PARALYZE: (
        "PARALYZE",
        "the PARALYZE mode was switched on; latched until reboot (core.c:416-418)",
        "reboot the FC (PARALYZE never clears by itself)",
    ),
    ArmingFlag.GPS: (
        "GPS",
        "GPS rescue is configured but there is no fix or too few satellites (core.c:383-390)",
        "wait for a 3D fix with gps_rescue_min_sats, or allow arming without a fix",
    ),
    ArmingFlag.RESC: (
        "RESCUE_SW",
        "the GPS RESCUE switch is on (core.c:391-395)",
        "turn the GPS RESCUE switch (AUX) off",
    ),
    ArmingFlag.DSHOT_TELEM: (
        "DSHOT_TELEM",
        "bidirectional DShot is on but a motor sends no telemetry (core.c:400-405)",
        "check ESC support for bidirectional DShot, or set dshot_bidir = OFF",
    ),
    ArmingFlag.REBOOT_REQUIRED: (
        "REBOOT_REQD",
        "a changed setting only takes effect after a reboot (config/config.c:805)",
        "save (MSP_EEPROM_WRITE) and reboot the FC",
    ),
    ArmingFlag.DSHOT_BITBANG: (
        "DSHOT_BBANG",
        "DShot bitbang output failed (core.c:408-413)",
        "set dshot_bitbang = OFF or fix the motor pin/timer assignment",
    ),
    ArmingFlag.ACC_CALIBRATION: (
        "NO_ACC_CAL",
        "accelerometer not calibrated while an ACC-based mode or feature needs it (core.c:420-425)",
        "level the craft, send MSP_ACC_CALIBRATION (205), then save",
    ),
    ArmingFlag.MOTOR_PROTOCOL: (
        "MOTOR_PROTO",
        "no motor protocol is enabled (core.c:428-430)",
        "set motor_pwm_protocol to a real protocol, save and reboot",
    ),
    ArmingFlag.CRASHFLIP: (
        "FLIP_SWITCH",
        "the crash-flip switch was released without a successful flip (core.c:347-359)",
        "turn the ARM switch off and on again (disarm/rearm after crash flip)",
    ),
    ArmingFlag.ALTHOLD: (
        "ALT_HOLD_SW",
        "the ALTHOLD switch is on while disarmed (core.c:323-327)",
        "turn the ALTHOLD switch (AUX) off before arming",
    ),
    ArmingFlag.POSHOLD: (
        "POS_HOLD_SW",
        "the POSHOLD switch is on while disarmed (core.c:329-333)",
        "turn the POSHOLD switch (AUX) off before arming",
    ),
    ArmingFlag.ARM_SWITCH: (
        "ARM_SWITCH",
        "the ARM switch was on while another flag blocked arming (core.c:427-458)",
        "turn the ARM switch (AUX) off, then on again once nothing else blocks",
    ),
}

#: All 29 flags of 4.6 in bit order.
ARMING_FLAGS: tuple[ArmingFlagInfo, ...] = tuple(
    ArmingFlagInfo(flag.value, flag.name, *_split_source(*_TABLE[flag])) for flag in ArmingFlag
)

#: Master (MSP API 1.49) adds AUTOPILOT at bit 28 and moves ARM_SWITCH to 29, the last bit
#: ("needs to be the last element", master fc/runtime_config.h).
AUTOPILOT_FLAG = ArmingFlagInfo(
    28,
    "AUTOPILOT",
    "AUTOPILOT",
    "the AUTOPILOT (flight plan) switch is on while disarmed",
    "turn the AUTOPILOT switch (AUX) off before arming",
    "fc/core.c (master)",
)

#: Flags per ``ARMING_DISABLE_FLAGS_COUNT``, which MSP_STATUS sends with the mask: 29 in 4.6,
#: 30 in master. The count is the firmware's own word on which table applies.
ARMING_FLAGS_BY_COUNT: dict[int, tuple[ArmingFlagInfo, ...]] = {
    ARMING_DISABLE_FLAGS_COUNT: ARMING_FLAGS,
    30: (*ARMING_FLAGS[:28], AUTOPILOT_FLAG, replace(ARMING_FLAGS[28], bit=29)),
}

_BY_BIT: dict[int, ArmingFlagInfo] = {info.bit: info for info in ARMING_FLAGS}
_BY_COUNT_AND_BIT: dict[int, dict[int, ArmingFlagInfo]] = {
    count: {info.bit: info for info in table} for count, table in ARMING_FLAGS_BY_COUNT.items()
}


def arming_flag_info(bit: int, flag_count: int = ARMING_DISABLE_FLAGS_COUNT) -> ArmingFlagInfo:
    """The description of one bit for a firmware with ``flag_count`` flags.

    A count no table knows (newer firmware) keeps the common bits 0..27, names its last bit
    ARM_SWITCH (the firmware keeps that one last) and calls the rest ``UNKNOWN_<bit>``.
    """
    table = _BY_COUNT_AND_BIT.get(flag_count)
    if table is None:
        if flag_count > 0 and bit == flag_count - 1:
            return replace(ARMING_FLAGS[ArmingFlag.ARM_SWITCH], bit=bit)
        table = _BY_BIT if bit < ArmingFlag.ARM_SWITCH else {}
    known = table.get(bit)
    if known is not None:
        return known
    return ArmingFlagInfo(
        bit,
        f"UNKNOWN_{bit}",
        f"UNKNOWN_{bit}",
        "a flag this table does not know (newer firmware?)",
        "run the CLI `status` command to see the firmware's own name for it",
    )


def decode_arming_flags(
    mask: int, flag_count: int = ARMING_DISABLE_FLAGS_COUNT
) -> tuple[ArmingFlagInfo, ...]:
    """Every set bit of an arming-disable mask, in bit order (most critical first)."""
    if mask < 0:
        raise ValueError(f"arming-disable mask must be non-negative, got {mask}")
    return tuple(
        arming_flag_info(bit, flag_count) for bit in range(mask.bit_length()) if mask >> bit & 1
    )


def arming_flags_text(mask: int, flag_count: int = ARMING_DISABLE_FLAGS_COUNT) -> str:
    """The mask as CLI ``status`` would print it, e.g. ``"RXLOSS ANGLE BOOTGRACE"``."""
    return " ".join(info.cli_name for info in decode_arming_flags(mask, flag_count))


def all_arming_flags() -> tuple[ArmingFlagInfo, ...]:
    """Every flag any supported firmware has (for looking a name up)."""
    return (*ARMING_FLAGS, AUTOPILOT_FLAG)
