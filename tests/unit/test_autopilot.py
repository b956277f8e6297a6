"""The :class:`~bfsitl.autopilot.Autopilot` on the point-mass vehicles of test_mission_runner:
its verbs (take-off, goto, hold, yaw_to, land, fly), the targets it hands the controllers,
its log (a record sink picked by suffix, closed with the vehicle on every way out), and its
refusals.

``PlanarVehicle`` moves north for a forward stick and east for a right one, turns with the
yaw stick and is pushed north by a steady wind, so a swapped axis, a wrong sign or a branch
that does not hold the position ends the flight somewhere else.  Time is the fakes' own
(20 ms per sample): nothing here waits on the wall clock.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
from support.fake_vehicles import FakeVehicle, PController, PlanarVehicle

from bfsitl.autopilot import GROUND_WAIT_S, Autopilot
from bfsitl.control.horizontal_estimator import HorizontalEstimator
from bfsitl.control.position import PositionGains
from bfsitl.errors import (
    BfsitlError,
    ControllerConfigError,
    CrashDetectedError,
    MissionError,
    MspErrorReply,
    SitlExitedError,
)
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan import MissionPlan
from bfsitl.mission.results import Outcome
from bfsitl.mission.vehicle import FlightSample, GpsPosition
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.records import sinks
from bfsitl.records.csv_log import read_flight_log


class Targets(PController):
    """The runner tests' P controller, remembering each (time, altitude target) it got."""

    def __init__(self) -> None:
        super().__init__()
        self.asked: list[tuple[float, float]] = []

    def update(self, sample) -> float:  # type: ignore[no-untyped-def]
        self.asked.append((sample.time_s, sample.target_alt_m))
        return super().update(sample)


class TipsOver(FakeVehicle):
    """Tips over (85 deg) once it is a metre up."""

    def sample(self) -> FlightSample:
        sample = super().sample()
        return replace(sample, sim_tilt_deg=85.0) if self.altitude_m > 1.0 else sample


class NoGps(FakeVehicle):
    """A 4.6.0 FC without a GPS: MSP_RAW_GPS is refused with ``!``."""

    def gps_position(self, sample: Any = None) -> GpsPosition:
        raise MspErrorReply(MspCommand.RAW_GPS)


def pilot_for(vehicle: FakeVehicle, controller: Any = None, **options: Any) -> Autopilot:
    pilot = Autopilot(vehicle, controller or PController(), **options)
    if isinstance(vehicle, PlanarVehicle):
        pilot.loop.steering.sticks = vehicle.sticks  # the FC's stick curve would be read over MSP
    return pilot


def rows_of(pilot: Autopilot, phase: Phase) -> list[FlightRow]:
    return [row for row in pilot.rows if row.phase == phase]


class RecordingSink(sinks.SinkBase):
    """A record format of the test's own, registered for ``.rec``: what reached it."""

    opened: list[RecordingSink] = []

    def __init__(self, path: Path, **options: Any) -> None:
        self.path, self.options = path, options
        self.rows: list[FlightRow] = []
        self.events: list[tuple[float, str]] = []
        self.closes = 0
        RecordingSink.opened.append(self)

    def write(self, row: FlightRow, sample: object = None) -> None:
        assert self.closes == 0, "a row after close"
        self.rows.append(row)

    def event(self, time_s: float, text: str) -> None:
        self.events.append((time_s, text))

    def close(self) -> None:
        self.closes += 1


@pytest.fixture
def rec(monkeypatch: pytest.MonkeyPatch) -> type[RecordingSink]:
    monkeypatch.setitem(sinks._SINKS, ".rec", RecordingSink)
    monkeypatch.setattr(RecordingSink, "opened", [])
    return RecordingSink


