"""The flight loop against a fake vehicle: phases, outcomes, rows, the disarm on abort.

The fake vehicle is a point mass whose climb rate follows the throttle, with an FC altitude
that lags it; enough to drive every branch of the runner without a SITL.  The real flights
are in tests/integration/test_fly_sitl.py.
"""

from __future__ import annotations

from dataclasses import replace

import pytest
from support.fake_vehicles import (
    HOVER_US,
    Descend,
    FakeVehicle,
    PController,
    PlanarVehicle,
    planar_loop,
)

from bfsitl.errors import ArmingBlockedError, MissionError, SitlExitedError
from bfsitl.mission.flight_metrics import hold_stats
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.plan import MissionPlan
from bfsitl.mission.plan_driver import fly
from bfsitl.mission.results import Outcome
from bfsitl.mission.vehicle import FlightSample
from bfsitl.records.csv_log import CsvFlightLog, read_flight_log


def test_default_plan_takes_off_holds_lands_and_records_every_step(tmp_path):
    vehicle = FakeVehicle()
    log = CsvFlightLog(tmp_path / "f.csv")
    result = fly(
        vehicle,
        MissionPlan(target_alt_m=2.0, hold_s=1.0),
        PController(),
        landing=Descend(),
        log=log,
    )
    log.close()
    assert result.outcome is Outcome.LANDED and result.succeeded
    phases = [row.phase for row in result.rows]
    assert phases[0] == "ground" and phases[-1] == "landed"
    assert (
        phases.index("ground")
        < phases.index("takeoff")
        < phases.index("hold")
        < phases.index("land")
    )
    assert result.hold is not None and result.hold.max_abs_error_m < 0.06
    assert result.armed_after_s == 5.2
    written = read_flight_log(tmp_path / "f.csv")
    assert len(written) == len(result.rows)
    assert written[-1]["armed"] == "0" and written[-1]["rc_aux1_us"] == "1000"
    summary = result.summary()
    assert summary["outcome"] == "landed" and summary["rc_link"]["packets"] == 10


def test_the_ground_phase_idles_feeds_observe_ground_and_restarts_a_plain_controller():
    """Armed at idle first: a controller with observe_ground gets those samples and is not
    reset afterwards; one without is reset when the take-off begins (its clock starts then)."""
    observed: list[float] = []
    resets: list[float] = []

    class Observing(PController):
        def observe_ground(self, sample):  # type: ignore[no-untyped-def]
            observed.append(sample.time_s)

    class Plain(PController):
        def reset(self, time_s):  # type: ignore[no-untyped-def]
            resets.append(time_s)
            super().reset(time_s)

    plan = MissionPlan(target_alt_m=1.0, hold_s=0.2, ground_s=0.5)
    vehicle = FakeVehicle()
    result = fly(vehicle, plan, Observing(), landing=Descend())
    ground = [r for r in result.rows if r.phase == "ground"]
    assert result.outcome is Outcome.LANDED
    assert len(ground) >= 20 and all(r.rc_throttle_us == 1000 for r in ground)
    assert len(observed) == len(ground)
    assert ground[-1].time_s - ground[0].time_s >= 0.5 - 0.021
    result = fly(FakeVehicle(), plan, Plain(), landing=Descend())
    first_takeoff = next(r for r in result.rows if r.phase == "takeoff")
    assert len(resets) == 2 and resets[1] < first_takeoff.time_s
    # No ground phase at all when it is 0; a bad value is refused.
    result = fly(
        FakeVehicle(),
        MissionPlan(target_alt_m=1.0, hold_s=0.2, ground_s=0.0),
        PController(),
        landing=Descend(),
    )
    assert result.rows[0].phase == "takeoff"
    with pytest.raises(MissionError, match="ground time"):
        MissionPlan(ground_s=-1.0)


