"""A policy file flies a vehicle from the FC's readings alone: the observation is the one
training fills (bfsitl.gym.snapshot.fc_view), the sticks go out at the policy's rate and in
its mode, the autopilot takes over where the policy left the vehicle, and every way it can go
wrong is said.

The vehicle is the planar fake of the mission tests (a point mass steered through the ANGLE
stick curve, pushed north by a steady wind, its GPS the truth); the policy a hand-written one
written as a bfsitl policy file (tests/support/onnx_policies.py) and run by onnxruntime, as a
trained one is.  It flies toward a target north-east-up of the take-off point: a swapped
axis, a wrong sign or a slot out of place ends the flight somewhere else.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("onnxruntime")
pytest.importorskip("onnx")

from support.fake_vehicles import PlanarVehicle, planar_loop  # noqa: E402
from support.onnx_policies import go_to_target_weights, linear_policy_file  # noqa: E402

from bfsitl.errors import MissionError  # noqa: E402
from bfsitl.gym.observation import observe_view  # noqa: E402
from bfsitl.gym.policy_pilot import PolicyPilot  # noqa: E402
from bfsitl.gym.snapshot import fc_view, watch_fc  # noqa: E402
from bfsitl.mission.phase import Phase  # noqa: E402
from bfsitl.mission.vehicle import (  # noqa: E402
    SWITCH_OFF_US,
    SWITCH_ON_US,
    FlightSample,
    Vehicle,
)
from bfsitl.protocol import messages as msg  # noqa: E402

TARGET = (2.0, -1.5, 2.5)


class PolicyVehicle(PlanarVehicle):
    """The planar fake with what a policy reads besides the sample (MSP_MOTOR), and the FC's
    modes: ANGLE while AUX2 is on (or always, or never)."""

    def __init__(self, *, angle: str = "aux2", **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(**kwargs)
        self.angle = angle
        self.motor_reads = 0

    def reading(self, message_type, sample=None):  # type: ignore[no-untyped-def]
        if message_type is msg.Motor:
            self.motor_reads += 1
            return msg.Motor(motors_us=(1500, 1510, 1490, 1505, 0, 0, 0, 0))
        return super().reading(message_type, sample)

    def sample(self) -> FlightSample:
        sample = super().sample()
        on = {"aux2": self.command.aux_us[1] >= SWITCH_ON_US, "always": True, "never": False}
        return replace(
            sample,
            flight_modes=("ARM", "ANGLE") if on[self.angle] else ("ARM",),
            fc_accel_flu_m_s2=(0.0, 0.0, 9.81),
            fc_gyro_flu_rad_s=(0.0, 0.0, 0.0),
        )


def policy_file(tmp_path: Path, **options) -> Path:  # type: ignore[no-untyped-def]
    return linear_policy_file(tmp_path / "policy.onnx", go_to_target_weights(), **options)


def flown(tmp_path: Path, vehicle: PolicyVehicle, seconds: float = 20.0, **options):  # type: ignore[no-untyped-def]
    loop = planar_loop(vehicle)
    pilot = PolicyPilot(vehicle, policy_file(tmp_path, **options), TARGET)
    loop.arm()
    loop.takeoff(1.5)
    loop.fly_sticks(seconds, pilot)
    return loop, pilot


def test_the_policy_flies_to_its_target_from_the_fcs_readings(tmp_path: Path) -> None:
    vehicle = PolicyVehicle()
    loop, pilot = flown(tmp_path, vehicle)
    # Where the truth is: 2 m north, 1.5 m west, 2.5 m up, against the wind.
    assert vehicle.north_m == pytest.approx(TARGET[0], abs=0.3)
    assert vehicle.east_m == pytest.approx(TARGET[1], abs=0.3)
    assert vehicle.altitude_m == pytest.approx(TARGET[2], abs=0.1)
    rows = [r for r in loop.rows if r.phase == Phase.POLICY]
    assert len(rows) == pytest.approx(20.0 * 50, abs=2)  # the policy's rate, 50 Hz
    assert all(r.target_alt_m == TARGET[2] for r in rows)
    assert all(r.rc_aux2_us == SWITCH_ON_US for r in rows)  # trained in ANGLE
    report = pilot.report(loop.rows)
    assert report.steps == len(rows)
    assert report.rate_hz_kept == pytest.approx(50.0)
    assert report.rate_hz_asked == 50.0
    assert 0 < report.inference_us_median <= report.inference_us_p99 <= report.inference_us_max
    assert report.true_distance_max_m < 0.3 and report.fc_distance_max_m < 0.3
    # MSP_MOTOR is read with each step's sample (one reading per step).
    assert vehicle.motor_reads == len(rows)


def test_after_the_policy_the_sticks_centre_and_the_autopilot_holds_where_it_was_left(
    tmp_path: Path,
) -> None:
    vehicle = PolicyVehicle()
    loop, _pilot = flown(tmp_path, vehicle)
    command = vehicle.rc_command
    assert (command.roll_us, command.pitch_us, command.yaw_us) == (1500, 1500, 1500)
    assert command.aux_us[:2] == (SWITCH_ON_US, SWITCH_ON_US)
    assert loop.target_alt_m == pytest.approx(TARGET[2], abs=0.1)
    left_at = (vehicle.north_m, vehicle.east_m)
    loop.hold_position(5.0)
    assert math.dist(left_at, (vehicle.north_m, vehicle.east_m)) < 0.3
    loop.land()
    assert loop.rows[-1].phase == Phase.LANDED


def test_an_acro_policy_flies_with_angle_off_and_the_switch_comes_back(tmp_path: Path) -> None:
    vehicle = PolicyVehicle()
    loop, _pilot = flown(tmp_path, vehicle, seconds=1.0, mode="acro")
    rows = [r for r in loop.rows if r.phase == Phase.POLICY]
    assert all(r.rc_aux2_us == SWITCH_OFF_US for r in rows)
    assert vehicle.rc_command.aux_us[1] == SWITCH_ON_US


@pytest.mark.parametrize(
    ("angle", "mode", "said"),
    [("never", "angle", "provision ANGLE on AUX2"), ("always", "acro", "stays in ANGLE")],
)
def test_a_policy_flown_in_another_mode_than_its_training_is_stopped(
    tmp_path: Path, angle: str, mode: str, said: str
) -> None:
    with pytest.raises(MissionError, match=said):
        flown(tmp_path, PolicyVehicle(angle=angle), seconds=2.0, mode=mode)


def test_the_loop_refuses_a_policy_trained_at_another_rate(tmp_path: Path) -> None:
    with pytest.raises(MissionError, match="pilot flies at 100 Hz and this loop at 50 Hz"):
        flown(tmp_path, PolicyVehicle(), control_hz=100.0)


@pytest.mark.parametrize(
    ("action", "said"), [([0.0, math.nan, 0.0, 0.0], "4 finite sticks"), ([0.0] * 3, "4 finite")]
)
def test_a_policy_that_gives_no_sticks_is_stopped(action: list[float], said: str) -> None:
    vehicle = PolicyVehicle()
    loop = planar_loop(vehicle)
    pilot = PolicyPilot(vehicle, lambda _obs: np.array(action), TARGET, rate_hz=50.0)
    loop.arm()
    loop.takeoff(1.0)
    with pytest.raises(MissionError, match=said):
        loop.fly_sticks(1.0, pilot)


class GpsFc(Vehicle):
    """The base vehicle with a GPS: what fc_view reads comes from the sample's replies."""

    @property
    def has_gps(self) -> bool:
        return True


