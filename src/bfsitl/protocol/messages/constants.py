"""Constants of the MSP messages: sensor scales, channel and mode-range limits, and the names of
bits the messages carry. Cited as ``file:line`` in Betaflight 4.6.0's ``src/main/``."""

from __future__ import annotations

from collections.abc import Sequence

#: 1 g in accelerometer LSB on the SITL: ``acc.dev.acc_1G = 256`` (sensors/acceleration_init.c:385)
#: and the virtual accelerometer never changes it. Real IMUs usually report 2048 per g.
SITL_ACC_1G_LSB = 256
#: The SITL turns the fdm's acceleration into int16 by truncation (``sitl.c``: ``int16_t z =
#: constrain(-acc * ACC_SCALE, ...)``), not rounding, so in flight its z axis reads half an LSB
#: low on average: 0.019 m/s^2, which integrated is a climb-rate drift of 2 cm/s per second.
SITL_ACC_TRUNCATION_LSB = 0.5

#: MSP_RAW_IMU gyro is raw LSB: ``gyroRateDps()`` divides deg/s by the sensor scale
#: (sensors/gyro_init.c:747-750); 2000 dps sensors and the SITL's virtual gyro use
#: ``GYRO_SCALE_2000DPS`` = 2000/32768 deg/s per LSB (drivers/accgyro/accgyro.h:41,
#: accgyro_virtual.c:97), i.e. 16.384 LSB per deg/s.
GYRO_LSB_PER_DPS = 16.384

#: ``MAX_SUPPORTED_RC_CHANNEL_COUNT`` (rx/rx.h:73): MSP_SET_RAW_RC refuses more channels.
MAX_RC_CHANNELS = 18

#: ``MAX_MODE_ACTIVATION_CONDITION_COUNT`` (fc/rc_modes.h:96): mode range slots.
MODE_RANGE_SLOTS = 20

#: ``MAX_AUX_CHANNEL_COUNT`` (rx/rx.h:76): AUX1..AUX14, the valid ``aux_channel_index`` values.
MAX_AUX_CHANNELS = 14

#: ``RX_MAPPABLE_CHANNEL_COUNT`` (target/common_defaults_post.h:61).
RX_MAP_CHANNELS = 8

#: Letters of the channel map as the CLI ``map`` command uses them (rx/rx.c:75, first 8 only).
RC_MAP_LETTERS = "AERT1234"

#: Default map ``AETR1234`` (pg/rx.c:122): internal channel -> raw (wire) channel index.
DEFAULT_RCMAP: tuple[int, ...] = (0, 1, 3, 2, 4, 5, 6, 7)

#: ``CHANNEL_RANGE_MIN``/``MAX`` and the 25 us step of mode ranges (fc/rc_modes.h:98-105).
MODE_RANGE_MIN_US = 900
MODE_RANGE_MAX_US = 2100
MODE_RANGE_STEP_US = 25

#: MSP2_SENSOR_CONFIG_ACTIVE value for a sensor type not compiled in (msp.c:2115).
SENSOR_NOT_BUILT = 0xFF

#: Bits of the STATUS ``sensors`` word (msp.c:1099; NOT the firmware's internal sensor bits).
SENSOR_NAMES: tuple[str, ...] = ("ACC", "BARO", "MAG", "GPS", "RANGEFINDER", "GYRO", "OPTICALFLOW")

#: Feature bits (config/feature.h:46-69) named as the CLI ``feature`` command spells them
#: (cli/cli.c:234-257). Bit 14 RX_MSP has no CLI name in 4.6 (the CLI cannot toggle it).
FEATURE_NAMES: dict[int, str] = {
    0: "RX_PPM", 2: "INFLIGHT_ACC_CAL", 3: "RX_SERIAL", 4: "MOTOR_STOP", 5: "SERVO_TILT",
    6: "SOFTSERIAL", 7: "GPS", 8: "OPTICALFLOW", 9: "RANGEFINDER", 10: "TELEMETRY", 12: "3D",
    13: "RX_PARALLEL_PWM", 14: "RX_MSP", 15: "RSSI_ADC", 16: "LED_STRIP", 17: "DISPLAY",
    18: "OSD", 20: "CHANNEL_FORWARDING", 21: "TRANSPONDER", 22: "AIRMODE", 25: "RX_SPI",
    27: "ESC_SENSOR", 28: "ANTI_GRAVITY",
}  # fmt: skip

#: MSP_BUILD_INFO option ids (msp/msp_build_info.h:35-84).
BUILD_OPTION_NAMES: dict[int, str] = {
    4097: "SERIALRX_CRSF", 4098: "SERIALRX_FPORT", 4099: "SERIALRX_GHST", 4100: "SERIALRX_IBUS",
    4101: "SERIALRX_JETIEXBUS", 4102: "RX_PPM", 4103: "SERIALRX_SBUS", 4104: "SERIALRX_SPEKTRUM",
    4105: "SERIALRX_SRXL2", 4106: "SERIALRX_SUMD", 4107: "SERIALRX_SUMH", 4108: "SERIALRX_XBUS",
    12301: "TELEMETRY_FRSKY_HUB", 12302: "TELEMETRY_HOTT", 12303: "TELEMETRY_IBUS_EXTENDED",
    12304: "TELEMETRY_LTM", 12305: "TELEMETRY_MAVLINK", 12306: "TELEMETRY_SMARTPORT",
    12307: "TELEMETRY_SRXL", 16404: "ACRO_TRAINER", 16405: "AKK_SMARTAUDIO",
    16406: "BATTERY_CONTINUE", 16407: "CAMERA_CONTROL", 16408: "DASHBOARD", 16409: "EMFAT_TOOLS",
    16410: "ESCSERIAL_SIMONK", 16411: "FRSKYOSD", 16412: "GPS", 16413: "LED_STRIP",
    16414: "LED_STRIP_64", 16415: "MAG", 16416: "OSD_SD", 16417: "OSD_HD", 16418: "PINIO",
    16419: "RACE_PRO", 16420: "SERVOS", 16421: "VTX", 16422: "ALTITUDE_HOLD",
    16423: "SOFTSERIAL", 16424: "WING", 16425: "POSITION_HOLD", 8230: "BRUSHED", 8231: "DSHOT",
    8232: "MULTISHOT", 8233: "ONESHOT", 8234: "PROSHOT", 8235: "PWM_OUTPUT",
}  # fmt: skip

#: BOARD_INFO ``configurationProblems`` bits (msp.c:723-724).
CONFIGURATION_PROBLEM_NAMES: dict[int, str] = {
    0: "ACC_NEEDS_CALIBRATION",
    1: "MOTOR_PROTOCOL_DISABLED",
}

#: ``batteryState_e`` (sensors/battery.h:88-94).
BATTERY_STATE_NAMES: tuple[str, ...] = ("OK", "WARNING", "CRITICAL", "NOT_PRESENT", "INIT")


def mask_names(mask: int, names: dict[int, str] | Sequence[str]) -> tuple[str, ...]:
    """The names of the bits set in ``mask``; a bit without a name reads ``BIT<n>``."""
    lookup = dict(enumerate(names)) if isinstance(names, Sequence) else names
    return tuple(
        lookup.get(bit, f"BIT{bit}") for bit in range(mask.bit_length()) if mask >> bit & 1
    )
