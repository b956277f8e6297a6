"""A real log's header as Betaflight 4.6.0 CLI lines: the replaying SITL set up like the real FC.

:func:`header_settings` reads one log's ``H name:value`` lines and returns, for every header
that matters to flight, the 4.6.0 ``set``/``feature`` lines that carry it or why it is not
carried; a bad value is reported, never raised.  The RC path (deadbands, ``thr_mid``,
``thr_expo``, ``thr_hover``, ``mid_rc``, ``rc_interpolation*``) is :mod:`.sticks`'s.  ``[4.6]``
is the installed 4.6.0 tree; ``[3.1.5]``, ``[4.2.9]`` and ``[4.5.2]`` are tags of
github.com/betaflight/betaflight.

* Names, ranges and tables are 4.6.0's (``[4.6] src/main/cli/settings.c``: tables from line
  222, settings from 747; the tests parse it); out-of-range values are clamped and reported.
  Headers log a table index; 4.6.0 takes the name, read from the logging version's table.
* D: up to 4.5 ``D`` is the peak and ``d_min`` the base, boosting when 0 < d_min < D
  (``[4.2.9] src/main/flight/pid.c:745-749``); 4.6 boosts from ``d_roll`` up to ``d_max_roll``
  (``[4.6] src/main/flight/pid_init.c:531-537``, ``pid.c:1418-1439``), both base + (peak -
  base) * boost.  4.3 moved the boost gain from 0.00005/10 Hz to 0.00008/35 Hz
  (``[4.2.9] src/main/flight/pid.c:108-111``, ``[4.6] pid_init.c:53-56``): a 4.2
  ``d_min_gain`` is multiplied by 2.1875.
* P, I, D and F have the same scales in 3.1.5 and 4.6 (``[4.6] src/main/flight/pid.h:46-52``).
  3.1.5 had no D on yaw (``[3.1.5] src/main/flight/pid.c:263``) and TPA on P and D (248, 281);
  4.2 and 4.3 log no ``tpa_mode``, default D there as in 4.6 (``[4.6] pid.c:228``).  3.1.5's
  rates are 4.6's BETAFLIGHT rates with shared roll/pitch values and a 1998 deg/s limit
  (``[3.1.5] src/main/fc/fc_rc.c:92-128``, ``[4.6] src/main/fc/rc.c:184-202``).
* What the logging firmware lacked is turned off: 4.6's yaw feedforward hold (default 15,
  ``[4.6] pid.c:244``), 4.5's low-throttle TPA (pid.c:234), and for 3.x feedforward, I-term
  relax, D max, dynamic and second lowpasses and throttle boost.  The tuning sliders are turned
  off so nothing recomputes the carried gains.
* PID rate: ``looptime`` is the gyro loop in us, the PID loop runs every ``pid_process_denom``
  of them (``[4.6] src/main/blackbox/blackbox.c:1528-1530``, ``[3.1.5] src/main/fc/fc_init.c:432``).
* The SITL has no DShot (``[4.6] src/main/target/common_pre.h:52-54``): no RPM telemetry, RPM
  filter or dynamic idle; no dynamic notch either (``common_post.h:550-553``).  Its motors are
  PWM (``[4.6] src/main/pg/motor.c:62-63``) with the idle at ``motor_idle / 10000`` of the range
  (``[4.6] src/main/drivers/pwm_output.c:45``, ``src/platform/SIMULATOR/sitl.c:572,597``), the
  share a DShot idle value gives, so a DShot log's idle carries unchanged.
* Changed laws are not carried: ``iterm_windup`` became the I limit as a share of
  pidsum_limit in 4.6 (``[4.6] pid_init.c:445``, ``[4.5.2] src/main/flight/pid.c:860-861``);
  4.4 rewrote anti-gravity, 4.3 feedforward's boost and limits, 4.5 angle and horizon modes
  (``[4.5.2] src/main/flight/pid_init.c:285-293``).
* An automatic rc smoothing cutoff (0) is pinned to the one the FC was using when it wrote the
  header (``active_cutoffs``) when known: the replay's RC rate may differ.
"""

from __future__ import annotations

import re
import struct
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from bfsitl.errors import SettingNotCarriedError
from bfsitl.replay.setting_tables import SETTING_CHOICES, SETTING_RANGES