def test_controllers_get_the_fc_acceleration_and_the_log_records_it(tmp_path):
    """The flying and the landing controller see each sample's accelerometer reading."""
    seen: list[tuple[float, float | None]] = []

    class Recording(PController):
        def update(self, sample):  # type: ignore[no-untyped-def]
            seen.append((sample.time_s, sample.accel_up_m_s2))
            return super().update(sample)

    class RecordingDescend(Descend):
        def update(self, sample):  # type: ignore[no-untyped-def]
            seen.append((sample.time_s, sample.accel_up_m_s2))
            return super().update(sample)

    log = CsvFlightLog(tmp_path / "f.csv")
    result = fly(
        FakeVehicle(),
        MissionPlan(target_alt_m=1.0, hold_s=0.5),
        Recording(),
        landing=RecordingDescend(),
        log=log,
    )
    log.close()
    assert result.outcome is Outcome.LANDED
    by_time = {row.time_s: row.fc_accel_up_m_s2 for row in result.rows}
    assert seen and all(accel == by_time[time_s] for time_s, accel in seen)
    assert any(accel != 0.0 for _time_s, accel in seen)
    written = read_flight_log(tmp_path / "f.csv")
    assert [float(r["fc_accel_up_m_s2"]) for r in written] == pytest.approx(
        [row.fc_accel_up_m_s2 for row in result.rows], abs=1e-4
    )


def test_hold_lasts_its_simulation_time():
    vehicle = FakeVehicle()
    loop = FlightLoop(vehicle, PController(), landing=Descend())
    loop.arm()
    loop.takeoff(1.0)
    start_s = vehicle.time_s
    loop.hold(2.0)
    assert 2.0 <= vehicle.time_s - start_s <= 2.05


def test_arming_blocked_is_an_outcome_with_the_blockers():
    vehicle = FakeVehicle(arm_error=ArmingBlockedError("blocked by RXLOSS", ("RXLOSS",)))
    result = fly(vehicle, MissionPlan(), PController(), landing=Descend())
    assert result.outcome is Outcome.ARMING_BLOCKED
    assert result.blockers == ("RXLOSS",)
    assert result.rows == [] and result.metrics is None


def test_tipping_over_is_a_crash():
    result = fly(FakeVehicle(tilt_deg=85.0), MissionPlan(), PController(), landing=Descend())
    assert result.outcome is Outcome.CRASHED
    assert "tipped over" in result.reason


def test_a_slow_controller_times_out_with_the_altitude_in_the_reason():
    class Weak(PController):
        def update(self, sample):  # type: ignore[no-untyped-def]
            return HOVER_US + 1.0

    plan = MissionPlan(target_alt_m=2.0, takeoff_timeout_s=1.0)
    result = fly(FakeVehicle(), plan, Weak(), landing=Descend())
    assert result.outcome is Outcome.TIMEOUT
    assert "target 2.00 m" in result.reason


@pytest.mark.parametrize(
    ("failure", "outcome"),
    [
        (KeyboardInterrupt(), Outcome.INTERRUPTED),
        (SitlExitedError("the SITL exited with code 139"), Outcome.SITL_EXITED),
    ],
)
def test_interrupt_and_sitl_exit_end_with_the_sticks_at_disarm(failure, outcome, tmp_path):
    vehicle = FakeVehicle(fail_after=40, failure=failure)
    log = CsvFlightLog(tmp_path / "f.csv")
    result = fly(vehicle, MissionPlan(), PController(), landing=Descend(), log=log)
    log.close()
    assert result.outcome is outcome
    last = read_flight_log(tmp_path / "f.csv")[-1]
    assert last["phase"] == outcome.value
    assert last["rc_throttle_us"] == "1000" and last["rc_aux1_us"] == "1000"
    assert vehicle.command.aux_us == (1000, 1000)


def test_a_non_finite_throttle_is_refused():
    class Broken(PController):
        def update(self, sample):  # type: ignore[no-untyped-def]
            return float("nan")

    result = fly(FakeVehicle(), MissionPlan(), Broken(), landing=Descend())
    assert result.outcome is Outcome.ERROR and "throttle nan" in result.reason


def test_hold_stats_use_the_truth_in_the_hold_phase_only():
    vehicle = FakeVehicle()
    loop = FlightLoop(vehicle, PController(), landing=Descend())
    loop.arm()
    loop.takeoff(1.0)
    loop.hold(0.5)
    stats = hold_stats(loop.rows)
    assert stats is not None
    assert stats.samples == sum(1 for r in loop.rows if r.phase == "hold")


