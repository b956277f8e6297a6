"""The flight loop's hooks and the plan driver, on the fake vehicle of test_mission_runner:
a stop condition ends the flying without an exception, phases and steps are reported in
order, a run's time left cuts the hold."""

from __future__ import annotations

from support.fake_vehicles import Descend, FakeVehicle, PController

from bfsitl.mission.hooks import FlightHooks
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan import MissionPlan
from bfsitl.mission.plan_driver import fly_steps

PLAN = MissionPlan(target_alt_m=2.0, hold_s=3.0, ground_s=0.0)


def flight_loop(vehicle: FakeVehicle, hooks: FlightHooks | None = None) -> FlightLoop:
    return FlightLoop(vehicle, PController(), landing=Descend(), hooks=hooks)  # type: ignore[arg-type]


def test_the_whole_plan_reports_each_step_and_phase_in_order() -> None:
    phases: list[Phase] = []
    steps: list[Phase] = []
    vehicle = FakeVehicle()
    flown = flight_loop(vehicle, FlightHooks(on_phase=phases.append))
    fly_steps(flown, PLAN, after_step=steps.append)
    assert steps == [Phase.TAKEOFF, Phase.HOLD, Phase.LANDED]
    assert phases == [Phase.TAKEOFF, Phase.HOLD, Phase.LAND, Phase.LANDED]
    assert flown.stopped is None and not vehicle.armed  # landed and disarmed


def test_a_stop_condition_ends_the_flying_where_it_is_without_an_exception() -> None:
    rows = []
    steps: list[Phase] = []
    vehicle = FakeVehicle()

    def high_enough(sample) -> str | None:  # type: ignore[no-untyped-def]
        return "someone else has the sticks" if sample.sim_alt_m >= 1.0 else None

    flown = flight_loop(
        vehicle, FlightHooks(on_step=lambda row, _s: rows.append(row), stop=high_enough)
    )
    fly_steps(flown, PLAN, after_step=steps.append)
    assert flown.stopped == "someone else has the sticks"
    assert steps == []  # the take-off never finished
    assert rows[-1].phase == Phase.TAKEOFF and 1.0 <= rows[-1].sim_alt_m < 1.2
    assert vehicle.armed  # nobody disarmed: not ours to do
    recorded = len(flown.rows)
    flown.hold(2.0)
    flown.land()
    assert len(flown.rows) == recorded and vehicle.armed  # later manoeuvres do nothing


def test_observing_goes_on_after_a_stop() -> None:
    vehicle = FakeVehicle()
    flown = flight_loop(vehicle, FlightHooks(stop=lambda s: "stop" if s.sim_alt_m > 0.5 else None))
    flown.arm()
    flown.takeoff(2.0)
    before = len(flown.rows)
    flown.observe(lambda s: False, timeout_s=0.5)
    assert flown.stopped == "stop" and len(flown.rows) - before >= 20


def test_the_time_a_run_has_left_cuts_the_hold() -> None:
    full, cut = flight_loop(FakeVehicle()), flight_loop(FakeVehicle())
    fly_steps(full, PLAN)
    fly_steps(cut, PLAN, time_left_s=lambda: 1.0)
    held_full = sum(1 for r in full.rows if r.phase == Phase.HOLD)
    held_cut = sum(1 for r in cut.rows if r.phase == Phase.HOLD)
    assert 145 <= held_full <= 155 and 45 <= held_cut <= 55  # 3 s and 1 s, 50 rows a second


def test_short_hooks_fold_into_flight_hooks() -> None:
    rows: list[object] = []
    events: list[str] = []
    flown = FlightLoop(
        FakeVehicle(),
        PController(),
        on_row=lambda r, _s: rows.append(r),  # type: ignore[arg-type]
        on_event=events.append,
    )
    assert flown.hooks.on_step is not None and flown.hooks.on_event is not None
    flown.arm()
    flown.takeoff(1.0)
    assert rows and any("take-off" in e for e in events)
