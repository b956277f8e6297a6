"""An offline closed loop for altitude controllers: the embedded physics plus a model of the FC.

Fast enough for unit tests (a 15 s flight takes about 0.1 s) and close enough to the real
4.6.0 SITL to tune against; the real SITL remains the proof (``benchmarks/altitude.py``).
What is modelled, each from the firmware source:

* **RC -> motors** (``fc/rc.c``, ``flight/mixer.c``, ``drivers/pwm_output.c``, ``sitl.c``):
  the throttle channel is constrained to ``min_check`` (1050) .. 2000 and scaled to 0..1; the
  mixer adds throttle boost (0.5 x a 15 Hz high-pass); the motor range is
  ``1000 + motor_idle 5.5 %`` .. 2000 us and the SITL sends ``(pwm - 1000) / 1000``, so a motor
  command is ``0.055 + 0.945 x throttle``.  All four motors get the same command (sticks centred,
  ANGLE mode keeps the vehicle level), so only the vertical axis moves.  RC arrives every 10 ms
  (the UDP link's rate) and is smoothed by a first-order lag standing in for RC smoothing.
* **Altitude** (``sensors/barometer.c``, ``flight/position.c``): the pressure is truncated to
  whole Pa (``sitl.c``: ``(int32)pressure``, ~8.3 cm), turned into centimetres with
  Betaflight's formula, sampled by the BARO task, zeroed at arming against the ground reading,
  and filtered by the ALTITUDE task's PT2 (3 Hz designed for 100 Hz; the SITL runs that task
  slower, which lowers the cut-off in time).  The mission reads it over MSP a little late and
  derives the climb rate with the mission's own estimator.  Task rate and delay were fitted to
  a real flight: replaying its true altitude through this model reproduced the FC's altitude
  to 8 mm RMS (task 35-40 Hz); the FC then lags the truth by about 0.2 s.
* **The mission loop**: 40 Hz of simulation time with +-12 ms of jitter (seeded), as the
  real runner managed against the SITL (its MSP round trip limits it; 8 to 56 ms measured),
  rows recorded like the runner's (time, truth, FC altitude, throttle, target, phase).
"""

from __future__ import annotations

import math
import random
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from bfsitl.control.base import AltitudeController, AltitudeInput
from bfsitl.mission.climb_rate import ClimbRateEstimator
from bfsitl.physics import IRIS, GeoPoint, QuadParams, SensorConfig, Simulator

#: Betaflight's pt2FilterGain shifts the cut-off so two PT1 stages give -3 dB there.
_PT2_CUTOFF_CORRECTION = 1.553773974


@dataclass(frozen=True, slots=True)
class FcModel:
    """The flight controller between the RC throttle and the reported altitude."""

    min_check_us: float = 1050.0
    motor_low: float = 0.055  # (1000 + 550 x 0.1 - 1000) / 1000
    throttle_boost: float = 0.5  # throttle_boost 5 x 0.1
    throttle_boost_cutoff_hz: float = 15.0
    rc_period_s: float = 0.01  # UDP RC at 100 Hz
    rc_smoothing_tau_s: float = 0.015
    baro_rate_hz: float = 40.0
    altitude_task_rate_hz: float = 40.0  # fitted to a real 4.6.0 SITL flight (35-40 Hz)
    altitude_lpf_hz: float = 3.0  # altitude_lpf 300 / 100
    altitude_filter_dt_s: float = 0.01  # the filter gain assumes the nominal 100 Hz
    msp_delay_s: float = 0.03  # telemetry round trip at the mission rate
    acc_lpf_hz: float = 25.0  # acc_lpf_hz, a PT2 at the accelerometer's rate
    acc_1g_lsb: float = 256.0  # the SITL's scale (MSP_RAW_IMU is rounded to LSB)
    #: The real SITL hovered at 1541.5 us where the formula above gives 1539.3: some offset in
    #: the throttle path that the formula misses, taken as a constant.
    rc_offset_us: float = -2.2

    def motor_command(self, throttle_us: float) -> float:
        """Steady motor command for an RC throttle (no boost)."""
        throttle = min(
            1.0, max(0.0, (throttle_us - self.min_check_us) / (2000.0 - self.min_check_us))
        )
        return self.motor_low + (1.0 - self.motor_low) * throttle

    def hover_throttle_us(self, hover_command: float) -> float:
        throttle = (hover_command - self.motor_low) / (1.0 - self.motor_low)
        return self.min_check_us + throttle * (2000.0 - self.min_check_us) - self.rc_offset_us


