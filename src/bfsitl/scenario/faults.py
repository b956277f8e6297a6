"""The fault catalog: what a ``[[fault]]`` table can inject, and on which firmware.

Each fault acts where the real thing would: on the RC link (what reaches the FC's receiver),
in the physics (a weak motor, the wind), or in the sensors the physics reports (noise, bias,
drift, the GPS).  The firmware sees nothing of bfsitl; it sees a receiver, a motor, a sensor.

========================  ==========================================  =====================
kind (parameters)          what the FC sees                             firmware
========================  ==========================================  =====================
``rc_loss``               ``method``: ``silence`` (no RC at all),      silence: master
(``method = "auto"``)     ``invalid_pulses`` (roll, pitch, throttle,   (4.6.0 holds the last
                          yaw at 0 us: a receiver's lost-channel       sticks forever);
                          output; the AUX switches stay), ``switch``   invalid_pulses and
                          (the FAILSAFE mode on AUX3, as a pilot's     switch: every
                          failsafe switch); ``auto`` = silence where   firmware
                          the firmware detects it, else the switch
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
========================  ==========================================  =====================

Every fault may last ``duration_s`` (then it is undone: RC comes back, the motor recovers);
without it, it lasts to the end of the run.  A fault the firmware cannot express is refused
before the flight (:class:`~bfsitl.errors.FaultNotSupportedError`), never silently passed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from bfsitl.errors import FaultNotSupportedError, ScenarioError
from bfsitl.fc.rc_link import RcFault
from bfsitl.mission.vehicle import SWITCH_OFF_US, SWITCH_ON_US
from bfsitl.physics.wind import MAX_GUST_STD_M_S, MAX_WIND_COMPONENT_M_S, Wind
from bfsitl.protocol.firmware_profile import FirmwareProfile

if TYPE_CHECKING:
    from bfsitl.mission.session import FlightSession
    from bfsitl.scenario.spec import FaultSpec, Scenario

#: What invalid_pulses sends on roll, pitch, throttle and yaw: no pulse at all, as a receiver
#: reports a lost channel; anything below rx_min_usec (885 us) is invalid to the firmware.
LOST_PULSE_US = 0
#: The FAILSAFE mode's switch for ``rc_loss`` with ``method = "switch"``: AUX3.
FAILSAFE_SWITCH_AUX_INDEX = 2
#: ISA sea level: the pressure falls this much per metre of climb (rho g).
PA_PER_M = 12.01
RC_LOSS_METHODS = ("auto", "silence", "invalid_pulses", "switch")


@dataclass(frozen=True, slots=True)
class Fault:
    """One fault of a scenario, ready to be injected into a started session."""

    spec: FaultSpec
    #: What it is, for events and reports ("RC lost (invalid pulses)").
    title: str
    #: The autopilot's sticks no longer reach the FC: the runner stops flying and watches.
    takes_sticks: bool
    _apply: Callable[[FlightSession], Callable[[FlightSession], None]]
    #: It works through the FAILSAFE mode's switch (AUX3), which must be provisioned.
    needs_failsafe_switch: bool = False

    def apply(self, session: FlightSession) -> Callable[[FlightSession], None]:
        """Inject it; returns what undoes it."""
        return self._apply(session)


def _rc_loss(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    method = spec.param("method", "auto")
    if method not in RC_LOSS_METHODS:
        raise ScenarioError(f"{where}: rc_loss method {method!r} is not one of "
                            f"{', '.join(RC_LOSS_METHODS)}")
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
            f"sticks forever when RC stops (its SITL receiver never times out). Use method = "
            f"\"switch\" or \"invalid_pulses\" (\"auto\" picks the switch there)")
    if method == "switch":
        def apply_switch(session: FlightSession) -> Callable[[FlightSession], None]:
            session.set_rc(session.rc_command.with_aux(FAILSAFE_SWITCH_AUX_INDEX,
                                                       SWITCH_ON_US))

            def undo(s: FlightSession) -> None:
                s.set_rc(s.rc_command.with_aux(FAILSAFE_SWITCH_AUX_INDEX, SWITCH_OFF_US))
            return undo
        return Fault(spec, "RC lost (failsafe switch on AUX3)", True, apply_switch,
                     needs_failsafe_switch=True)
    rc_fault = RcFault(silent=True) if method == "silence" else RcFault(
        pulses_us=tuple((channel, LOST_PULSE_US) for channel in range(4)))
    title = "RC lost (silence)" if method == "silence" else "RC lost (invalid pulses)"
    return Fault(spec, title, True, lambda session: _set_rc_fault(session, rc_fault))


def _set_rc_fault(session: FlightSession, fault: RcFault) -> Callable[[FlightSession], None]:
    rc = session.rc
    if rc is None:
        raise ScenarioError("an RC fault needs bfsitl's RC link (the session has none)")
    rc.fault = fault

    def undo(s: FlightSession) -> None:
        if s.rc is not None:
            s.rc.fault = None
    return undo


def _rc_latency(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    delay_s = _param_number(spec, where, "delay_s", 0.0, 2.0)
    jitter_s = _param_number(spec, where, "jitter_s", 0.0, 2.0, default=0.0)
    rc_fault = RcFault(delay_s=delay_s, jitter_s=jitter_s)
    return Fault(spec, f"RC {delay_s * 1000:.0f} ms late (+{jitter_s * 1000:.0f} ms jitter)",
                 False, lambda session: _set_rc_fault(session, rc_fault))


def _gps_loss(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    _need_gps(profile, where, "gps_loss")
    if not profile.fdm.gps_loss_sentinel:
        raise FaultNotSupportedError(
            f"{where}: gps_loss cannot happen on {_name(profile)}: its virtual GPS keeps a "
            f"12-satellite fix whatever the simulator sends (no loss sentinel in its sitl.c). "
            f"gps_glitch works there; GPS loss runs on master")

    def apply(session: FlightSession) -> Callable[[FlightSession], None]:
        bridge = _bridge(session)
        bridge.encoder.gps_lost = True

        def undo(s: FlightSession) -> None:
            _bridge(s).encoder.gps_lost = False
        return undo
    return Fault(spec, "GPS lost", False, apply)


def _sensor_fault(fields: dict[str, Any]
                  ) -> Callable[[FlightSession], Callable[[FlightSession], None]]:
    """A fault that sets sensor error ``fields``; undoing restores what they were."""
    def apply(session: FlightSession) -> Callable[[FlightSession], None]:
        simulator = _simulator(session)
        before = simulator.sensor_config
        simulator.set_sensors(replace(before, **fields))

        def undo(s: FlightSession) -> None:
            sim = _simulator(s)
            sim.set_sensors(replace(sim.sensor_config,
                                    **{k: getattr(before, k) for k in fields}))
        return undo
    return apply


def _gps_glitch(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    _need_gps(profile, where, "gps_glitch")
    north = _param_number(spec, where, "north_m", -1000.0, 1000.0, default=0.0)
    east = _param_number(spec, where, "east_m", -1000.0, 1000.0, default=0.0)
    return Fault(spec, f"GPS off by {north:g} m north, {east:g} m east", False,
                 _sensor_fault({"gps_offset_ne_m": (north, east)}))


def _motor_thrust(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    motor = spec.param("motor")
    if motor not in (1, 2, 3, 4) or isinstance(motor, bool):
        raise ScenarioError(f"{where}: motor_thrust needs motor = 1..4 (Betaflight's "
                            f"numbering), got {motor!r}")
    fraction = _param_number(spec, where, "fraction", 0.0, 1.0)

    def apply(session: FlightSession) -> Callable[[FlightSession], None]:
        simulator = _simulator(session)
        before = simulator.motor_thrust[motor - 1]
        simulator.set_motor_thrust(motor, fraction)
        return lambda s: _simulator(s).set_motor_thrust(motor, before)
    return Fault(spec, f"motor {motor} at {fraction * 100:.0f} % thrust", False, apply)


def _gyro_noise(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    std = math.radians(_param_number(spec, where, "std_deg_s", 0.0, 1000.0))
    return Fault(spec, f"gyro noise {math.degrees(std):g} deg/s", False,
                 _sensor_fault({"gyro_noise_std_rad_s": std}))


def _gyro_bias(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    bias = tuple(math.radians(_param_number(spec, where, f"{axis}_deg_s", -1000.0, 1000.0,
                                            default=0.0)) for axis in "xyz")
    shown = ", ".join(f"{math.degrees(b):g}" for b in bias)
    return Fault(spec, f"gyro bias ({shown}) deg/s", False,
                 _sensor_fault({"gyro_bias_rad_s": bias}))


def _accel_noise(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    std = _param_number(spec, where, "std_m_s2", 0.0, 100.0)
    return Fault(spec, f"accelerometer noise {std:g} m/s^2", False,
                 _sensor_fault({"accel_noise_std_m_s2": std}))


def _accel_bias(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    bias = tuple(_param_number(spec, where, f"{axis}_m_s2", -50.0, 50.0, default=0.0)
                 for axis in "xyz")
    return Fault(spec, f"accelerometer bias {bias} m/s^2", False,
                 _sensor_fault({"accel_bias_m_s2": bias}))


def _baro_drift(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    rate_m_s = _param_number(spec, where, "rate_m_s", -10.0, 10.0)
    return Fault(spec, f"barometer drifting {rate_m_s:+g} m/s", False,
                 _sensor_fault({"baro_drift_pa_s": -rate_m_s * PA_PER_M}))


def _wind(spec: FaultSpec, profile: FirmwareProfile, where: str) -> Fault:
    most = MAX_WIND_COMPONENT_M_S
    wind = Wind((_param_number(spec, where, "north_m_s", -most, most, default=0.0),
                 _param_number(spec, where, "east_m_s", -most, most, default=0.0), 0.0),
                _param_number(spec, where, "gust_std_m_s", 0.0, MAX_GUST_STD_M_S, default=0.0))

    def apply(session: FlightSession) -> Callable[[FlightSession], None]:
        simulator = _simulator(session)
        before = simulator.wind
        simulator.set_wind(wind)
        return lambda s: _simulator(s).set_wind(before)
    north, east, _ = wind.velocity_ned_m_s
    return Fault(spec, f"wind to {north:g} m/s north, {east:g} m/s east "
                       f"(gusts {wind.gust_std_m_s:g} m/s)", False, apply)


_KINDS: dict[str, Callable[[FaultSpec, FirmwareProfile, str], Fault]] = {
    "rc_loss": _rc_loss, "rc_latency": _rc_latency, "gps_loss": _gps_loss,
    "gps_glitch": _gps_glitch, "motor_thrust": _motor_thrust, "gyro_noise": _gyro_noise,
    "gyro_bias": _gyro_bias, "accel_noise": _accel_noise, "accel_bias": _accel_bias,
    "baro_drift": _baro_drift, "wind": _wind,
}
#: Each kind's own parameters (beyond kind, at_s, duration_s).
_PARAMS: dict[str, set[str]] = {
    "rc_loss": {"method"}, "rc_latency": {"delay_s", "jitter_s"}, "gps_loss": set(),
    "gps_glitch": {"north_m", "east_m"}, "motor_thrust": {"motor", "fraction"},
    "gyro_noise": {"std_deg_s"}, "gyro_bias": {"x_deg_s", "y_deg_s", "z_deg_s"},
    "accel_noise": {"std_m_s2"}, "accel_bias": {"x_m_s2", "y_m_s2", "z_m_s2"},
    "baro_drift": {"rate_m_s"}, "wind": {"north_m_s", "east_m_s", "gust_std_m_s"},
}
FAULT_KINDS = tuple(sorted(_KINDS))


def make_fault(spec: FaultSpec, profile: FirmwareProfile, *, where: str = "scenario") -> Fault:
    """The fault ``spec`` describes, for a firmware of ``profile``; raises
    :class:`FaultNotSupportedError` when that firmware cannot express it."""
    here = f"{where}, {spec.label}"
    builder = _KINDS.get(spec.kind)
    if builder is None:
        raise ScenarioError(f"{here}: unknown fault kind {spec.kind!r}; known: "
                            f"{', '.join(FAULT_KINDS)}")
    unknown = {key for key, _ in spec.params} - _PARAMS[spec.kind]
    if unknown:
        raise ScenarioError(f"{here}: {spec.kind} has no parameter(s) "
                            f"{', '.join(sorted(unknown))}; it takes "
                            f"{', '.join(sorted(_PARAMS[spec.kind])) or 'none'}")
    return builder(spec, profile, here)


def make_faults(scenario: Scenario, profile: FirmwareProfile) -> tuple[Fault, ...]:
    return tuple(make_fault(spec, profile, where=scenario.where) for spec in scenario.faults)


def check_faults(scenario: Scenario) -> None:
    """Refuse unknown kinds and bad parameters when the file is read (against master's
    profile, which can express every fault: what a firmware cannot do is found per run)."""
    from bfsitl.fc.firmware_detect import MASTER_API_VERSION
    from bfsitl.protocol.firmware_profile import profile_for

    master = profile_for(MASTER_API_VERSION)
    for spec in scenario.faults:
        try:
            make_fault(spec, master, where=scenario.where)
        except FaultNotSupportedError:
            pass




# -- helpers -------------------------------------------------------------------------------------
def _name(profile: FirmwareProfile) -> str:
    return f"Betaflight {profile.firmware_version or profile.generation.value}"


def _need_gps(profile: FirmwareProfile, where: str, kind: str) -> None:
    if not profile.has_gps:
        raise FaultNotSupportedError(f"{where}: {kind} needs a firmware with GPS (`bfsitl "
                                     f"firmware build --gps`; master has it)")


def _param_number(spec: FaultSpec, where: str, key: str, low: float, high: float,
                  default: float | None = None) -> float:
    value = spec.param(key, default)
    if value is None:
        raise ScenarioError(f"{where}: {spec.kind} needs {key}")
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value) or not low <= value <= high:
        raise ScenarioError(f"{where}: {spec.kind} {key} = {value!r} must be a number in "
                            f"{low:g}..{high:g}")
    return float(value)


def _simulator(session: FlightSession) -> Any:
    if session.simulator is None:
        raise ScenarioError("this fault acts in bfsitl's embedded physics (physics = embedded)")
    return session.simulator


def _bridge(session: FlightSession) -> Any:
    if session.bridge is None:
        raise ScenarioError("this fault acts in bfsitl's embedded physics (physics = embedded)")
    return session.bridge