def test_the_fc_view_of_a_sample_reads_its_batched_replies_in_the_observations_units() -> None:
    vehicle = GpsFc()
    watch_fc(vehicle)
    assert vehicle._sample_extras == (msg.Motor.COMMAND, msg.RawGps.COMMAND)
    origin = msg.RawGps(2, 12, 473_977_420, 85_455_940, 500, 0, 0)
    vehicle.local_gps(origin)  # the origin, as at arming
    moved = msg.RawGps(2, 12, 473_977_420 + 90, 85_455_940 - 200, 500, 300, 900)  # 3 m/s east
    sample = FlightSample(
        time_s=1.0,
        wall_s=1.0,
        fc_alt_m=2.0,
        fc_climb_m_s=0.5,
        fc_accel_up_m_s2=0.1,
        roll_deg=10.0,
        pitch_deg=-5.0,
        yaw_deg=90.5,
        sim_alt_m=math.nan,
        sim_climb_m_s=math.nan,
        sim_tilt_deg=math.nan,
        sim_roll_deg=math.nan,
        sim_pitch_deg=math.nan,
        sim_yaw_deg=math.nan,
        on_ground=False,
        armed=True,
        arming_blockers=(),
        flight_modes=("ARM", "ANGLE"),
        motors=(math.nan,) * 4,  # type: ignore[arg-type]
        rc=vehicle.rc_command,
        fc_accel_flu_m_s2=(0.5, -0.25, 9.9),
        fc_gyro_flu_rad_s=(0.1, -0.2, 0.3),
        replies={
            msg.Motor.COMMAND: msg.Motor(motors_us=(1000, 1500, 2000, 2100, 0, 0, 0, 0)).encode(),
            msg.RawGps.COMMAND: moved.encode(),
        },
    )
    view = fc_view(vehicle, sample)
    assert view.motors == (0.0, 0.5, 1.0, 1.0)  # pulse widths as 0..1, clipped
    assert view.north_m == pytest.approx(1.0, abs=0.01)  # 90e-7 deg of latitude
    assert view.east_m == pytest.approx(-1.51, abs=0.01)  # 200e-7 deg at 47.4 deg north
    assert (view.v_north_m_s, view.v_east_m_s) == pytest.approx((0.0, 3.0), abs=1e-9)
    observation = observe_view(view, (4.0, 1.0, 3.0))
    expected = [3.0, 2.51, 1.0, 0.0, 3.0, 0.5, math.radians(10.0), math.radians(-5.0)]
    assert observation[:8] == pytest.approx(expected, abs=0.01)
    assert observation[8:10] == pytest.approx([1.0, math.cos(math.radians(90.5))], abs=1e-4)
    assert observation[10:16] == pytest.approx([0.1, -0.2, 0.3, 0.5, -0.25, 9.9], abs=1e-6)