__all__ = [
    "SETTING_CHOICES",
    "SETTING_RANGES",
    "CarriedSetting",
    "HeaderSettings",
    "NotCarried",
    "header_settings",
]


@dataclass(frozen=True, slots=True)
class CarriedSetting:
    """One header field carried over to the replaying FC."""

    header: str  # the header's name, e.g. "rollPID"
    value: str  # as logged
    cli_lines: tuple[str, ...]  # e.g. ("set p_roll = 47", "set i_roll = 85", ...)


@dataclass(frozen=True, slots=True)
class NotCarried:
    """A header field (or part of one) the replaying FC does not get."""

    header: str
    value: str  # as logged
    why: str  # one short clause


@dataclass(frozen=True, slots=True)
class HeaderSettings:
    """What one log's header gives the replaying 4.6.0 SITL."""

    firmware: str  # the logging firmware, e.g. "Betaflight 4.2.9"
    carried: tuple[CarriedSetting, ...]  # header order, the firmware baseline first
    not_carried: tuple[NotCarried, ...]  # the flight-relevant fields (or parts) left behind

    @property
    def cli_lines(self) -> tuple[str, ...]:
        """Every carried line, in order, each once."""
        return tuple(dict.fromkeys(line for s in self.carried for line in s.cli_lines))


_AXES = ("roll", "pitch", "yaw")


_Version = tuple[int, int]
_Assignment = tuple[str, int | str] | str  # (setting, value) or a whole CLI line
_Rule = Callable[["_Collect", str, str], None]


class _Collect:
    """The headers being read and what came of each."""

    def __init__(self, headers: dict[str, str], version: _Version, sitl_pid_rate_hz: float):
        self.headers, self.version, self.sitl_pid_rate_hz = headers, version, sitl_pid_rate_hz
        self.carried: list[CarriedSetting] = []
        self.not_carried: list[NotCarried] = []

    def skip(self, header: str, why: str) -> None:
        self.not_carried.append(NotCarried(header, self.headers.get(header, ""), why))

    def carry(self, header: str, assignments: Sequence[_Assignment]) -> None:
        lines = []
        for item in assignments:
            if isinstance(item, str):
                lines.append(item)
                continue
            name, value = item
            if name not in SETTING_CHOICES:
                low, high = SETTING_RANGES[name]
                clamped = min(max(int(value), low), high)
                if clamped != value:
                    self.skip(
                        header, f"{name} {value} is outside 4.6.0's {low}..{high}: set {clamped}"
                    )
                value = clamped
            lines.append(f"set {name} = {value}")
        self.carried.append(CarriedSetting(header, self.headers.get(header, ""), tuple(lines)))


def _ints(value: str, count: int) -> list[int]:
    """The header's comma-separated integers, exactly ``count`` of them."""
    try:
        numbers = [int(part) for part in value.split(",")]
    except ValueError:
        raise SettingNotCarriedError(f"not {count} integer(s): {value!r}") from None
    if len(numbers) != count:
        raise SettingNotCarriedError(f"{len(numbers)} value(s) where {count} were expected")
    return numbers


def _header_ints(c: _Collect, header: str, count: int) -> list[int] | None:
    """Another header's integers, or None when it is absent or unreadable."""
    try:
        return _ints(c.headers[header], count) if header in c.headers else None
    except SettingNotCarriedError:
        return None


def _to(*names: str, scale: float = 1.0) -> _Rule:
    """The header's values, in order, are these 4.6.0 settings (times ``scale``)."""

    def rule(c: _Collect, header: str, value: str) -> None:
        c.carry(
            header,
            [(n, round(v * scale)) for n, v in zip(names, _ints(value, len(names)), strict=True)],
        )

    return rule


def _each(*names: str) -> _Rule:
    """The header's one value goes to each of these settings (3.x shared roll and pitch)."""
    return lambda c, header, value: c.carry(header, [(n, _ints(value, 1)[0]) for n in names])