def test_plan_rejects_nonsense():
    from bfsitl.errors import MissionError

    with pytest.raises(MissionError, match="outside"):
        MissionPlan(target_alt_m=-1.0)
    with pytest.raises(MissionError, match="hold"):
        MissionPlan(hold_s=float("nan"))


def test_a_stick_step_is_held_for_the_hold_and_centred_afterwards():
    vehicle = FakeVehicle()
    loop = FlightLoop(vehicle, PController())
    loop.arm()
    loop.takeoff(1.0)
    start = len(loop.rows)
    loop.hold(0.5, roll_us=1600, yaw_us=1400)
    stepped = loop.rows[start:]
    assert stepped and all(r.rc_roll_us == 1600 and r.rc_yaw_us == 1400 for r in stepped)
    assert all(r.rc_pitch_us == 1500 for r in stepped)
    assert (vehicle.command.roll_us, vehicle.command.pitch_us, vehicle.command.yaw_us) == (
        1500,
        1500,
        1500,
    )


def test_reached_also_counts_the_controllers_estimate_when_it_keeps_one():
    """The FC reads 8 cm high (its zero error); a controller that knows it says 'there'."""

    class Offset(FakeVehicle):
        def sample(self) -> FlightSample:
            sample = super().sample()
            return replace(sample, fc_alt_m=sample.fc_alt_m + 0.08)

    class FliesTheTruth(PController):
        """Regulates the true altitude (as the fused controller does with its estimate)."""

        def __init__(self, vehicle: FakeVehicle) -> None:
            super().__init__()
            self.vehicle = vehicle

        def update(self, sample) -> float:  # type: ignore[no-untyped-def]
            return HOVER_US + 150.0 * (sample.target_alt_m - self.vehicle.altitude_m)

    class Estimating(FliesTheTruth):
        @property
        def altitude_estimate_m(self) -> float:
            return self.vehicle.altitude_m

    vehicle = Offset()
    loop = FlightLoop(vehicle, Estimating(vehicle))
    loop.arm()
    took_s = loop.takeoff(1.0, timeout_s=10.0)  # reached: the estimate says so
    assert took_s < 10.0
    # The same flight without the estimate: the FC's reading stays 8 cm off, never "reached".
    vehicle = Offset()
    loop = FlightLoop(vehicle, FliesTheTruth(vehicle))
    loop.arm()
    with pytest.raises(MissionError, match="did not finish"):
        loop.takeoff(1.0, timeout_s=3.0)


class GustyVehicle(FakeVehicle):
    """The FC's altitude jumps 6 cm above and below the truth on alternate samples: gusts
    through the rotors, seen by the barometer (never within 5 cm, always within 10 cm)."""

    def sample(self) -> FlightSample:
        sample = super().sample()
        jitter_m = 0.06 if self.samples % 2 else -0.06
        return replace(sample, fc_alt_m=round(sample.fc_alt_m + jitter_m, 2))


def test_a_take_off_in_gusts_is_reached_with_a_wider_band_after_a_while(monkeypatch):
    from bfsitl.errors import MissionTimeoutError
    from bfsitl.mission import loop as runner

    loop = FlightLoop(GustyVehicle(), PController())  # type: ignore[arg-type]
    loop.arm()
    took_s = loop.takeoff(1.0, timeout_s=20.0)
    assert runner.REACHED_PATIENCE_S <= took_s < runner.REACHED_PATIENCE_S + 3.0
    # The control: with the band never widening, the same take-off times out.
    monkeypatch.setattr(runner, "REACHED_PATIENCE_S", 1e9)
    loop = FlightLoop(GustyVehicle(), PController())  # type: ignore[arg-type]
    loop.arm()
    with pytest.raises(MissionTimeoutError):
        loop.takeoff(1.0, timeout_s=20.0)


