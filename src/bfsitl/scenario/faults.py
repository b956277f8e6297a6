"""The fault catalog: what a ``[[fault]]`` table can inject, and on which firmware.

Each fault acts where the real thing would: on the RC link (what reaches the FC's receiver),
in the physics (a weak motor, the wind), or in the sensors the physics reports (noise, bias,
drift, the GPS).  The firmware sees nothing of bfsitl; it sees a receiver, a motor, a sensor.

========================  ==========================================  =====================
kind (parameters)          what the FC sees                             firmware
========================  ==========================================  =====================
``rc_loss``               ``method``: ``silence`` (no RC at all),      silence: master and
(``method = "auto"``)     ``invalid_pulses`` (roll, pitch, throttle,   lockstep 4.6.0 (a
                          yaw at 0 us: a receiver's lost-channel       stock 4.6.0 holds the
                          output; the AUX switches stay), ``switch``   last sticks forever);
                          (the FAILSAFE mode on AUX3, as a pilot's     invalid_pulses and
                          failsafe switch); ``auto`` = silence where   switch: every
                          the firmware detects it, else the switch     firmware
``rc_latency``            every RC command ``delay_s`` late, plus up   every firmware
(``delay_s``,             to ``jitter_s`` more per packet (resolution:
``jitter_s = 0``)         the control period)
``gps_loss``              the virtual GPS stops: out-of-range lat/lon, master (4.6.0's virtual
                          the FC's fix goes stale                      GPS keeps its fix)
``gps_glitch``            the GPS position jumps by ``north_m``,       GPS builds
(``north_m``, ``east_m``) ``east_m`` and stays off by that much
``motor_thrust``          motor ``motor`` (1-4, Betaflight's order)    every firmware
(``motor``, ``fraction``) gives ``fraction`` of its thrust and torque
``gyro_noise``            white noise, ``std_deg_s`` per sample        every firmware
``gyro_bias``             ``x_deg_s``, ``y_deg_s``, ``z_deg_s`` (FRD)  every firmware
``accel_noise``           white noise, ``std_m_s2`` per sample         every firmware
``accel_bias``            ``x_m_s2``, ``y_m_s2``, ``z_m_s2`` (FRD)     every firmware
``baro_drift``            the barometer drifts as if climbing at       every firmware
(``rate_m_s``)            ``rate_m_s`` (ISA: 12 Pa per metre)
``wind``                  the wind changes to ``north_m_s``,           every firmware
                          ``east_m_s``, ``gust_std_m_s`` (a step; with
                          ``duration_s``, a gust that ends)
``mode_switch``           the pilot raises the ``mode`` switch          ALTHOLD, POSHOLD,
(``mode``)                (ALTHOLD, POSHOLD, GPS RESCUE, AUTOPILOT)     GPS RESCUE: every
                          and lets go: sticks centred, throttle where   firmware with them;
                          it was; the FC flies (bfsitl only watches)    AUTOPILOT: master's
                                                                       flight plan builds
========================  ==========================================  =====================

Every fault may last ``duration_s`` (then it is undone: RC comes back, the motor recovers);
without it, it lasts to the end of the run.  A fault the firmware cannot express is refused
before the flight (:class:`~bfsitl.errors.FaultNotSupportedError`), never silently passed.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from bfsitl.errors import FaultNotSupportedError, ScenarioError
from bfsitl.fc.rc_link import RC_MID_US, RcFault
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US
from bfsitl.physics.wind import MAX_GUST_STD_M_S, MAX_WIND_COMPONENT_M_S, Wind
from bfsitl.protocol.boxes import AUTOPILOT_BOX_ID, BoxId
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.scenario.values import number_in

if TYPE_CHECKING:
    from bfsitl.mission.vehicle import Vehicle

#: What invalid_pulses sends on roll, pitch, throttle and yaw: no pulse at all, as a receiver
#: reports a lost channel; anything below rx_min_usec (885 us) is invalid to the firmware.
LOST_PULSE_US = 0
#: The FAILSAFE mode's switch for ``rc_loss`` with ``method = "switch"``: AUX3.
FAILSAFE_SWITCH_AUX_INDEX = 2
#: ``mode_switch``: each mode on its own AUX channel (AUX1 arms, AUX2 is ANGLE, AUX3 the
#: FAILSAFE switch), so switches combine: mode -> (the permanent box ids it raises, AUX
#: index).  POSHOLD raises ALTHOLD with it, as a pilot's hold switch does: POSHOLD alone
#: holds the position and leaves the height to the throttle.
MODE_SWITCHES: dict[str, tuple[tuple[int, ...], int]] = {
    "ALTHOLD": ((int(BoxId.ALTHOLD),), 3),
    "POSHOLD": ((int(BoxId.POSHOLD), int(BoxId.ALTHOLD)), 4),
    "GPS RESCUE": ((int(BoxId.GPSRESCUE),), 5),
    "AUTOPILOT": ((AUTOPILOT_BOX_ID,), 6),
}
#: The build feature (bfsitl.build.binary_scan) a mode needs beyond GPS.
MODE_FEATURES = {
    "AUTOPILOT": "flight_plan",
    "GPS RESCUE": "gps_rescue",
    "ALTHOLD": "altitude_hold",
    "POSHOLD": "position_hold",
}
#: ISA sea level: the pressure falls this much per metre of climb (rho g).
PA_PER_M = 12.01
RC_LOSS_METHODS = ("auto", "silence", "invalid_pulses", "switch")


#: Undoes an injected fault.
Undo = Callable[[], None]
#: Injects a fault into a started vehicle, through its disturbance surface or its sticks.
Inject = Callable[["Vehicle"], Undo]


@dataclass(frozen=True, slots=True)
class FaultSpec:
    """One ``[[fault]]`` table, checked when the file is read (:func:`read_fault_spec`): its
    kind, when, for how long, and its own parameters with their defaults filled in."""

    kind: str
    at_s: float
    #: None: it lasts to the end of the run.
    duration_s: float | None
    params: tuple[tuple[str, Any], ...]
    #: "fault 2" in messages.
    label: str

    def param(self, key: str, default: Any = None) -> Any:
        return dict(self.params).get(key, default)


@dataclass(frozen=True, slots=True)
class Fault:
    """One fault of a scenario, made for one firmware, ready to be injected."""

    spec: FaultSpec
    #: What it is, for events and reports ("RC lost (invalid pulses)").
    title: str
    #: The autopilot's sticks no longer reach the FC: the runner stops flying and watches.
    takes_sticks: bool
    _inject: Inject
    #: The mode switches it works through, each (permanent box id, AUX index), which the
    #: run provisions (the FAILSAFE switch on AUX3, a ``mode_switch``'s modes).
    switches: tuple[tuple[int, int], ...] = ()
    #: A build feature it needs (``flight_plan``: the binary is scanned before the run).
    needs_feature: str | None = None

    def apply(self, vehicle: Vehicle) -> Undo:
        """Inject it; returns what undoes it."""
        return self._inject(vehicle)


def _rc_loss(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    method = spec.param("method")
    silence_detected = profile.rc.rxloss_after_silence_s is not None
    if method == "auto":
        # Where silence is not detected, invalid pulses are no steady loss either: the SITL
        # receiver still reports whole frames, so in stage 2 the firmware counts them as
        # valid data and recovers after failsafe_recovery_delay, then loses the link again
        # (measured on both generations: LANDING and IDLE alternate).  The FAILSAFE switch in
        # its default STAGE1 mode is the firmware's own "link lost" input, and holds.
        method = "silence" if silence_detected else "switch"
    if method == "silence" and not silence_detected:
        raise FaultNotSupportedError(
            f"{where}: rc_loss by silence cannot happen on {_name(profile)}: it holds the last "
            f"sticks forever when RC stops (its SITL receiver never times out; a lockstep "
            f"build from `bfsitl firmware build --lockstep` does). Use method = "
            f'"switch" or "invalid_pulses" ("auto" picks the switch there)'
        )
    if method == "switch":
        # The pilot's own failsafe switch: the vehicle's sticks, not a disturbance.
        def apply_switch(vehicle: Vehicle) -> Undo:
            vehicle.set_rc(vehicle.rc_command.with_aux(FAILSAFE_SWITCH_AUX_INDEX, SWITCH_ON_US))
            return lambda: vehicle.set_rc(
                vehicle.rc_command.with_aux(FAILSAFE_SWITCH_AUX_INDEX, SWITCH_OFF_US)
            )

        return Fault(
            spec,
            "RC lost (failsafe switch on AUX3)",
            True,
            apply_switch,
            switches=((int(BoxId.FAILSAFE), FAILSAFE_SWITCH_AUX_INDEX),),
        )
    rc_fault = (
        RcFault(silent=True)
        if method == "silence"
        else RcFault(pulses_us=tuple((channel, LOST_PULSE_US) for channel in range(4)))
    )
    title = "RC lost (silence)" if method == "silence" else "RC lost (invalid pulses)"
    return Fault(spec, title, True, _rc_fault_injector(rc_fault))


def _rc_fault_injector(fault: RcFault) -> Inject:
    def inject(vehicle: Vehicle) -> Undo:
        disturbances = vehicle.disturbances
        disturbances.set_rc_fault(fault)
        return lambda: disturbances.set_rc_fault(None)

    return inject


def _rc_latency(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    delay_s, jitter_s = spec.param("delay_s"), spec.param("jitter_s")
    return Fault(
        spec,
        f"RC {delay_s * 1000:.0f} ms late (+{jitter_s * 1000:.0f} ms jitter)",
        False,
        _rc_fault_injector(RcFault(delay_s=delay_s, jitter_s=jitter_s)),
    )


def _gps_loss(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    _need_gps(profile, where, "gps_loss")
    if not profile.fdm.gps_loss_sentinel:
        raise FaultNotSupportedError(
            f"{where}: gps_loss cannot happen on {_name(profile)}: its virtual GPS keeps a "
            f"12-satellite fix whatever the simulator sends (no loss sentinel in its sitl.c). "
            f"gps_glitch works there; GPS loss runs on master"
        )

    def inject(vehicle: Vehicle) -> Undo:
        disturbances = vehicle.disturbances
        disturbances.set_gps_lost(True)
        return lambda: disturbances.set_gps_lost(False)

    return Fault(spec, "GPS lost", False, inject)


def _sensor_injector(fields: dict[str, Any]) -> Inject:
    """Sets sensor error ``fields``; undoing restores what they were (and only them)."""

    def inject(vehicle: Vehicle) -> Undo:
        disturbances = vehicle.disturbances
        before = disturbances.change_sensors(**fields)

        def undo() -> None:
            disturbances.change_sensors(**{key: getattr(before, key) for key in fields})

        return undo

    return inject


def _gps_glitch(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    _need_gps(profile, where, "gps_glitch")
    north, east = spec.param("north_m"), spec.param("east_m")
    return Fault(
        spec,
        f"GPS off by {north:g} m north, {east:g} m east",
        False,
        _sensor_injector({"gps_offset_ne_m": (north, east)}),
    )


def _motor_thrust(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    motor, fraction = spec.param("motor"), spec.param("fraction")

    def inject(vehicle: Vehicle) -> Undo:
        disturbances = vehicle.disturbances
        before = disturbances.motor_thrust[motor - 1]
        disturbances.set_motor_thrust(motor, fraction)
        return lambda: disturbances.set_motor_thrust(motor, before)

    return Fault(spec, f"motor {motor} at {fraction * 100:.0f} % thrust", False, inject)


def _gyro_noise(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    std = math.radians(spec.param("std_deg_s"))
    return Fault(
        spec,
        f"gyro noise {math.degrees(std):g} deg/s",
        False,
        _sensor_injector({"gyro_noise_std_rad_s": std}),
    )


def _gyro_bias(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    bias = tuple(math.radians(spec.param(f"{axis}_deg_s")) for axis in "xyz")
    shown = ", ".join(f"{math.degrees(b):g}" for b in bias)
    return Fault(
        spec, f"gyro bias ({shown}) deg/s", False, _sensor_injector({"gyro_bias_rad_s": bias})
    )


def _accel_noise(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    std = spec.param("std_m_s2")
    return Fault(
        spec,
        f"accelerometer noise {std:g} m/s^2",
        False,
        _sensor_injector({"accel_noise_std_m_s2": std}),
    )


def _accel_bias(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    bias = tuple(spec.param(f"{axis}_m_s2") for axis in "xyz")
    return Fault(
        spec, f"accelerometer bias {bias} m/s^2", False, _sensor_injector({"accel_bias_m_s2": bias})
    )


def _baro_drift(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    rate_m_s = spec.param("rate_m_s")
    return Fault(
        spec,
        f"barometer drifting {rate_m_s:+g} m/s",
        False,
        _sensor_injector({"baro_drift_pa_s": -rate_m_s * PA_PER_M}),
    )


def _wind(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    wind = Wind((spec.param("north_m_s"), spec.param("east_m_s"), 0.0), spec.param("gust_std_m_s"))

    def inject(vehicle: Vehicle) -> Undo:
        disturbances = vehicle.disturbances
        before = disturbances.wind
        disturbances.set_wind(wind)
        return lambda: disturbances.set_wind(before)

    north, east, _ = wind.velocity_ned_m_s
    return Fault(
        spec,
        f"wind to {north:g} m/s north, {east:g} m/s east (gusts {wind.gust_std_m_s:g} m/s)",
        False,
        inject,
    )


def _mode_switch(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    mode = spec.param("mode")
    if mode in ("GPS RESCUE", "AUTOPILOT", "POSHOLD"):
        _need_gps(profile, where, f"mode_switch {mode}")
    boxes, aux_index = MODE_SWITCHES[mode]

    def raise_switch(vehicle: Vehicle) -> Undo:
        # Letting go: roll, pitch and yaw centred; the throttle stays where the autopilot
        # held it, the hover, inside the altitude hold's deadband.
        held = vehicle.rc_command
        vehicle.set_rc(
            replace(held, roll_us=RC_MID_US, pitch_us=RC_MID_US, yaw_us=RC_MID_US).with_aux(
                aux_index, SWITCH_ON_US
            )
        )
        return lambda: vehicle.set_rc(vehicle.rc_command.with_aux(aux_index, SWITCH_OFF_US))

    return Fault(
        spec,
        f"{mode} switch on AUX{aux_index + 1}: the FC flies",
        True,
        raise_switch,
        switches=tuple((box, aux_index) for box in boxes),
        needs_feature=MODE_FEATURES[mode],
    )


_KINDS: dict[str, Callable[[FaultSpec, FirmwareProfile, str], Fault]] = {
    "rc_loss": _rc_loss,
    "rc_latency": _rc_latency,
    "gps_loss": _gps_loss,
    "gps_glitch": _gps_glitch,
    "motor_thrust": _motor_thrust,
    "gyro_noise": _gyro_noise,
    "gyro_bias": _gyro_bias,
    "accel_noise": _accel_noise,
    "accel_bias": _accel_bias,
    "baro_drift": _baro_drift,
    "wind": _wind,
    "mode_switch": _mode_switch,
}


@dataclass(frozen=True, slots=True)
class _Number:
    """A number parameter in ``low..high``; without a default it must be given."""

    low: float
    high: float
    default: float | None = None


_WIND = MAX_WIND_COMPONENT_M_S
#: Each kind's own parameters (beyond kind, at_s, duration_s), checked when the file is read.
_PARAMS: dict[str, Mapping[str, _Number | tuple[str, ...] | type[int]]] = {
    "rc_loss": {"method": RC_LOSS_METHODS},
    "rc_latency": {"delay_s": _Number(0.0, 2.0), "jitter_s": _Number(0.0, 2.0, 0.0)},
    "gps_loss": {},
    "gps_glitch": {
        "north_m": _Number(-1000.0, 1000.0, 0.0),
        "east_m": _Number(-1000.0, 1000.0, 0.0),
    },
    "motor_thrust": {"motor": int, "fraction": _Number(0.0, 1.0)},
    "gyro_noise": {"std_deg_s": _Number(0.0, 1000.0)},
    "gyro_bias": {f"{axis}_deg_s": _Number(-1000.0, 1000.0, 0.0) for axis in "xyz"},
    "accel_noise": {"std_m_s2": _Number(0.0, 100.0)},
    "accel_bias": {f"{axis}_m_s2": _Number(-50.0, 50.0, 0.0) for axis in "xyz"},
    "baro_drift": {"rate_m_s": _Number(-10.0, 10.0)},
    "wind": {
        "north_m_s": _Number(-_WIND, _WIND, 0.0),
        "east_m_s": _Number(-_WIND, _WIND, 0.0),
        "gust_std_m_s": _Number(0.0, MAX_GUST_STD_M_S, 0.0),
    },
    # No default: the first word would be one, and a mode must be named.
    "mode_switch": {"mode": ("", *MODE_SWITCHES)},
}
FAULT_KINDS = tuple(sorted(_KINDS))
#: Keys every fault table has besides its kind's own.
_COMMON_KEYS = ("kind", "at_s", "duration_s")
MAX_FAULT_DURATION_S = 3600.0


def read_fault_spec(raw: Any, *, where: str, number: int, run_s: float) -> FaultSpec:
    """One ``[[fault]]`` table, checked once, when the file is read: its kind, its times
    (``at_s`` within the run of ``run_s``) and its parameters, defaults filled in."""
    label = f"fault {number}"
    here = f"{where}, {label}"
    if not isinstance(raw, dict):
        raise ScenarioError(f"{here}: faults are written as [[fault]] tables")
    for key in ("kind", "at_s"):
        if key not in raw:
            raise ScenarioError(f"{here}: {key} is missing")
    kind = raw["kind"]
    if not isinstance(kind, str):
        raise ScenarioError(f"{here}: kind must be a string, got {kind!r}")
    if kind not in _KINDS:
        raise ScenarioError(f"{here}: unknown fault kind {kind!r}; known: {', '.join(FAULT_KINDS)}")
    at_s = number_in(where, f"{label} at_s", raw["at_s"], 0.0, run_s)
    lasts = raw.get("duration_s")
    if lasts is not None:
        lasts = number_in(where, f"{label} duration_s", lasts, 0.0, MAX_FAULT_DURATION_S)
    given = {key: value for key, value in raw.items() if key not in _COMMON_KEYS}
    schema = _PARAMS[kind]
    unknown = set(given) - set(schema)
    if unknown:
        raise ScenarioError(
            f"{here}: {kind} has no parameter(s) "
            f"{', '.join(sorted(unknown))}; it takes "
            f"{', '.join(sorted(schema)) or 'none'}"
        )
    params = {key: _param(here, kind, key, rule, given.get(key)) for key, rule in schema.items()}
    return FaultSpec(kind, at_s, lasts, tuple(sorted(params.items())), label)


def _param(
    here: str, kind: str, key: str, rule: _Number | tuple[str, ...] | type[int], value: Any
) -> Any:
    if isinstance(rule, tuple):  # one of some words; the first is the default ("": none)
        words = [word for word in rule if word]
        if value is None and not rule[0]:
            raise ScenarioError(f"{here}: {kind} needs {key}: one of {', '.join(words)}")
        value = rule[0] if value is None else value
        if value not in words:
            raise ScenarioError(f"{here}: {kind} {key} {value!r} is not one of {', '.join(words)}")
        return value
    if rule is int:  # a motor number, Betaflight's numbering
        if value not in (1, 2, 3, 4) or isinstance(value, bool):
            raise ScenarioError(
                f"{here}: {kind} needs {key} = 1..4 (Betaflight's numbering), got {value!r}"
            )
        return value
    assert isinstance(rule, _Number)
    if value is None:
        if rule.default is None:
            raise ScenarioError(f"{here}: {kind} needs {key}")
        return rule.default
    return number_in(here, f"{kind} {key}", value, rule.low, rule.high)


def make_fault(spec: FaultSpec, profile: FirmwareProfile, *, where: str = "scenario") -> Fault:
    """The fault ``spec`` describes, made for a firmware of ``profile`` (once per run);
    raises :class:`FaultNotSupportedError` when that firmware cannot express it."""
    return _KINDS[spec.kind](spec, profile, f"{where}, {spec.label}")


def make_faults(
    specs: tuple[FaultSpec, ...], profile: FirmwareProfile, *, where: str = "scenario"
) -> tuple[Fault, ...]:
    return tuple(make_fault(spec, profile, where=where) for spec in specs)


# -- helpers -------------------------------------------------------------------------------------
def _name(profile: FirmwareProfile) -> str:
    return f"Betaflight {profile.firmware_version or profile.generation.value}"


def _need_gps(profile: FirmwareProfile, where: str, kind: str) -> None:
    if not profile.has_gps:
        raise FaultNotSupportedError(
            f"{where}: {kind} needs a firmware with GPS (`bfsitl "
            f"firmware build --gps`; master has it)"
        )
