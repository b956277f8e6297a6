"""The accelerometer + barometer estimator and the fused controller, on the rig and alone.

The rig (tests/support/altitude_plant.py) gives the controller what the real SITL's MSP gives:
the barometric altitude (whole pascals, the firmware's PT2, ~0.2 s late) and the accelerometer
(MSP_RAW_IMU z, 256 LSB per g, 25 Hz PT2).  Real-SITL figures: benchmarks/altitude.py.
"""

from __future__ import annotations

import math

import pytest
from support.altitude_plant import AltitudePlant, FcModel, hand_back_sag_m

from bfsitl.backend.options import DEFAULT_ACCEL_NOISE_M_S2, DEFAULT_BARO_NOISE_PA
from bfsitl.control.altitude_estimator import AltitudeEstimator
from bfsitl.control.base import AltitudeInput
from bfsitl.control.cascade import SensorLag
from bfsitl.control.fused import FusedAltitudeController, FusedGains
from bfsitl.control.metrics import step_response
from bfsitl.control.tutorial import TutorialPid
from bfsitl.errors import ControllerConfigError
from bfsitl.mission.plan import MissionPlan

TARGET_M = 2.0


def fly(controller, duration_s: float = 12.0, **plant_kwargs):
    """As `bfsitl fly` flies: its sensor noise, its ground phase before the take-off."""
    plant_kwargs.setdefault("baro_noise_pa", DEFAULT_BARO_NOISE_PA)
    plant_kwargs.setdefault("accel_noise_m_s2", DEFAULT_ACCEL_NOISE_M_S2)
    plant = AltitudePlant(**plant_kwargs)
    trace = plant.fly(
        controller, target_alt_m=TARGET_M, duration_s=duration_s, ground_s=MissionPlan().ground_s
    )
    return plant, trace, step_response(trace.time_s, trace.true_alt_m, target_m=TARGET_M)


# -- the estimator ------------------------------------------------------------------------------


def simulate_estimator(
    estimator, accel_of_t, duration_s=4.0, dt_s=0.025, lag_s=0.2, baro_offset_m=0.0
):
    """A vehicle with a known acceleration; the barometer is the truth through ``lag_s``."""
    baro = SensorLag(lag_s)
    alt = climb = 0.0
    worst_m = 0.0
    previous = accel_of_t(0.0)
    for step in range(1, round(duration_s / dt_s) + 1):
        # The truth integrates the acceleration linearly between samples, as samples of a
        # continuous signal are.
        a = accel_of_t(step * dt_s)
        mean = 0.5 * (previous + a)
        previous = a
        alt += (climb + 0.5 * mean * dt_s) * dt_s
        climb += mean * dt_s
        seen = baro.step(alt, dt_s) + baro_offset_m
        est = estimator.update(dt_s, a, seen)
        worst_m = max(worst_m, abs(est.alt_m - alt))
    return alt, climb, est, worst_m


def test_estimate_is_on_time_while_the_barometer_lags():
    """One sine period of acceleration (up 1.27 m in 2 s, 1.3 m/s at the fastest): the
    barometer trails by 0.2 s (up to 0.25 m), the estimate stays within a centimetre."""
    est = AltitudeEstimator(lag_s=0.2, accel_delay_s=0.0)
    alt, climb, final, worst = simulate_estimator(
        est, lambda t: 2.0 * math.sin(math.pi * t) if t <= 2.0 else 0.0, lag_s=0.2
    )
    assert alt == pytest.approx(4.0 / math.pi, abs=0.01) and abs(climb) < 0.01
    assert worst < 0.01
    assert final.alt_m == pytest.approx(alt, abs=0.01)


def test_the_barometer_corrects_a_wrong_start_and_an_accelerometer_bias():
    est = AltitudeEstimator(lag_s=0.2, accel_delay_s=0.0, bandwidth_rad_s=1.0)
    est.reset(alt_m=0.5)  # wrong by half a metre
    bias = 0.2  # m/s^2 of accelerometer error, hovering still
    baro = SensorLag(0.2)
    for _ in range(int(20.0 / 0.025)):
        final = est.update(0.025, 0.0 + bias, baro.step(0.0, 0.025))
    assert abs(final.alt_m) < 0.01 and abs(final.climb_m_s) < 0.01
    assert final.accel_bias_m_s2 == pytest.approx(bias, abs=0.01)


def test_on_the_ground_it_cannot_sink_and_learns_no_bias():
    est = AltitudeEstimator()
    for _ in range(100):
        final = est.update(0.02, -0.5, 0.0, on_ground=True)
    assert final.climb_m_s >= 0.0 and final.accel_bias_m_s2 == 0.0


def test_estimator_rejects_bad_settings_and_ignores_a_zero_step():
    with pytest.raises(ValueError):
        AltitudeEstimator(bandwidth_rad_s=0.0)
    est = AltitudeEstimator()
    before = est.estimate
    assert est.update(0.0, 5.0, 1.0) == before


# -- the controller on the rig ----------------------------------------------------------------


def test_step_and_hold_on_the_rig():
    controller = FusedAltitudeController()
    plant, trace, m = fly(controller)
    assert m.overshoot_pct < 5.0
    assert m.rise_time_s < 1.5
    assert m.settling_time_s < 4.0
    assert m.steady_state_rms_m < 0.03
    # The hover throttle learnt in flight (1541.5 us here, never told).
    assert abs(controller.hover_throttle_us - plant.hover_throttle_us) < 3.0