def _pick(name: str, table: Sequence[str]) -> _Rule:
    """The header logs an index into ``table`` (the logging version's), or (4.5+ mixer_type) the
    name itself; 4.6.0 takes the name."""

    def rule(c: _Collect, header: str, value: str) -> None:
        if value.strip() in table:
            choice = value.strip()
        else:
            index = _ints(value, 1)[0]
            if not 0 <= index < len(table):
                raise SettingNotCarriedError(
                    f"{index} is not an index of the table {'/'.join(table)}"
                )
            choice = table[index]
        if choice not in SETTING_CHOICES[name]:
            raise SettingNotCarriedError(f"{choice} has no 4.6.0 equivalent")
        c.carry(header, [(name, choice)])

    return rule


def _not(why: str) -> _Rule:
    return lambda c, header, value: c.skip(header, why)


def _since(version: _Version, rule: _Rule, why: str) -> _Rule:
    """``rule`` for logs from ``version`` on; older logs' field meant something else."""
    return lambda c, h, v: rule(c, h, v) if c.version >= version else c.skip(h, why)


def _d_lines(c: _Collect, axis: int) -> list[_Assignment]:
    """``d_<axis>`` and ``d_max_<axis>`` from the logged D and (before 4.6) d_min or d_max."""
    name = _AXES[axis]
    pid = _header_ints(c, f"{name}PID", 3)
    if pid is None:
        raise SettingNotCarriedError(f"{name}PID is missing or unreadable")
    d = pid[2]
    if c.version < (4, 0):
        return [(f"d_{name}", 0 if axis == 2 else d), (f"d_max_{name}", 0)]
    if c.version >= (4, 6):
        d_max = _header_ints(c, "d_max", 3)
        return [(f"d_{name}", d), (f"d_max_{name}", d_max[axis])] if d_max else [(f"d_{name}", d)]
    d_min = _header_ints(c, "d_min", 3)
    if d_min is None:
        return [(f"d_{name}", d)]
    base, peak = (d_min[axis], d) if 0 < d_min[axis] < d else (d, 0)
    return [(f"d_{name}", base), (f"d_max_{name}", peak)]


def _pid(axis: int) -> _Rule:
    def rule(c: _Collect, header: str, value: str) -> None:
        p, i, d = _ints(value, 3)
        name = _AXES[axis]
        c.carry(header, [(f"p_{name}", p), (f"i_{name}", i), *_d_lines(c, axis)])
        if c.version < (4, 0) and axis == 2 and d:
            c.skip(header, f"yaw D {d}: 3.x applied no D on yaw, so d_yaw is 0")

    return rule


def _d_min(c: _Collect, header: str, value: str) -> None:
    _ints(value, 3)
    c.carry(header, [line for axis in range(3) for line in _d_lines(c, axis)])


def _digital_motors(c: _Collect) -> bool | None:
    """Whether the log's ESC protocol was DShot/ProShot (index 5..8 in 3.1.5 to 4.6's table,
    ``[4.2.9] src/main/cli/settings.c:278-282``, ``[3.1.5] src/main/fc/cli.c:334-339``)."""
    for header in ("motor_pwm_protocol", "fast_pwm_protocol"):
        protocol = _header_ints(c, header, 1)
        if protocol is not None:
            return 5 <= protocol[0] <= 8
    return None


def _motor(name: str, digital: bool, offset_us: int = 0, scale: int = 1) -> _Rule:
    """A DShot idle value carries only from DShot logs, minthrottle/maxthrottle (analog output
    bounds) only from analog ones; 4.6's PWM idle is ``motor_idle`` * 0.1 us above min_command."""

    def rule(c: _Collect, header: str, value: str) -> None:
        if digital and _digital_motors(c) is False:
            raise SettingNotCarriedError(
                "unused with analog (PWM) motors: minthrottle set their idle"
            )
        if not digital and _digital_motors(c) is not False:
            raise SettingNotCarriedError(
                "bounds analog (PWM) outputs only; the log's motors were DShot"
            )
        c.carry(header, [(name, (_ints(value, 1)[0] - offset_us) * scale)])

    return rule