# -- position control on the planar fake ----------------------------------------------------
def test_a_square_mission_flies_its_legs_turns_and_lands_at_its_start(tmp_path):
    import math

    from bfsitl.mission.flight_metrics import cross_track_rms, landed_from_start_m
    from bfsitl.mission.plan import Waypoint
    from bfsitl.mission.plan_driver import fly_steps

    vehicle = PlanarVehicle()
    log = CsvFlightLog(tmp_path / "square.csv")
    loop = planar_loop(vehicle, log)
    square = (
        Waypoint(10, 0, 1.0),
        Waypoint(10, 10, 1.0, heading_deg=90.0),
        Waypoint(0, 10, 1.5, hold_s=1.0),
        Waypoint(0, 0, 1.0),
    )
    fly_steps(loop, MissionPlan(target_alt_m=1.0, hold_s=0.0, ground_s=0.0, waypoints=square))
    log.close()
    assert [leg.waypoint for leg in loop.legs] == [1, 2, 3, 4]
    assert all(leg.arrival_error_m < 0.35 for leg in loop.legs)
    assert cross_track_rms(loop.legs) < 0.5
    assert landed_from_start_m(loop.rows) < 0.5
    # The turn at waypoint 2 happened and was kept: the heading ends east.
    assert abs(vehicle.heading_deg - 90.0) < 3.0
    # Waypoint 3 is 0.5 m higher: the altitude target moved with the leg.
    assert max(r.target_alt_m for r in loop.rows if r.waypoint == 3) == pytest.approx(1.5)
    rows = read_flight_log(tmp_path / "square.csv")
    assert {"sim_north_m", "fc_east_m", "target_north_m", "target_heading_deg", "waypoint"} <= set(
        rows[0]
    )
    assert {r["waypoint"] for r in rows} == {"0", "1", "2", "3", "4"}
    assert not math.isnan(loop.rows[-1].sim_north_m)


def test_without_the_position_loop_the_wind_carries_the_planar_fake_away():
    """The control of the test above: the same take-off without holding the position
    drifts with the wind, so the square's result is the controller's doing."""
    vehicle = PlanarVehicle()
    loop = planar_loop(vehicle)
    loop.arm()
    loop.takeoff(1.0)
    loop.hold(5.0)
    assert vehicle.north_m > 2.0
    vehicle = PlanarVehicle()
    loop = planar_loop(vehicle)
    loop.arm()
    loop.takeoff(1.0, hold_position=True)
    loop.hold_position(5.0)
    assert abs(vehicle.north_m) < 0.3


def test_yaw_to_turns_the_short_way_and_settles(tmp_path):
    vehicle = PlanarVehicle(wind_push_m_s2=0.0)
    vehicle.heading_deg = 350.0
    loop = planar_loop(vehicle)
    loop.arm()
    loop.takeoff(1.0)
    took_s = loop.yaw_to(20.0)
    assert abs(vehicle.heading_deg - 20.0) < 2.5
    headings = [r.yaw_deg for r in loop.rows if r.phase == "yaw"]
    assert all(h >= 340.0 or h <= 25.0 for h in headings)  # through north, not round south
    assert took_s < 5.0


def test_waypoints_on_a_firmware_without_gps_end_before_arming_with_the_fix():
    from bfsitl.mission.plan import Waypoint

    vehicle = FakeVehicle()
    vehicle.has_gps = False
    result = fly(
        vehicle,
        MissionPlan(waypoints=(Waypoint(5, 0, 2),)),  # type: ignore[arg-type]
        PController(),
    )  # type: ignore[arg-type]
    assert result.outcome is Outcome.ERROR
    assert "GPS build" in result.reason and "--gps" in result.reason
    assert not vehicle.armed and vehicle.samples == 0


@pytest.mark.parametrize(("hold_position", "stays"), [(True, True), (False, False)])
def test_the_default_plan_on_a_gps_vehicle_holds_its_take_off_point(hold_position, stays):
    """No waypoints: with a GPS the take-off, hold and landing hold the take-off point
    against the fake's wind; ``hold_position=False`` drifts (the control)."""
    from bfsitl.mission.flight_metrics import landed_from_start_m
    from bfsitl.mission.plan_driver import fly_steps

    vehicle = PlanarVehicle()
    loop = planar_loop(vehicle)
    fly_steps(
        loop, MissionPlan(target_alt_m=1.0, hold_s=4.0, ground_s=0.0, hold_position=hold_position)
    )
    landed_m = landed_from_start_m(loop.rows)
    assert landed_m is not None
    assert (landed_m < 0.3) == stays, landed_m