@pytest.mark.parametrize("hover_scale", [0.95, 1.05])
def test_a_heavier_or_lighter_vehicle_beats_the_tutorial(hover_scale):
    fused = FusedAltitudeController()
    plant, _, f = fly(fused, hover_scale=hover_scale)
    _, _, t = fly(TutorialPid(), hover_scale=hover_scale)
    assert f.settling_time_s < 4.0 and f.overshoot_pct < 5.0
    assert f.settling_time_s < t.settling_time_s
    assert f.steady_state_rms_m <= t.steady_state_rms_m
    assert abs(fused.hover_throttle_us - plant.hover_throttle_us) < 3.0


@pytest.mark.parametrize("task_hz", [30.0, 50.0])
def test_a_slower_or_faster_altitude_task_changes_little(task_hz):
    """The FC's lag moves with its ALTITUDE task rate; the estimator's model of it does not."""
    _, _, m = fly(FusedAltitudeController(), fc=FcModel(altitude_task_rate_hz=task_hz))
    assert m.overshoot_pct < 6.0 and m.settling_time_s < 5.5
    assert m.steady_state_rms_m < 0.04


# -- the controller alone ---------------------------------------------------------------------


def test_without_an_accelerometer_it_says_which_controllers_fly_without():
    c = FusedAltitudeController()
    c.reset(0.0)
    with pytest.raises(ControllerConfigError, match="cascade"):
        c.update(AltitudeInput(0.02, 0.0, 0.0, 2.0))


def test_spool_up_then_lift_off_from_the_accelerometer():
    g = FusedGains()
    c = FusedAltitudeController(g)
    c.reset(0.0)
    outs = [c.update(AltitudeInput(0.02 * i, 0.0, 0.0, 2.0, 0.0)) for i in range(1, 26)]
    assert outs[-1] == pytest.approx(g.hover_guess_us + g.spool_rate_us_s * 0.5, abs=1.0)
    assert all(o == math.floor(o) for o in outs) and not c.airborne
    # One sample of upward acceleration is not enough (noise); two are.
    c.update(AltitudeInput(0.52, 0.0, 0.0, 2.0, 1.0))
    assert not c.airborne
    c.update(AltitudeInput(0.54, 0.0, 0.0, 2.0, 1.0))
    assert c.airborne
    # Hover: the throttle the motors had, minus 1 m/s^2 worth of it.
    assert c.hover_throttle_us < outs[-1]


def test_nowhere_to_go_stays_at_idle():
    c = FusedAltitudeController()
    c.reset(0.0)
    assert c.update(AltitudeInput(0.02, 0.0, 0.0, 0.0, 0.0)) == 1000.0


def test_output_stays_within_the_throttle_limits():
    g = FusedGains()
    c = FusedAltitudeController(g)
    c.reset(0.0)
    c.update(AltitudeInput(0.02, 0.0, 0.0, 2.0, 1.0))
    c.update(AltitudeInput(0.04, 0.0, 0.0, 2.0, 1.0))
    for i in range(3, 200):  # the vehicle falls whatever is sent: the output saturates
        out = c.update(AltitudeInput(0.02 * i, -0.1 * i, -2.0, 50.0, -9.0))
        assert g.throttle_min_us <= out <= g.throttle_max_us
    assert g.hover_min_us <= c.hover_throttle_us <= g.hover_max_us


def test_a_repeated_sample_changes_nothing_and_reset_starts_over():
    c = FusedAltitudeController()
    c.reset(0.0)
    first = c.update(AltitudeInput(0.02, 0.0, 0.0, 2.0, 0.0))
    assert c.update(AltitudeInput(0.02, 0.0, 0.0, 2.0, 0.0)) == first
    c.reset(1.0)
    assert c.hover_throttle_us == FusedGains().hover_guess_us and not c.airborne


@pytest.mark.parametrize(
    "bad",
    [{"vel_kp": -1.0}, {"hover_learn_s": 0.0}, {"hover_min_us": 1700.0, "hover_max_us": 1600.0}],
)
def test_bad_gains_are_rejected(bad):
    with pytest.raises(ControllerConfigError):
        FusedGains(**bad)


def test_a_feedforward_lead_rises_sooner():
    """ff_lead_s takes the reference's acceleration from a little ahead (the thrust answers
    the throttle late): the climb is quicker, and with the default brisk reference it
    overshoots more (why it is off by default)."""
    _, _, plain = fly(FusedAltitudeController())
    _, _, led = fly(FusedAltitudeController(FusedGains(ff_lead_s=0.05)))
    assert led.rise_time_s < plain.rise_time_s
    assert led.overshoot_pct < 10.0


def test_a_long_gap_between_samples_is_integrated_in_full():
    """A stalled loop (0.3 s without a sample) while climbing at 2 m/s: the estimate moves
    the whole 0.6 m, not just the loop's step cap."""
    est = AltitudeEstimator(accel_delay_s=0.0)
    est.reset(alt_m=1.0, climb_m_s=2.0)
    moved = est.update(0.3, 0.0, 0.5).alt_m - 1.0
    assert moved == pytest.approx(0.6, abs=0.02)


def test_reference_copy_is_independent():
    from bfsitl.control.cascade import ReferenceProfile

    ref = ReferenceProfile(3.0, 1.0, 5.0, 3.0)
    ref.step(2.0, 0.1)
    twin = ref.copy()
    twin.step(2.0, 0.5)
    assert (ref.alt_m, ref.climb_m_s) != (twin.alt_m, twin.climb_m_s)
    assert twin.copy().alt_m == twin.alt_m


def test_after_another_pilot_the_sticks_come_back_without_a_sag():
    """While the pilot flies, the fused controller keeps its estimate, motors and reference
    on the vehicle (observe_flight); unwatched, its reference was left where the pilot took
    over and the hold that followed sagged towards it."""
    watched = hand_back_sag_m(FusedAltitudeController, watched=True)
    assert watched < 0.05
    # The rig tells the two apart.
    assert hand_back_sag_m(FusedAltitudeController, watched=False) > 2 * watched