def _features(c: _Collect, header: str, value: str) -> None:
    """AIRMODE, MOTOR_STOP and ANTI_GRAVITY: the same bits in 3.1.5 to 4.6
    (``[4.6] src/main/config/feature.h:49,65,69``, ``[3.1.5] src/main/fc/config.h:53``);
    anti-gravity needs the feature in 4.2 and 4.6 (``[4.6] src/main/fc/core.c:1175``); 3.1.5
    had no such bit."""
    bits = _ints(value, 1)[0]
    named = [("AIRMODE", 22), ("MOTOR_STOP", 4)]
    if c.version >= (4, 0):
        named.append(("ANTI_GRAVITY", 28))
    c.carry(header, [f"feature {'' if bits >> bit & 1 else '-'}{name}" for name, bit in named])
    if bits >> 12 & 1:
        c.skip(header, "3D (reversible motors): the replay flies ordinary motors")


def _pid_denom(c: _Collect, header: str, value: str) -> None:
    """The SITL's denominator whose rate is nearest the log's PID rate; off by 10 % is reported."""
    looptime_us = _header_ints(c, "looptime", 1)
    denom = _ints(value, 1)[0]
    if not looptime_us or looptime_us[0] <= 0 or denom <= 0:
        raise SettingNotCarriedError("no usable looptime or denominator to find the log's PID rate")
    log_hz = 1e6 / (looptime_us[0] * denom)
    sitl = min(range(1, 17), key=lambda n: abs(c.sitl_pid_rate_hz / n - log_hz))
    c.carry(header, [("pid_process_denom", sitl)])
    if abs(c.sitl_pid_rate_hz / sitl - log_hz) > 0.1 * log_hz:
        hz = c.sitl_pid_rate_hz / sitl
        c.skip(header, f"the SITL's nearest PID rate is {hz:.0f} Hz, the log's {log_hz:.0f} Hz")


def _anti_gravity(c: _Collect, header: str, value: str) -> None:
    """From 4.4 the same setting; before, a throttle-step booster whose 'off' carries as 0
    (3.x logs a float, 1.0 = no boost; 4.2 1000 = off, 4.3 0 = off,
    ``[4.2.9] src/main/flight/pid.h:54``)."""
    gain = _ints(value, 1)[0]
    if c.version < (4, 0):
        off = struct.unpack("<f", struct.pack("<I", gain & 0xFFFFFFFF))[0] <= 1.0
    else:
        off = gain <= (1000 if c.version < (4, 3) else 0)
    if c.version < (4, 4) and not off:
        raise SettingNotCarriedError(
            "4.4 replaced the throttle-step anti-gravity with a new law and gain scale"
        )
    c.carry(header, [("anti_gravity_gain", gain if c.version >= (4, 4) else 0)])


def _float_accel_limit(name: str) -> _Rule:
    """3.x logs a float in deg/s per ms; 4.x's integer is tenths of that
    (``[3.1.5] src/main/flight/pid.c:168-169``, ``[4.6] src/main/flight/pid_init.c:433-434``)."""

    def rule(c: _Collect, header: str, value: str) -> None:
        raw = _ints(value, 1)[0] & 0xFFFFFFFF
        c.carry(header, [(name, round(struct.unpack("<f", struct.pack("<I", raw))[0] * 10))])

    return rule


def _vbat_compensation(c: _Collect, header: str, value: str) -> None:
    """Off carries as off; on has no equivalent (4.6's vbat_sag_compensation is another law)."""
    if _ints(value, 1)[0]:
        raise SettingNotCarriedError(
            "vbat PID compensation has no 4.6 equivalent (vbat_sag is another law)"
        )
    c.carry(header, [("vbat_sag_compensation", 0)])


