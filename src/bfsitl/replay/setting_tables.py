"""Betaflight 4.6.0's setting names, ranges and lookup tables that a replay writes
(:mod:`.header_settings`): every ``set`` line is checked against them before a SITL is asked,
and the tests check them against ``[4.6] src/main/cli/settings.c``."""

from __future__ import annotations

_OFF_ON = ("OFF", "ON")
_LPF = ("PT1", "BIQUAD", "PT2", "PT3")  # [4.6] src/main/cli/settings.c:367-379

#: 4.6.0 lookup settings this module sets, with their tables ([4.6] src/main/cli/settings.c).
SETTING_CHOICES: dict[str, tuple[str, ...]] = {
    **dict.fromkeys(("gyro_lpf1_type", "gyro_lpf2_type", "dterm_lpf1_type",
                     "dterm_lpf2_type"), _LPF),
    "rates_type": ("BETAFLIGHT", "RACEFLIGHT", "KISS", "ACTUAL", "QUICK"),
    "iterm_relax": ("OFF", "RP", "RPY", "RP_INC", "RPY_INC"),
    "iterm_relax_type": ("GYRO", "SETPOINT"),
    "tpa_mode": ("PD", "D"),
    "feedforward_averaging": ("OFF", "2_POINT", "3_POINT", "4_POINT"),
    "throttle_limit_type": ("OFF", "SCALE", "CLIP"),
    "mixer_type": ("LEGACY", "LINEAR", "DYNAMIC", "EZLANDING"),
    "simplified_pids_mode": ("OFF", "RP", "RPY"),
    **dict.fromkeys(("pid_at_min_throttle", "use_integrated_yaw", "rc_smoothing", "tpa_low_always",
                     "simplified_dterm_filter", "simplified_gyro_filter"), _OFF_ON),
}  # fmt: skip

# Each low..high applies to the names after it ([4.6] src/main/cli/settings.c).
_RANGES = """
0..250 p_roll i_roll d_roll d_max_roll p_pitch i_pitch d_pitch d_max_pitch p_yaw i_yaw d_yaw
d_max_yaw anti_gravity_gain anti_gravity_p_gain ez_landing_speed landing_disarm_threshold
rc_smoothing_auto_factor rc_smoothing_auto_factor_throttle 0..1000 f_roll f_pitch f_yaw
gyro_lpf1_static_hz gyro_lpf2_static_hz dterm_lpf1_static_hz dterm_lpf2_static_hz dterm_notch_hz
dterm_notch_cutoff gyro_notch1_hz gyro_notch1_cutoff gyro_notch2_hz gyro_notch2_cutoff
gyro_lpf1_dyn_min_hz gyro_lpf1_dyn_max_hz dterm_lpf1_dyn_min_hz dterm_lpf1_dyn_max_hz
1..255 roll_rc_rate pitch_rc_rate yaw_rc_rate 0..255 roll_srate pitch_srate yaw_srate
rc_smoothing_setpoint_cutoff rc_smoothing_feedforward_cutoff rc_smoothing_throttle_cutoff
200..1998 roll_rate_limit pitch_rate_limit yaw_rate_limit 0..100 roll_expo pitch_expo yaw_expo
tpa_rate tpa_low_rate feedforward_transition angle_earth_ref airmode_start_throttle_percent
horizon_level_strength feedforward_yaw_hold_gain throttle_boost d_max_gain 0..200 angle_p_gain
angle_feedforward d_max_advance feedforward_max_rate_limit ez_landing_threshold 0..500 acc_limit
acc_limit_yaw yaw_lowpass_hz acc_lpf_hz 0..10 gyro_lpf1_dyn_expo dterm_lpf1_dyn_expo
100..1000 pidsum_limit pidsum_limit_yaw 1000..2000 tpa_breakpoint tpa_low_breakpoint
10..250 feedforward_yaw_hold_time angle_feedforward_smoothing_ms horizon_limit_degrees
20..100 iterm_windup 1..50 iterm_relax_cutoff 2..50 anti_gravity_cutoff_hz 0..20 abs_control_gain
feedforward_jitter_factor 0..95 feedforward_smooth_factor 0..50 feedforward_boost 10..80
angle_limit 10..200 horizon_limit_sticks 10..5000 horizon_delay_ms 0..75 ez_landing_limit
0..2000 motor_idle 750..2250 max_throttle 0..150 vbat_sag_compensation thrust_linear
1..100 motor_output_limit 25..100 throttle_limit_percent 5..50 throttle_boost_cutoff
1..16 pid_process_denom
"""


def _read_ranges(spec: str) -> dict[str, tuple[int, int]]:
    ranges, current = {}, (0, 0)
    for token in spec.split():
        if ".." in token:
            low, high = token.split("..")
            current = (int(low), int(high))
        else:
            ranges[token] = current
    return ranges


#: 4.6.0 numeric settings this module sets, with their (min, max).
SETTING_RANGES: dict[str, tuple[int, int]] = _read_ranges(_RANGES)