def betaflight_altitude_cm(pressure_pa: float) -> float:
    """``pressureToAltitude`` of ``sensors/barometer.c``."""
    return (1.0 - (pressure_pa / 101325.0) ** 0.190295) * 4433000.0


@dataclass
class Trace:
    """One row per control step, like the mission runner's flight rows."""

    time_s: list[float] = field(default_factory=list)
    phase: list[str] = field(default_factory=list)
    target_alt_m: list[float] = field(default_factory=list)
    true_alt_m: list[float] = field(default_factory=list)
    true_climb_m_s: list[float] = field(default_factory=list)
    fc_alt_m: list[float] = field(default_factory=list)
    climb_m_s: list[float] = field(default_factory=list)
    throttle_us: list[float] = field(default_factory=list)
    on_ground: list[bool] = field(default_factory=list)

    def select(self, *phases: str) -> Trace:
        """The rows of some phases only."""
        out = Trace()
        for i, phase in enumerate(self.phase):
            if phase in phases:
                for name in self.__dataclass_fields__:
                    getattr(out, name).append(getattr(self, name)[i])
        return out


class AltitudePlant:
    """The vehicle on the ground and armed; fly phases one after the other."""

    def __init__(
        self,
        fc: FcModel | None = None,
        *,
        physics_step_s: float = 0.002,
        control_rate_hz: float = 40.0,
        control_jitter_s: float = 0.012,
        home_alt_m: float = 0.0,
        hover_scale: float = 1.0,
        baro_noise_pa: float = 0.0,
        accel_noise_m_s2: float = 0.0,
        seed: int = 0,
        quad: QuadParams = IRIS,
    ) -> None:
        """``quad`` is the vehicle (IRIS by default); ``hover_scale`` multiplies every motor
        command (< 1: a heavier vehicle, whose hover throttle the controller does not know);
        ``baro_noise_pa`` and ``accel_noise_m_s2`` add white noise to the pressure and the
        acceleration the FC reads."""
        self.fc = fc or FcModel()
        self.sim = Simulator(
            quad,
            home=GeoPoint(0.0, 0.0, home_alt_m),
            seed=seed,
            sensors=SensorConfig(
                baro_noise_std_pa=baro_noise_pa, accel_noise_std_m_s2=accel_noise_m_s2
            ),
        )
        self.physics_step_s = physics_step_s
        self.control_period_s = 1.0 / control_rate_hz
        self.control_jitter_s = control_jitter_s
        self.hover_scale = hover_scale
        self._rng = random.Random(seed)
        self.trace = Trace()
        self.climb = ClimbRateEstimator()
        fc = self.fc
        # The FC zeroes the altitude at arming against a smoothed ground reading
        # (position.c: newBaroAltOffsetCm = 0.2 x reading + 0.8 x itself, every ALTITUDE task):
        # a short average, so with a noisy barometer every flight has its own zero error.
        self._ground_cm = self._smoothed_ground_cm(100 if baro_noise_pa > 0 else 1)
        self._ground_true_m = self.sim.altitude_m
        k = 2.0 * math.pi * fc.altitude_lpf_hz * _PT2_CUTOFF_CORRECTION * fc.altitude_filter_dt_s
        self._pt2_k = k / (k + 1.0)
        self._pt2 = [0.0, 0.0]
        self._baro_cm = 0.0
        self._history: deque[tuple[float, float]] = deque([(0.0, 0.0)])
        acc_k = 2.0 * math.pi * fc.acc_lpf_hz * _PT2_CUTOFF_CORRECTION * physics_step_s
        self._acc_k = acc_k / (acc_k + 1.0)
        self._acc = [fc.acc_1g_lsb, fc.acc_1g_lsb]
        self._acc_history: deque[tuple[float, float]] = deque([(0.0, fc.acc_1g_lsb)])
        self._next_baro_s = 0.0
        self._next_alt_s = 0.0
        self._next_rc_s = 0.0
        self._command_us = 1000.0  # what the mission asked for last
        self._rc_us = 1000.0  # what the FC has received
        self._smoothed = 0.0  # RC-smoothed throttle 0..1
        self._boost_lpf = 0.0
        boost_k = 2.0 * math.pi * fc.throttle_boost_cutoff_hz * physics_step_s
        self._boost_k = boost_k / (boost_k + 1.0)
        self._smooth_k = -math.expm1(-physics_step_s / fc.rc_smoothing_tau_s)

    def _smoothed_ground_cm(self, samples: int) -> float:
        """The FC's ground reference: ``samples`` readings (vehicle parked, one per altitude
        task), exponentially smoothed like position.c's."""
        smoothed: float | None = None
        per_task = max(1, round(1.0 / (self.fc.altitude_task_rate_hz * self.physics_step_s)))
        for _ in range(samples):
            reading = betaflight_altitude_cm(int(self.sim.read_sensors().pressure_pa))
            smoothed = reading if smoothed is None else 0.2 * reading + 0.8 * smoothed
            if samples > 1:
                for _ in range(per_task):
                    self.sim.step((0.0, 0.0, 0.0, 0.0), self.physics_step_s)
        assert smoothed is not None
        return smoothed

    @property
    def time_s(self) -> float:
        return self.sim.time_s

    @property
    def true_alt_m(self) -> float:
        return self.sim.altitude_m - self._ground_true_m

    @property
    def hover_throttle_us(self) -> float:
        """The throttle that holds this vehicle (to check controllers against, not to use)."""
        return self.fc.hover_throttle_us(self.sim.params.hover_command / self.hover_scale)

    # -- the FC ------------------------------------------------------------------------------
    def _fc_tick(self) -> None:
        t = self.sim.time_s
        fc = self.fc
        if t >= self._next_rc_s:
            self._rc_us = float(min(2000, max(1000, round(self._command_us)))) + fc.rc_offset_us
            self._next_rc_s += fc.rc_period_s
        if t >= self._next_baro_s:
            pressure = int(self.sim.read_sensors().pressure_pa)
            self._baro_cm = betaflight_altitude_cm(pressure) - self._ground_cm
            self._next_baro_s += 1.0 / fc.baro_rate_hz
        # The accelerometer: body z specific force (up, the vehicle stays level) in LSB,
        # PT2-filtered at the sensor's rate.
        force_up = -self.sim.read_sensors().specific_force_frd_m_s2[2]
        acc = self._acc
        # sitl.c hands the FC int16 values made by truncation (half an LSB low on average).
        acc[0] += self._acc_k * (int(force_up / 9.80665 * fc.acc_1g_lsb) - acc[0])
        acc[1] += self._acc_k * (acc[0] - acc[1])
        self._acc_history.append((t, acc[1]))
        if t >= self._next_alt_s:
            k, state = self._pt2_k, self._pt2
            state[0] += k * (self._baro_cm - state[0])
            state[1] += k * (state[0] - state[1])
            self._history.append((t, state[1] / 100.0))
            self._next_alt_s += 1.0 / fc.altitude_task_rate_hz

    def _motor(self) -> float:
        fc = self.fc
        throttle = min(1.0, max(0.0, (self._rc_us - fc.min_check_us) / (2000.0 - fc.min_check_us)))
        self._smoothed += self._smooth_k * (throttle - self._smoothed)
        self._boost_lpf += self._boost_k * (self._smoothed - self._boost_lpf)
        boosted = self._smoothed + fc.throttle_boost * (self._smoothed - self._boost_lpf)
        boosted = min(1.0, max(0.0, boosted))
        return (fc.motor_low + (1.0 - fc.motor_low) * boosted) * self.hover_scale

    def fc_alt_m(self) -> float:
        """What MSP_ALTITUDE reports now: the altitude task's output ``msp_delay_s`` ago, in
        whole centimetres (``lrintf``)."""
        seen_at = self.sim.time_s - self.fc.msp_delay_s
        history = self._history
        while len(history) > 1 and history[1][0] <= seen_at:
            history.popleft()
        return round(history[0][1] * 100.0) / 100.0

    def fc_accel_up_m_s2(self) -> float:
        """What MSP_RAW_IMU's z (whole LSB) says, ``msp_delay_s`` ago, gravity removed, with
        the half LSB the SITL's truncation takes put back (as the flight session does)."""
        seen_at = self.sim.time_s - self.fc.msp_delay_s
        history = self._acc_history
        while len(history) > 1 and history[1][0] <= seen_at:
            history.popleft()
        return (round(history[0][1]) + 0.5) / self.fc.acc_1g_lsb * 9.80665 - 9.80665

    def _advance_to(self, time_s: float) -> None:
        while self.sim.time_s < time_s - 1e-9:
            self._fc_tick()
            u = self._motor()
            self.sim.step((u, u, u, u), self.physics_step_s)

    # -- the mission -------------------------------------------------------------------------
    def fly(
        self,
        controller: AltitudeController,
        *,
        target_alt_m: float | Callable[[float], float],
        duration_s: float,
        phase: str = "fly",
        reset: bool = True,
        until: Callable[[], bool] | None = None,
        ground_s: float = 0.0,
    ) -> Trace:
        """Run the mission loop for ``duration_s`` (or until ``until()``), rows into ``trace``.

        ``target_alt_m`` may be a function of the time since the phase began.  ``ground_s``:
        first sit armed at idle that long, like the mission's ground phase (the samples go to
        the controller's ``observe_ground`` if it has one; no rows are recorded).
        """
        if reset:
            controller.reset(self.sim.time_s)
        if ground_s > 0:
            self._ground_phase(controller, ground_s)
        start_s = self.sim.time_s
        next_s = start_s
        while self.sim.time_s < start_s + duration_s:
            self._advance_to(next_s)
            t = self.sim.time_s
            fc_alt = self.fc_alt_m()
            climb = self.climb.update(t, fc_alt)
            target = target_alt_m(t - start_s) if callable(target_alt_m) else target_alt_m
            throttle = controller.update(
                AltitudeInput(t, fc_alt, climb, target, self.fc_accel_up_m_s2())
            )
            if not math.isfinite(throttle):
                raise AssertionError(f"{controller.name} returned {throttle}")
            self._command_us = throttle
            trace = self.trace
            trace.time_s.append(t)
            trace.phase.append(phase)
            trace.target_alt_m.append(target)
            trace.true_alt_m.append(self.true_alt_m)
            trace.true_climb_m_s.append(-self.sim.state.velocity_ned_m_s[2])
            trace.fc_alt_m.append(fc_alt)
            trace.climb_m_s.append(climb)
            trace.throttle_us.append(throttle)
            trace.on_ground.append(self.sim.on_ground)
            if until is not None and until():
                break
            jitter = self._rng.uniform(-1.0, 1.0) * self.control_jitter_s
            next_s += self.control_period_s + jitter
            # Never step backwards or stand still: the mission clock strictly increases.
            next_s = max(next_s, self.sim.time_s + self.physics_step_s)
        return self.trace

    def _ground_phase(self, controller: AltitudeController, ground_s: float) -> None:
        observe = getattr(controller, "observe_ground", None)
        self._command_us = 1000.0
        end_s = self.sim.time_s + ground_s
        next_s = self.sim.time_s
        while self.sim.time_s < end_s:
            self._advance_to(next_s)
            if observe is not None:
                t = self.sim.time_s
                observe(AltitudeInput(t, self.fc_alt_m(), 0.0, 0.0, self.fc_accel_up_m_s2()))
            next_s += self.control_period_s
            next_s = max(next_s, self.sim.time_s + self.physics_step_s)
        if observe is None:
            controller.reset(self.sim.time_s)  # as the mission does: it saw nothing