# -- take-off -----------------------------------------------------------------------------------
def test_takeoff_arms_waits_on_the_ground_then_climbs_to_the_height_asked() -> None:
    vehicle = FakeVehicle()
    controller = Targets()
    events: list[str] = []
    pilot = pilot_for(vehicle, controller, on_event=events.append)
    assert not pilot.armed
    took_s = pilot.takeoff(2.5)
    assert vehicle.armed and pilot.armed
    ground, climb = rows_of(pilot, Phase.GROUND), rows_of(pilot, Phase.TAKEOFF)
    assert pilot.rows[: len(ground)] == ground  # the wait comes first
    assert ground[-1].time_s - ground[0].time_s >= GROUND_WAIT_S - 0.021
    assert all(row.rc_throttle_us == 1000 for row in ground)  # armed at idle
    assert climb and all(row.target_alt_m == 2.5 for row in climb)
    asked_in_climb = [target for t, target in controller.asked if t >= climb[0].time_s]
    assert asked_in_climb and set(asked_in_climb) == {2.5}
    assert vehicle.altitude_m == pytest.approx(2.5, abs=0.06)
    assert took_s == pytest.approx(climb[-1].time_s - climb[0].time_s, abs=0.05)
    assert "take-off to 2.50 m" in events and any(e.startswith("reached 2.50 m") for e in events)
    # In the air a second take-off only changes the height: no arming, no ground wait.
    pilot.takeoff(1.0)
    assert len(rows_of(pilot, Phase.GROUND)) == len(ground)
    assert sum(e.startswith("arming") for e in events) == 1
    assert pilot.rows[-1].target_alt_m == 1.0
    assert vehicle.altitude_m == pytest.approx(1.0, abs=0.06)


@pytest.mark.parametrize(("has_gps", "holds"), [(True, True), (False, False)])
def test_takeoff_holds_the_take_off_point_on_a_gps_vehicle_only(has_gps, holds) -> None:
    """The fake's wind pushes north; with a GPS the climb holds the take-off point, without
    one (the control) the climb drifts with it."""
    vehicle = PlanarVehicle(wind_push_m_s2=0.5)
    vehicle.has_gps = has_gps
    pilot = pilot_for(vehicle)
    pilot.takeoff(2.0)
    drifted_m = math.hypot(vehicle.north_m, vehicle.east_m)
    assert (drifted_m < 0.3) == holds, drifted_m
    climb = rows_of(pilot, Phase.TAKEOFF)
    assert all(math.isfinite(r.target_north_m) for r in climb) == holds


# -- goto ---------------------------------------------------------------------------------------
def test_goto_flies_north_and_east_the_right_way_round_and_numbers_its_legs() -> None:
    vehicle = PlanarVehicle()
    controller = Targets()
    pilot = pilot_for(vehicle, controller)
    pilot.takeoff(1.5)
    leg = pilot.goto(6.0, -4.0)
    assert (vehicle.north_m, vehicle.east_m) == pytest.approx((6.0, -4.0), abs=0.3)
    assert (leg.waypoint, leg.target_north_m, leg.target_east_m, leg.target_alt_m) == (
        1,
        6.0,
        -4.0,
        1.5,
    )
    assert pilot.legs == [leg] and leg.arrival_error_m < 0.3
    # The position loop's target travels from the start to the end, north up and east down.
    first = [r for r in rows_of(pilot, Phase.GOTO) if r.waypoint == 1]
    norths = [r.target_north_m for r in first]
    easts = [r.target_east_m for r in first]
    assert norths[0] < 0.5 and norths[-1] == 6.0 and norths == sorted(norths)
    assert easts[0] > -0.5 and easts[-1] == -4.0 and easts == sorted(easts, reverse=True)
    assert all(r.target_alt_m == 1.5 for r in first)  # altitude: the one held
    # A second leg, climbing, at 1 m/s: numbered 2, the altitude target moves with it.
    second_leg = pilot.goto(0.0, 3.0, 2.5, speed_m_s=1.0)
    assert second_leg.waypoint == 2 and len(pilot.legs) == 2
    assert (vehicle.north_m, vehicle.east_m) == pytest.approx((0.0, 3.0), abs=0.3)
    second = [r for r in rows_of(pilot, Phase.GOTO) if r.waypoint == 2]
    assert second[0].target_alt_m < 1.7 and second[-1].target_alt_m == pytest.approx(2.5)
    assert second_leg.took_s >= math.hypot(6.0, 7.0) / 1.0
    pilot.hold(2.0)  # the leg's altitude is the one held from now on
    assert controller.asked[-1][1] == pytest.approx(2.5)
    assert vehicle.altitude_m == pytest.approx(2.5, abs=0.06)


