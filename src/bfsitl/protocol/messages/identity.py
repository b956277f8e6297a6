"""Who the flight controller is: API and firmware versions, board, build, MCU, name, UID."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from bfsitl.protocol.messages.constants import (
    BUILD_OPTION_NAMES,
    CONFIGURATION_PROBLEM_NAMES,
    mask_names,
)
from bfsitl.protocol.messages.layout import WireRecord, msp_message
from bfsitl.protocol.messages.wire_types import (
    TAIL,
    U8,
    U16,
    U32,
    Array,
    PStr,
    Raw,
    RestArray,
    RestText,
    Text,
    u16,
    u32,
)
from bfsitl.protocol.msp_codes import MspCommand


@msp_message(MspCommand.API_VERSION)
@dataclass(frozen=True, slots=True)
class ApiVersion(WireRecord):
    """MSP_API_VERSION (1): msp.c:632-636. 4.6.0 answers 0, 1, 47."""

    protocol_version: U8
    api_major: U8
    api_minor: U8

    @property
    def api(self) -> tuple[int, int]:
        """(major, minor), comparable: ``msg.api >= (1, 46)``."""
        return (self.api_major, self.api_minor)


@msp_message(MspCommand.FC_VARIANT)
@dataclass(frozen=True, slots=True)
class FcVariant(WireRecord):
    """MSP_FC_VARIANT (2): 4 characters, ``BTFL`` for Betaflight (msp.c:638-640)."""

    identifier: Annotated[str, Text(4)]


@msp_message(MspCommand.FC_VERSION)
@dataclass(frozen=True, slots=True)
class FcVersion(WireRecord):
    """MSP_FC_VERSION (3): U8 major, minor, patch (4.6 msp.c:642-646).

    Master (calendar versions) sends U8 year - 2000, U8 month, U8 patch and then the whole
    version as a PStr, e.g. ``2026.12.0-alpha`` (master msp.c:688-695); :attr:`text` is that
    string when present.
    """

    major: U8
    minor: U8
    patch: U8
    version_string: Annotated[str | None, PStr(), TAIL] = None

    @property
    def text(self) -> str:
        if self.version_string:
            return self.version_string
        return f"{self.major}.{self.minor}.{self.patch}"


@msp_message(MspCommand.BOARD_INFO)
@dataclass(frozen=True, slots=True)
class BoardInfo(WireRecord):
    """MSP_BOARD_INFO (4): msp.c:654-753.

    4 chars board id, U16 hardware revision, U8 FC type (2 = with MAX7456), U8 capability bits,
    PStr target name; then, appended over API versions: PStr board name, PStr manufacturer id,
    32-byte signature, U8 MCU type, U8 configuration state (1.42), U16 gyro sample rate (1.43),
    U32 configuration problems, U8 SPI and U8 I2C device counts (1.44). The SITL sends 57 bytes.
    """

    board_id: Annotated[str, Text(4)]
    hardware_revision: U16
    fc_type: U8
    target_capabilities: U8
    target_name: Annotated[str, PStr()]
    board_name: Annotated[str | None, PStr(), TAIL] = None
    manufacturer_id: Annotated[str | None, PStr()] = None
    signature: Annotated[bytes | None, Raw(32)] = None
    mcu_type_id: U8 | None = None
    configuration_state: U8 | None = None
    gyro_sample_rate_hz: U16 | None = None
    configuration_problems: U32 | None = None
    spi_device_count: U8 | None = None
    i2c_device_count: U8 | None = None

    @property
    def problems(self) -> tuple[str, ...]:
        """Names of the configuration problems the FC reports (ACC calibration, motor protocol)."""
        return mask_names(self.configuration_problems or 0, CONFIGURATION_PROBLEM_NAMES)


@msp_message(MspCommand.BUILD_INFO)
@dataclass(frozen=True, slots=True)
class BuildInfo(WireRecord):
    """MSP_BUILD_INFO (5): msp.c:755-761, msp/msp_build_info.c:38-188.

    11 chars date, 8 chars time, 7 chars short git revision, then U16 build-option ids to the
    end of the payload (1.46; no count byte). A build without git metadata sends whatever follows
    the revision string in memory; the text stops at the first NUL.
    """

    date: Annotated[str, Text(11)]
    time: Annotated[str, Text(8)]
    git_revision: Annotated[str, Text(7)]
    build_options: Annotated[tuple[int, ...], RestArray(u16, "options")] = ()

    @property
    def option_names(self) -> tuple[str, ...]:
        return tuple(BUILD_OPTION_NAMES.get(o, f"OPTION_{o}") for o in self.build_options)


@msp_message(MspCommand.MSP2_MCU_INFO)
@dataclass(frozen=True, slots=True)
class McuInfo(WireRecord):
    """MSP2_MCU_INFO (0x300C): U8 MCU type id, PStr MCU name (msp.c:648-652); SITL: 0, SIMULATOR."""

    mcu_type_id: U8
    name: Annotated[str, PStr()]


@msp_message(MspCommand.NAME)
@dataclass(frozen=True, slots=True)
class CraftName(WireRecord):
    """MSP_NAME (10): the craft name, raw characters, no terminator, may be empty (msp.c:1160-1162).

    The whole payload is the name, so there is no trailing-byte tolerance here.
    """

    name: Annotated[str, RestText()]


@msp_message(MspCommand.UID)
@dataclass(frozen=True, slots=True)
class Uid(WireRecord):
    """MSP_UID (160): the MCU unique id as 3 x U32 (msp.c:777-781); SITL sends 0, 1, 2."""

    uid: Annotated[tuple[int, int, int], Array(u32, 3)]

    @property
    def text(self) -> str:
        return "".join(f"{word:08x}" for word in self.uid)