def _airmode_start(c: _Collect, header: str, value: str) -> None:
    """3.x compares throttle in us; 4.x in percent, converted as 4.2's MSP does
    (``[4.2.9] src/main/msp/msp.c:3016``)."""
    v = _ints(value, 1)[0]
    c.carry(header, [("airmode_start_throttle_percent", (v - 1000) // 10 if v >= 1000 else v)])


def _ff_averaging(c: _Collect, header: str, value: str) -> None:
    """4.2: OFF, ON, AVERAGED_2..4 (``[4.2.9] src/main/cli/settings.c:478-480``)."""
    mode = _ints(value, 1)[0]
    if not 1 <= mode <= 4:
        raise SettingNotCarriedError(
            "4.2 without setpoint interpolation has no 4.6 feedforward mode"
        )
    c.carry(header, [("feedforward_averaging", SETTING_CHOICES["feedforward_averaging"][mode - 1])])


def _rc_cutoffs_42(c: _Collect, header: str, value: str) -> None:
    """4.2's input and derivative cutoffs (0 = auto) become 4.6's setpoint and feedforward ones;
    4.2 filtered throttle with the input cutoff (rc_interpolation_channels RPYT by default)."""
    if _header_ints(c, "rc_smoothing_type", 1) == [0]:
        raise SettingNotCarriedError(
            "unused: the log smoothed by interpolation, which 4.6 does not have"
        )
    setpoint, derivative = _ints(value, 2)
    active = _header_ints(c, "rc_smoothing_active_cutoffs", 2) or [0, 0]
    setpoint, derivative = setpoint or active[0], derivative or active[1]
    pairs = ("setpoint", setpoint), ("throttle", setpoint), ("feedforward", derivative)
    c.carry(header, [(f"rc_smoothing_{k}_cutoff", v) for k, v in pairs])


def _rc_cutoff(kind: str, index: int) -> _Rule:
    """4.3+: the setting, or (when automatic) the active cutoff the FC was using."""

    def rule(c: _Collect, header: str, value: str) -> None:
        cutoff = _ints(value, 1)[0]
        active = _header_ints(c, "rc_smoothing_active_cutoffs_ff_sp_thr", 3)
        c.carry(header, [(f"rc_smoothing_{kind}_cutoff", cutoff or (active or [0] * 3)[index])])

    return rule


def _baseline(version: _Version) -> list[_Assignment]:
    """Lines for what the logging firmware did not have (see the module docstring)."""
    lines: list[_Assignment] = [("simplified_pids_mode", "OFF")]
    lines += [("simplified_dterm_filter", "OFF"), ("simplified_gyro_filter", "OFF")]
    if version < (4, 6):
        lines.append(("feedforward_yaw_hold_gain", 0))
    if version < (4, 5):
        lines.append(("tpa_low_rate", 0))
    if version < (4, 4):
        lines.append(("tpa_mode", "PD" if version < (4, 0) else "D"))
    if version < (4, 0):
        lines += [("rates_type", "BETAFLIGHT"), ("iterm_relax", "OFF"), ("throttle_boost", 0)]
        lines += [(f"{a}_rate_limit", 1998) for a in _AXES] + [(f"f_{a}", 0) for a in _AXES]
        lines += [(f"{f}_lpf1_dyn_min_hz", 0) for f in ("gyro", "dterm")]
        lines += [(f"{f}_lpf2_static_hz", 0) for f in ("gyro", "dterm")]
    return lines


_FF_42 = "4.3 rewrote feedforward's boost, spike and rate limits (not the same law)"
_NAV = "navigation (GPS, altitude and position hold): not flown by a replay"
_WING = "fixed-wing only (USE_WING), not in the quad SITL"
_RPM = "the SITL has no DShot, so no RPM telemetry (bidirectional DShot)"
_NOTCH = "the SITL build has no dynamic notch (no FFT on x86)"
_HARDWARE = "the FC's hardware: the SITL's sensors are simulated"
_MOTOR = "ESC protocol and rate: the SITL's motors are simulated, fed PWM values"
_BATTERY = "battery sensing and alarms (hardware calibration)"
_SLIDERS = "tuning-slider positions: the gains and filters they set are carried directly"
_FILTER_3 = ("PT1", "BIQUAD", "FIR")  # [3.1.5] src/main/fc/cli.c:349-351; 4.2 kept PT1, BIQUAD

_RULES: dict[str, _Rule] = {
    "rollPID": _pid(0), "pitchPID": _pid(1), "yawPID": _pid(2),
    "d_min": _d_min, "d_max": _to("d_max_roll", "d_max_pitch", "d_max_yaw"),
    "d_min_gain": _to("d_max_gain", scale=2.1875), "d_max_gain": _to("d_max_gain"),
    "d_min_advance": _to("d_max_advance"), "d_max_advance": _to("d_max_advance"),
    "feedforward_weight": _to("f_roll", "f_pitch", "f_yaw"),
    "ff_weight": _to("f_roll", "f_pitch", "f_yaw"),
    "levelPID": _since((4, 5), _to("angle_p_gain", "horizon_level_strength",
                                   "horizon_limit_sticks"), "4.5 rewrote angle and horizon modes"),
    "pid_process_denom": _pid_denom, "features": _features,
    "rc_rates": _to("roll_rc_rate", "pitch_rc_rate", "yaw_rc_rate"),
    "rc_expo": _to("roll_expo", "pitch_expo", "yaw_expo"),
    "rates": _to("roll_srate", "pitch_srate", "yaw_srate"),
    "rate_limits": _to("roll_rate_limit", "pitch_rate_limit", "yaw_rate_limit"),
    "rates_type": _pick("rates_type", SETTING_CHOICES["rates_type"]),
    "rcRate": _each("roll_rc_rate", "pitch_rc_rate"), "rcYawRate": _to("yaw_rc_rate"),
    "rcExpo": _each("roll_expo", "pitch_expo"), "rcYawExpo": _to("yaw_expo"),
    "dynThrPID": _to("tpa_rate"),
    "tpa_mode": _pick("tpa_mode", SETTING_CHOICES["tpa_mode"]),
    "gyro_soft_type": _pick("gyro_lpf1_type", _FILTER_3),
    "gyro_lowpass_type": _pick("gyro_lpf1_type", _FILTER_3),
    "gyro_lowpass2_type": _pick("gyro_lpf2_type", _FILTER_3),
    "gyro_lowpass_hz": _to("gyro_lpf1_static_hz"), "gyro_lowpass2_hz": _to("gyro_lpf2_static_hz"),
    "gyro_lowpass_dyn_hz": _to("gyro_lpf1_dyn_min_hz", "gyro_lpf1_dyn_max_hz"),
    "gyro_lpf1_dyn_hz": _to("gyro_lpf1_dyn_min_hz", "gyro_lpf1_dyn_max_hz"),
    "gyro_notch_hz": _to("gyro_notch1_hz", "gyro_notch2_hz"),
    "gyro_notch_cutoff": _to("gyro_notch1_cutoff", "gyro_notch2_cutoff"),
    "dterm_filter_type": _pick("dterm_lpf1_type", _FILTER_3),
    "dterm_filter2_type": _pick("dterm_lpf2_type", _FILTER_3),
    "dterm_lowpass_hz": _to("dterm_lpf1_static_hz"), "dterm_lpf_hz": _to("dterm_lpf1_static_hz"),
    "dterm_lowpass2_hz": _to("dterm_lpf2_static_hz"),
    "dterm_lowpass_dyn_hz": _to("dterm_lpf1_dyn_min_hz", "dterm_lpf1_dyn_max_hz"),
    "dterm_lpf1_dyn_hz": _to("dterm_lpf1_dyn_min_hz", "dterm_lpf1_dyn_max_hz"),
    "yaw_lpf_hz": _to("yaw_lowpass_hz"),
    "iterm_windup": _since((4, 6), _to("iterm_windup"), "before 4.6 a motor-saturation point"),
    "itermWindupPointPercent": _not("a motor-saturation point; 4.6's iterm_windup is the I limit"),
    "iterm_relax": _pick("iterm_relax", SETTING_CHOICES["iterm_relax"]),
    "iterm_relax_type": _pick("iterm_relax_type", SETTING_CHOICES["iterm_relax_type"]),
    "pidAtMinThrottle": _pick("pid_at_min_throttle", SETTING_CHOICES["pid_at_min_throttle"]),
    "anti_gravity_gain": _anti_gravity,
    "anti_gravity_mode": _not("4.4 replaced the throttle-step anti-gravity and its modes"),
    "anti_gravity_threshold": _not("4.4 replaced the throttle-step anti-gravity and its threshold"),
    "use_integrated_yaw": _pick("use_integrated_yaw", SETTING_CHOICES["use_integrated_yaw"]),
    "ff_interpolate_sp": _ff_averaging,
    "ff_spike_limit": _not(_FF_42), "ff_max_rate_limit": _not(_FF_42), "ff_boost": _not(_FF_42),
    "yawRateAccelLimit": _float_accel_limit("acc_limit_yaw"),
    "rateAccelLimit": _float_accel_limit("acc_limit"),
    "vbat_pid_gain": _vbat_compensation, "vbat_pid_compensation": _vbat_compensation,
    "acc_lpf_hz": _to("acc_lpf_hz", scale=0.01),  # logged x100 ([4.6] blackbox.c:1713)
    "airmode_activate_throttle": _airmode_start,
    "dshot_idle_value": _motor("motor_idle", True),
    "digitalIdleOffset": _motor("motor_idle", True),  # 3.x: percent x 100, like 4.x
    "minthrottle": _motor("motor_idle", False, 1000, 10),
    "maxthrottle": _motor("max_throttle", False),
    "mixer_type": _pick("mixer_type", SETTING_CHOICES["mixer_type"]),
    "rc_smoothing_type": lambda c, h, v: c.carry(h, [("rc_smoothing", "ON")])
    if _ints(v, 1) == [1] else c.skip(h, "4.6 has no interpolation smoothing"),
    "rc_smoothing_cutoffs": _rc_cutoffs_42,
    "rc_smoothing_auto_factor": _since((4, 3), _to("rc_smoothing_auto_factor"),
                                       "4.3 changed the automatic cutoff law (cutoffs pinned)"),
    "rc_smoothing_filter_type": _not("4.6's rc smoothing filters are fixed PT3"),
    "rc_smoothing_setpoint_cutoff": _rc_cutoff("setpoint", 1),
    "rc_smoothing_feedforward_cutoff": _rc_cutoff("feedforward", 0),
    "rc_smoothing_throttle_cutoff": _rc_cutoff("throttle", 2),
    "magPID": _not("no 4.6.0 setting (magnetometer heading hold)"),
    "dtermSetpointWeight": _not("3.x D on setpoint: 4.6's D acts on the gyro only"),
    "setpointRelaxRatio": _not("3.x D on setpoint: 4.6's D acts on the gyro only"),
    "yaw_p_limit": _not("no 4.6.0 setting"), "dterm_average_count": _not("removed after 3.x"),
    "motor_kv": _not("only for RPM-telemetry features the SITL lacks"),
    "gyro_cal_on_first_arm": _not("gyro calibration timing only"),
    "serialrx_provider": _not("receiver hardware: the SITL gets its sticks over UDP"),
}  # fmt: skip
# Headers that are 4.6.0 settings of the same name and meaning (4.3+ names mostly).
_SAME_NAME = """
tpa_rate tpa_breakpoint tpa_low_rate tpa_low_breakpoint yaw_lowpass_hz dterm_notch_hz
dterm_notch_cutoff iterm_relax_cutoff pidsum_limit pidsum_limit_yaw acc_limit acc_limit_yaw
abs_control_gain motor_idle feedforward_transition anti_gravity_cutoff_hz anti_gravity_p_gain
gyro_lpf1_static_hz gyro_lpf2_static_hz gyro_lpf1_dyn_expo dterm_lpf1_static_hz
dterm_lpf2_static_hz dterm_lpf1_dyn_expo rc_smoothing_auto_factor_throttle vbat_sag_compensation
motor_output_limit throttle_limit_percent throttle_boost throttle_boost_cutoff thrust_linear
feedforward_smooth_factor feedforward_jitter_factor feedforward_boost feedforward_max_rate_limit
feedforward_yaw_hold_gain feedforward_yaw_hold_time angle_feedforward angle_limit angle_earth_ref
angle_feedforward_smoothing_ms horizon_limit_degrees horizon_delay_ms ez_landing_threshold
ez_landing_limit ez_landing_speed landing_disarm_threshold
"""
_RULES.update({name: _to(name) for name in _SAME_NAME.split()})
_RULES.update({name: _pick(name, SETTING_CHOICES[name]) for name in (
    "gyro_lpf1_type", "gyro_lpf2_type", "dterm_lpf1_type", "dterm_lpf2_type", "pid_at_min_throttle",
    "feedforward_averaging", "throttle_limit_type", "tpa_low_always", "rc_smoothing")})  # fmt: skip
for _names, _why in (
    (("gyro_hardware_lpf", "gyro_lpf", "acc_hardware", "baro_hardware", "mag_hardware"), _HARDWARE),
    (("gyro_to_use",), _HARDWARE),
    (("vbat_scale", "vbatscale", "vbatcellvoltage", "currentSensor", "currentMeter"), _BATTERY),
    (("motor_pwm_protocol", "fast_pwm_protocol", "motor_pwm_rate"), _MOTOR),
    (("use_unsynced_pwm", "unsynced_fast_pwm"), _MOTOR),
    (("dshot_bidir", "motor_poles", "rpm_notch_lpf", "dyn_idle_start_increase"), _RPM),
    (("altPID", "posPID", "posrPID", "navrPID", "velPID"), "3.x navigation PIDs: none in 4.6.0"),
    (("s_roll", "s_pitch", "s_yaw", "yaw_type", "angle_pitch_offset"), _WING),
):
    _RULES.update(dict.fromkeys(_names, _not(_why)))
_PREFIX_RULES = (
    (("dyn_notch_",), _NOTCH),
    (("gyro_rpm_notch_", "dterm_rpm_notch_", "rpm_filter_", "dyn_idle_"), _RPM),
    (("gps_", "alt_hold_", "pos_hold_", "altitude_", "ap_"), _NAV),
    (("spa_", "tpa_curve_", "tpa_speed_"), _WING),
    (("chirp_",), "the chirp test signal: not part of a replayed flight"),
    (("simplified_",), _SLIDERS),
)
#: Not settings (identity, measurements, logging), or the RC path that .sticks sets: no entry.
_SILENT = {"Product", "Data version", "Firmware type", "Firmware revision", "Firmware date",
           "Board information", "Log start datetime", "Craft name", "DeviceUID", "I interval",
           "P interval", "P ratio", "gyro_scale", "acc_1G", "motorOutput", "vbatref", "looptime",
           "gyro_sync_denom", "debug_mode", "fields_disabled_mask", "gyro_debug_axis",
           "rc_smoothing_debug_axis", "rc_smoothing_rx_average", "rc_smoothing_rx_smoothed",
           "rc_smoothing_active_cutoffs", "rc_smoothing_active_cutoffs_ff_sp_thr",
           "deadband", "yaw_deadband", "thr_mid", "thr_expo", "thrMid", "thrExpo", "thr_hover",
           "mincheck", "min_check", "midrc", "mid_rc"}  # fmt: skip
_SILENT_PREFIXES = ("Field ", "blackbox_", "rc_interpolation")


def _firmware(headers: dict[str, str]) -> tuple[str, _Version]:
    """The logging firmware's name and (major, minor); without a revision, guessed from names."""
    revision = headers.get("Firmware revision", "")
    guess = (3, 1) if "rcRate" in headers else (4, 6) if "d_max" in headers else (4, 2)
    found = re.match(r"\s*(\S+)\s+(\d+)\.(\d+)\.(\d+)", revision)
    if not found:
        return (revision.strip() or "unknown"), guess
    name, major, minor, patch = found.groups()
    # Another firmware's numbers (INAV, EmuFlight) say nothing of Betaflight's settings.
    version = (int(major), int(minor)) if name == "Betaflight" else guess
    return f"{name} {major}.{minor}.{patch}", version


def header_settings(headers: dict[str, str], *, sitl_pid_rate_hz: float = 8000.0) -> HeaderSettings:
    """The 4.6.0 CLI lines that set a SITL up like the FC that wrote a log, and what cannot be.

    Args:
        headers: Every ``H name:value`` line of one log, name stripped, value as text.
        sitl_pid_rate_hz: The replaying SITL's PID rate at ``pid_process_denom = 1``.

    Returns:
        The firmware, the carried fields with their lines, and the flight-relevant fields that
        are not carried with why.  Identity, logging and RC-path headers appear in neither.
    """
    firmware, version = _firmware(headers)
    collect = _Collect(headers, version, sitl_pid_rate_hz)
    collect.carry("Firmware revision", _baseline(version))
    for name, value in headers.items():
        if name in _SILENT or name.startswith(_SILENT_PREFIXES):
            continue
        rule = _RULES.get(name)
        if rule is None:
            why = next((w for p, w in _PREFIX_RULES if name.startswith(p)), None)
            rule = _not(why or "no known 4.6.0 equivalent")
        try:
            rule(collect, name, value)
        except SettingNotCarriedError as refused:
            collect.skip(name, str(refused))
    return HeaderSettings(firmware, tuple(collect.carried), tuple(collect.not_carried))