def test_a_leg_too_short_for_the_speed_asked_says_what_it_peaks_at() -> None:
    events: list[str] = []
    pilot = pilot_for(PlanarVehicle(), on_event=events.append)
    pilot.takeoff(1.5)
    pilot.goto(3.0, 0.0, speed_m_s=5.0)  # 3 m at 1 m/s^2: sqrt(3) at the most
    pilot.goto(3.0, 40.0, speed_m_s=5.0)  # long enough
    legs = [e for e in events if "fly to" in e]
    assert legs[0].endswith("(3.0 m at 5 m/s: too short for it, peaks at 1.7 m/s)")
    assert legs[1].endswith("(40.0 m at 5 m/s)")


def test_goto_without_a_gps_says_which_firmware_to_fly() -> None:
    vehicle = NoGps()
    pilot = pilot_for(vehicle)
    pilot.takeoff(1.0)
    recorded = len(pilot.rows)
    with pytest.raises(MissionError, match=r"needs the FC's GPS.*firmware build --gps"):
        pilot.goto(3.0, 0.0)
    assert len(pilot.rows) == recorded and pilot.legs == [] and vehicle.armed
    pilot.hold(0.5)  # the altitude alone still flies
    assert rows_of(pilot, Phase.HOLD) and all(
        math.isnan(r.target_north_m) for r in rows_of(pilot, Phase.HOLD)
    )


# -- hold, yaw, land ----------------------------------------------------------------------------
@pytest.mark.parametrize("has_gps", [True, False])
def test_hold_holds_the_position_with_a_gps_and_the_altitude_alone_without(has_gps) -> None:
    vehicle = PlanarVehicle(wind_push_m_s2=0.5)
    pilot = pilot_for(vehicle)
    pilot.takeoff(1.5)
    vehicle.has_gps = has_gps  # the same vehicle, told it has no GPS for the hold
    before = (vehicle.north_m, vehicle.east_m)
    pilot.hold(4.0)
    held = rows_of(pilot, Phase.HOLD)
    assert held[-1].time_s - held[0].time_s == pytest.approx(4.0, abs=0.03)
    assert vehicle.altitude_m == pytest.approx(1.5, abs=0.06)
    moved_m = math.hypot(vehicle.north_m - before[0], vehicle.east_m - before[1])
    if has_gps:
        assert moved_m < 0.3 and all(math.isfinite(r.target_north_m) for r in held)
    else:
        assert vehicle.north_m - before[0] > 1.0  # the wind had its way
        assert all(math.isnan(r.target_north_m) for r in held)


