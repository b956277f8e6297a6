"""Typed MSP payloads of Betaflight 4.6 (MSP API 1.47), both directions.

Every message is a frozen dataclass with ``COMMAND``, ``decode(payload)`` and ``encode()``; both
follow the firmware layout exactly, so a fake FC can build replies with the same classes a client
uses to read them, and ``encode(decode(x)) == x`` for every layout the class covers fully. A
layout is written once, as the wire types of the fields (:mod:`.wire_types`, :mod:`.layout`);
decode and encode are derived from it (:mod:`.codec`), except where the layout really varies.

Conventions, and why:

* Fields hold the exact wire integer and carry the wire unit in their name (``roll_decideg``,
  ``vbat_cv``); properties convert to physical units. Units differ per field in MSP (attitude
  yaw is whole degrees while roll is decidegrees), and keeping the raw value makes that visible.
* Decoders ignore trailing bytes, because newer firmware appends fields to old messages. Fields
  that older firmware lacks (gated by API version) are ``None`` when absent. A tail is either
  absent or complete: a half field means a broken payload.
* A payload too short for its layout raises :class:`MspDecodeError`, never ``struct.error``.
* Request values the FC would refuse, misread or crash on raise :class:`MspRequestError`
  (an :class:`MspFrameError` and a ``ValueError``) before anything is sent.
* Text fields are latin-1: every byte decodes, so text always re-encodes to the same bytes.

Layouts are cited as ``file:line`` in the firmware tree ``src/main/`` of Betaflight 4.6.0;
``msp.c`` means ``msp/msp.c``. The modules split the messages by domain: :mod:`.identity`,
:mod:`.status`, :mod:`.sensors`, :mod:`.rc`, :mod:`.config`, :mod:`.modes`, :mod:`.system`, and
:mod:`.registry` (the command tables and MSP_MULTIPLE_MSP).
"""

from __future__ import annotations

from bfsitl.errors import MspDecodeError, MspRequestError
from bfsitl.protocol.messages.config import (
    ArmingConfig,
    FeatureConfig,
    PidAdvanced,
    SetArmingConfig,
    SetFeatureConfig,
)
from bfsitl.protocol.messages.constants import (
    BATTERY_STATE_NAMES,
    BUILD_OPTION_NAMES,
    CONFIGURATION_PROBLEM_NAMES,
    DEFAULT_RCMAP,
    FEATURE_NAMES,
    GYRO_LSB_PER_DPS,
    MAX_AUX_CHANNELS,
    MAX_RC_CHANNELS,
    MODE_RANGE_MAX_US,
    MODE_RANGE_MIN_US,
    MODE_RANGE_SLOTS,
    MODE_RANGE_STEP_US,
    RC_MAP_LETTERS,
    RX_MAP_CHANNELS,
    SENSOR_NAMES,
    SENSOR_NOT_BUILT,
    SITL_ACC_1G_LSB,
    SITL_ACC_TRUNCATION_LSB,
)
from bfsitl.protocol.messages.identity import (
    ApiVersion,
    BoardInfo,
    BuildInfo,
    CraftName,
    FcVariant,
    FcVersion,
    McuInfo,
    Uid,
)
from bfsitl.protocol.messages.layout import MspMessage, WireRecord
from bfsitl.protocol.messages.modes import (
    BoxIds,
    BoxNames,
    ModeRange,
    ModeRanges,
    SetModeRange,
)
from bfsitl.protocol.messages.rc import Rc, RcTuning, RxMap, SetRawRc, SetRxMap
from bfsitl.protocol.messages.registry import (
    REPLY_TYPES,
    REQUEST_TYPES,
    MultipleMspReply,
    MultipleMspRequest,
    decode_reply,
    decode_request,
)
from bfsitl.protocol.messages.sensors import (
    Altitude,
    Analog,
    Attitude,
    BatteryState,
    Debug,
    Motor,
    MotorTelemetry,
    MotorTelemetryEntry,
    RawGps,
    RawImu,
    SensorConfigActive,
)
from bfsitl.protocol.messages.status import Status, StatusEx
from bfsitl.protocol.messages.system import (
    EepromWrite,
    Reboot,
    RebootMode,
    RebootReply,
    Rtc,
    SetRtc,
)

__all__ = [
    "BATTERY_STATE_NAMES", "BUILD_OPTION_NAMES", "CONFIGURATION_PROBLEM_NAMES", "DEFAULT_RCMAP",
    "FEATURE_NAMES", "GYRO_LSB_PER_DPS", "MAX_AUX_CHANNELS", "MAX_RC_CHANNELS",
    "MODE_RANGE_MAX_US", "MODE_RANGE_MIN_US", "MODE_RANGE_SLOTS", "MODE_RANGE_STEP_US",
    "RC_MAP_LETTERS", "REPLY_TYPES", "REQUEST_TYPES", "RX_MAP_CHANNELS", "SENSOR_NAMES",
    "SENSOR_NOT_BUILT", "SITL_ACC_1G_LSB", "SITL_ACC_TRUNCATION_LSB",
    "Altitude", "Analog", "ApiVersion", "ArmingConfig", "Attitude", "BatteryState", "BoardInfo",
    "BoxIds", "BoxNames", "BuildInfo", "CraftName", "Debug", "EepromWrite", "FcVariant",
    "FcVersion", "FeatureConfig", "McuInfo", "ModeRange", "ModeRanges", "Motor",
    "MotorTelemetry", "MotorTelemetryEntry", "MspDecodeError", "MspMessage", "MspRequestError",
    "MultipleMspReply", "MultipleMspRequest", "PidAdvanced", "RawGps", "RawImu", "Rc",
    "RcTuning", "Reboot", "RebootMode", "RebootReply", "Rtc", "RxMap", "SensorConfigActive",
    "SetArmingConfig", "SetFeatureConfig", "SetModeRange", "SetRawRc", "SetRtc", "SetRxMap",
    "Status", "StatusEx", "Uid", "WireRecord", "decode_reply", "decode_request",
]  # fmt: skip