class HandPilot:
    """A pilot with the throttle, as the mission's ``fly_sticks`` hands it over: up 40 us from
    the hover, down 40, back; the controller ``watcher`` sees each step through its
    ``observe_flight`` when given (as the mission does), else nothing of it."""

    name = "hand"

    def __init__(self, hover_us: float, watcher: Any = None) -> None:
        self.hover_us, self.watcher, self.steps = hover_us, watcher, 0

    def reset(self, time_s: float) -> None:
        pass

    def update(self, sample: AltitudeInput) -> float:
        self.steps += 1
        throttle = self.hover_us + (40.0 if self.steps < 100 else -40.0 if self.steps < 200 else 0)
        if self.watcher is not None:
            self.watcher.observe_flight(sample, throttle)
        return throttle


def hand_back_sag_m(make_controller: Callable[[], Any], *, watched: bool) -> float:
    """Hold 2 m, let the hand pilot fly 8 s, take the sticks back to hold where it left the
    quad: the largest distance from there over the next 6 s (truth), with the mission's
    sensor noise and ground phase."""
    from bfsitl.backend.options import DEFAULT_ACCEL_NOISE_M_S2, DEFAULT_BARO_NOISE_PA
    from bfsitl.mission.plan import MissionPlan

    controller = make_controller()
    plant = AltitudePlant(
        baro_noise_pa=DEFAULT_BARO_NOISE_PA, accel_noise_m_s2=DEFAULT_ACCEL_NOISE_M_S2
    )
    plant.fly(controller, target_alt_m=2.0, duration_s=10.0, ground_s=MissionPlan().ground_s)
    pilot = HandPilot(round(controller.hover_throttle_us), controller if watched else None)
    plant.fly(pilot, target_alt_m=2.0, duration_s=8.0, reset=False, phase="hand")
    left_at_m = plant.true_alt_m
    trace = plant.fly(
        controller, target_alt_m=plant.fc_alt_m(), duration_s=6.0, reset=False, phase="back"
    )
    return max(abs(alt - left_at_m) for alt in trace.select("back").true_alt_m)