def test_yaw_to_turns_clockwise_and_back_to_the_heading_asked() -> None:
    vehicle = PlanarVehicle(wind_push_m_s2=0.0)
    pilot = pilot_for(vehicle)
    pilot.takeoff(1.0)
    took_s = pilot.yaw_to(90.0)
    assert vehicle.heading_deg == pytest.approx(90.0, abs=2.5) and 0.5 <= took_s < 10.0
    turning = rows_of(pilot, Phase.YAW)
    assert turning[len(turning) // 4].yaw_deg < 90.0  # it went up from 0, not round
    pilot.yaw_to(-45.0)  # the same as 315
    assert vehicle.heading_deg == pytest.approx(315.0, abs=2.5)
    assert rows_of(pilot, Phase.YAW)[-1].target_heading_deg == pytest.approx(315.0)


@pytest.mark.parametrize("heading", [math.nan, math.inf])
def test_yaw_to_refuses_a_heading_that_is_not_a_number(heading) -> None:
    vehicle = PlanarVehicle()
    pilot = pilot_for(vehicle)
    pilot.takeoff(1.0)
    recorded = len(pilot.rows)
    with pytest.raises(MissionError, match="is not a number"):
        pilot.yaw_to(heading)
    assert len(pilot.rows) == recorded


def test_land_touches_down_where_the_last_leg_ended_and_disarms() -> None:
    vehicle = PlanarVehicle(wind_push_m_s2=0.5)
    pilot = pilot_for(vehicle)
    pilot.takeoff(1.5)
    pilot.goto(4.0, 2.0)
    pilot.land()
    assert not vehicle.armed and not pilot.armed and vehicle.altitude_m == 0.0
    assert pilot.rows[-1].phase == Phase.LANDED
    landing = rows_of(pilot, Phase.LAND)
    assert {(r.target_north_m, r.target_east_m) for r in landing} == {(4.0, 2.0)}
    assert (vehicle.north_m, vehicle.east_m) == pytest.approx((4.0, 2.0), abs=0.3)
    with pytest.raises(MissionError, match="take off first"):
        pilot.goto(0.0, 0.0)


@pytest.mark.parametrize("verb", ["goto", "hold", "yaw_to", "land"])
def test_manoeuvres_on_the_ground_are_refused_before_anything_moves(verb) -> None:
    vehicle = PlanarVehicle()
    pilot = pilot_for(vehicle)
    act = {
        "goto": lambda: pilot.goto(1.0, 1.0),
        "hold": lambda: pilot.hold(1.0),
        "yaw_to": lambda: pilot.yaw_to(10.0),
        "land": lambda: pilot.land(),
    }[verb]
    with pytest.raises(
        MissionError, match=f"^{verb}: the vehicle is on the ground, disarmed; take off first$"
    ):
        act()
    assert not vehicle.armed and vehicle.samples == 0 and pilot.rows == []


# -- a whole plan -------------------------------------------------------------------------------
def test_fly_runs_a_plan_from_the_ground_into_the_same_log_and_refuses_in_the_air(rec) -> None:
    vehicle = FakeVehicle()
    pilot = pilot_for(vehicle, log="flight.rec")
    result = pilot.fly(MissionPlan(target_alt_m=1.0, hold_s=1.0, ground_s=0.0))
    assert result.outcome is Outcome.LANDED and not vehicle.armed
    assert [r.phase for r in result.rows][-1] == Phase.LANDED
    assert rec.opened[0].rows == result.rows  # recorded in the autopilot's log
    pilot.takeoff(1.0)
    with pytest.raises(MissionError, match="land first"):
        pilot.fly(MissionPlan())


# -- the log ------------------------------------------------------------------------------------
def test_the_log_is_opened_by_its_suffix_gets_every_row_and_closes_with_the_vehicle(
    rec, tmp_path
) -> None:
    vehicle = FakeVehicle()
    pilot = pilot_for(vehicle, log=tmp_path / "flight.rec")
    (sink,) = rec.opened
    assert sink.path == tmp_path / "flight.rec"
    pilot.takeoff(1.0)
    pilot.land()
    assert sink.rows == pilot.rows and sink.closes == 0  # open while the vehicle is
    vehicle.close()
    vehicle.close()
    assert sink.closes == 1


def test_a_csv_log_holds_the_rows_of_the_flight(tmp_path) -> None:
    vehicle = FakeVehicle()
    pilot = pilot_for(vehicle, log=str(tmp_path / "flight.csv"))
    pilot.takeoff(1.0)
    pilot.hold(0.5)
    vehicle.close()
    written = read_flight_log(tmp_path / "flight.csv")
    assert [row["phase"] for row in written] == [str(row.phase) for row in pilot.rows]
    assert float(written[-1]["target_alt_m"]) == 1.0


@pytest.mark.parametrize(
    ("make", "error"),
    [
        (
            lambda: FakeVehicle(fail_after=150, failure=SitlExitedError("the SITL exited")),
            SitlExitedError,
        ),
        (TipsOver, CrashDetectedError),
    ],
)
def test_the_log_keeps_the_rows_so_far_and_closes_on_the_way_out_of_a_failed_flight(
    rec, make, error
) -> None:
    vehicle = make()
    with pytest.raises(error), vehicle:
        pilot = pilot_for(vehicle, log="flight.rec")
        pilot.takeoff(2.0)
    (sink,) = rec.opened
    assert sink.closes == 1 and sink.rows == pilot.rows and pilot.rows


def test_a_log_without_a_known_suffix_is_refused_before_the_flight(tmp_path) -> None:
    vehicle = FakeVehicle()
    with pytest.raises(BfsitlError, match=r"no record format for \.txt; known: .*\.csv"):
        pilot_for(vehicle, log=tmp_path / "flight.txt")
    assert not vehicle.armed and not (tmp_path / "flight.txt").exists()
    vehicle.close()


def test_a_log_written_only_at_the_end_is_refused_with_the_formats_that_stream(tmp_path) -> None:
    """A plot or a summary needs a finished flight, and the Autopilot never finishes one."""
    vehicle = FakeVehicle()
    for name in ("flight.png", "flight.json"):
        with pytest.raises(MissionError, match=r"name a \.csv or \.mcap file"):
            pilot_for(vehicle, log=tmp_path / name)
    assert not vehicle.armed and list(tmp_path.iterdir()) == []
    vehicle.close()


# -- construction -------------------------------------------------------------------------------
def test_the_loop_rate_and_the_controller_come_from_the_vehicle_and_the_caller() -> None:
    vehicle = FakeVehicle()
    vehicle.control_rate_hz = 40.0
    assert Autopilot(vehicle, PController()).loop.rate_hz == 40.0
    assert Autopilot(vehicle, PController(), rate_hz=20.0).loop.rate_hz == 20.0
    with pytest.raises(MissionError, match="outside 1..200 Hz"):
        Autopilot(vehicle, PController(), rate_hz=500.0)
    assert Autopilot(vehicle).controller.name == "fused"  # the default
    assert Autopilot(vehicle, "cascade").controller.name == "cascade"
    with pytest.raises(ControllerConfigError, match="unknown controller 'pid2'"):
        Autopilot(vehicle, "pid2")


def test_fusing_the_accelerometer_changes_the_position_loops_estimate_and_lead_only() -> None:
    plain = Autopilot(FakeVehicle(), PController()).loop.steering
    fused = Autopilot(FakeVehicle(), PController(), fuse_accelerometer=True).loop.steering
    assert plain.horizontal is None and plain.position.gains.lead_s > 0.0
    assert isinstance(fused.horizontal, HorizontalEstimator)
    assert fused.position.gains == PositionGains(
        **{
            **{f: getattr(plain.position.gains, f) for f in plain.position.gains.__slots__},
            "lead_s": 0.0,
        }
    )


# -- plans ---------------------------------------------------------------------------------------
def test_after_a_plan_that_ends_in_the_air_the_autopilot_can_land() -> None:
    vehicle = FakeVehicle()
    pilot = pilot_for(vehicle)
    result = pilot.fly(MissionPlan(target_alt_m=1.0, hold_s=0.5, ground_s=0.0, land=False))
    assert result.outcome is Outcome.COMPLETED and vehicle.armed
    assert pilot.armed
    pilot.land()
    assert not vehicle.armed
    # Each plan's result is its own: a second plan's rows start at its take-off, after the
    # landing above.
    landed_s = pilot.rows[-1].time_s
    again = pilot.fly(MissionPlan(target_alt_m=1.0, hold_s=0.5, ground_s=0.0))
    assert again.outcome is Outcome.LANDED and again.rows[0].phase == "takeoff"
    assert again.rows[0].time_s > landed_s
    assert len(pilot.rows) > len(result.rows) + len(again.rows)


def test_a_plans_progress_reaches_the_autopilots_on_event_and_its_log(rec) -> None:
    events: list[str] = []
    pilot = pilot_for(FakeVehicle(), on_event=events.append, log="flight.rec")
    pilot.fly(MissionPlan(target_alt_m=1.0, hold_s=0.5, ground_s=0.0))
    assert "take-off to 1.00 m" in events and events[-1] == "disarmed"
    assert [text for _t, text in rec.opened[0].events] == events