def test_without_a_gps_the_horizontal_slots_are_zero_as_in_training() -> None:
    vehicle = PolicyVehicle()
    vehicle.has_gps = False
    watch_fc(vehicle)
    assert vehicle._sample_extras == (msg.Motor.COMMAND,)
    vehicle.north_m = 3.0
    view = fc_view(vehicle, vehicle.sample())
    assert (view.north_m, view.east_m, view.has_gps) == (0.0, 0.0, False)


def test_a_second_policy_s_report_is_its_own_flight_not_the_first_s(tmp_path: Path) -> None:
    """Two pilots in one loop: the rows hold both flights, and each report pairs its own
    steps with its own rows (by time, not by index)."""
    vehicle = PolicyVehicle()
    loop, first = flown(tmp_path, vehicle, seconds=8.0)
    second_target = (0.0, 0.0, 1.5)
    second = PolicyPilot(vehicle, policy_file(tmp_path), second_target)
    loop.fly_sticks(8.0, second)
    policy_rows = [r for r in loop.rows if r.phase == Phase.POLICY]
    report = second.report(loop.rows)
    assert report.steps == len(second.step_times_s) == pytest.approx(8.0 * 50, abs=2)
    assert report.steps < len(policy_rows)
    # Its FC distances are its own last steps', towards its own target (not NaN, not the
    # first flight's).
    assert math.isfinite(report.fc_distance_rms_m)
    assert report.fc_distance_rms_m == pytest.approx(report.true_distance_rms_m, abs=0.3)
    assert first.report(loop.rows).steps == len(first.step_times_s)


def test_the_altitude_controller_watches_the_policy_fly_when_it_can(tmp_path: Path) -> None:
    """A controller with observe_flight sees every step the policy flies, with the throttle
    the policy sent: so it takes the sticks back from where the vehicle is."""
    from support.fake_vehicles import PController

    class Watching(PController):
        def __init__(self) -> None:
            super().__init__()
            self.seen: list[tuple[float, float]] = []

        def observe_flight(self, sample, throttle_us: float) -> None:  # type: ignore[no-untyped-def]
            self.seen.append((sample.time_s, throttle_us))

    vehicle = PolicyVehicle()
    loop = planar_loop(vehicle)
    loop.controller = watching = Watching()
    pilot = PolicyPilot(vehicle, policy_file(tmp_path), TARGET)
    loop.arm()
    loop.takeoff(1.5)
    loop.fly_sticks(2.0, pilot)
    rows = [r for r in loop.rows if r.phase == Phase.POLICY]
    assert [t for t, _ in watching.seen] == [r.time_s for r in rows] == pilot.step_times_s
    assert [u for _, u in watching.seen] == [r.rc_throttle_us for r in rows]
