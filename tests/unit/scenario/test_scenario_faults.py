"""Fault injection below the scenario runner: the RC link's faults, the physics' and sensors'
fault hooks, and the catalog's per-firmware choices."""

from __future__ import annotations

import math

import pytest

from bfsitl.errors import BfsitlError, FaultNotSupportedError, ScenarioError, SimInputError
from bfsitl.fc.firmware_detect import MASTER_API_VERSION
from bfsitl.fc.rc_link import RcCommand, RcFault, RcFaultState
from bfsitl.physics import IRIS, SensorConfig, Simulator, Wind
from bfsitl.protocol.firmware_profile import BuildOptions, profile_for, with_rc_link
from bfsitl.scenario.faults import LOST_PULSE_US, FaultSpec, make_fault, read_fault_spec

V46 = profile_for("1.47", "4.6.0")
V46_GPS = profile_for("1.47", "4.6.0", has_gps=True)
MASTER = profile_for(MASTER_API_VERSION, "2026.12.0-alpha")
DT = 0.001


# -- the RC link's fault --------------------------------------------------------------------------
def test_without_a_fault_the_command_goes_out_clamped() -> None:
    state = RcFaultState()
    command = RcCommand(throttle_us=2500, aux_us=(1800,))
    assert state.channels(0.0, command) == (1500, 1500, 2000, 1500, 1800)


def test_silence_sends_nothing_and_lost_pulses_go_out_unclamped() -> None:
    state = RcFaultState()
    state.fault = RcFault(silent=True)
    assert state.channels(0.0, RcCommand()) is None
    state.fault = RcFault(pulses_us=((0, 0), (2, 800)))
    assert state.channels(0.0, RcCommand(aux_us=(1800,))) == (0, 1500, 800, 1500, 1800)


def test_a_delay_sends_the_command_of_that_long_ago() -> None:
    state = RcFaultState()
    state.fault = RcFault(delay_s=0.1)
    early, late = RcCommand(throttle_us=1200), RcCommand(throttle_us=1700)
    state.note(0.0, early)
    assert state.channels(0.05, late)[2] == 1200  # 0.05 s after: still the old one
    assert state.channels(0.149, late)[2] == 1200
    assert state.channels(0.151, late)[2] == 1700  # the new one set at 0.05 s, 0.1 s later


def test_a_command_set_just_after_a_delay_begins_waits_too() -> None:
    state = RcFaultState()
    before, after = RcCommand(throttle_us=1200), RcCommand(throttle_us=1700)
    assert state.channels(0.00, before)[2] == 1200  # healthy: what goes out
    state.inject(RcFault(delay_s=0.2), before)
    assert state.channels(0.01, after)[2] == 1200  # set after the delay began
    assert state.channels(0.20, after)[2] == 1200
    assert state.channels(0.22, after)[2] == 1700
    state.inject(None, after)
    assert state.channels(0.23, before)[2] == 1200  # over: at once again


def test_jitter_is_repeatable_with_its_seed_and_within_its_bound() -> None:
    def run(seed: int) -> list[int]:
        state = RcFaultState(seed)
        state.fault = RcFault(delay_s=0.0, jitter_s=0.05)
        out = []
        for k in range(200):
            command = RcCommand(throttle_us=1000 + k)  # a new command every 10 ms
            out.append(state.channels(k * 0.01, command)[2])
        return out

    first = run(1)
    assert first == run(1) and first != run(2)
    lags = [1000 + k - value for k, value in enumerate(first)]
    assert min(lags) >= 0 and max(lags) <= 5 and len(set(lags)) > 2  # 0..50 ms, varied


@pytest.mark.parametrize(
    "fault", [dict(pulses_us=((16, 1000),)), dict(pulses_us=((0, 70000),)), dict(delay_s=-1.0)]
)
def test_impossible_rc_faults_are_refused(fault: dict) -> None:
    with pytest.raises(BfsitlError):
        RcFault(**fault)


# -- the physics' and sensors' hooks ---------------------------------------------------------------
def _spin(commands: tuple[float, ...], weak_motor: int | None) -> tuple[float, float, float]:
    sim = Simulator(IRIS)
    speeds = tuple(IRIS.steady_rotor_speed_rad_s(u) for u in commands)
    sim.reset((0.0, 0.0, -50.0), motor_speeds_rad_s=speeds)
    if weak_motor is not None:
        sim.set_motor_thrust(weak_motor, 0.5)
    sim.step(commands, DT)
    return sim.state.angular_velocity_frd_rad_s


def test_a_weak_rear_left_motor_rolls_left_and_pitches_the_nose_up() -> None:
    hover = (IRIS.hover_command,) * 4
    assert all(abs(w) < 1e-9 for w in _spin(hover, None))
    # Betaflight's quad X: M1 rear right, M2 front right, M3 rear left, M4 front left.
    p, q, _ = _spin(hover, 3)
    assert p < -0.01 and q > 0.01
    p, q, _ = _spin(hover, 2)  # front right: roll right, nose down
    assert p > 0.01 and q < -0.01


def test_a_weak_motor_loses_lift_in_proportion() -> None:
    def climb_after(fraction: float) -> float:
        sim = Simulator(IRIS)
        speeds = (IRIS.steady_rotor_speed_rad_s(IRIS.hover_command),) * 4
        sim.reset((0.0, 0.0, -50.0), motor_speeds_rad_s=speeds)
        for motor in (1, 2, 3, 4):
            sim.set_motor_thrust(motor, fraction)
        for _ in range(100):
            sim.step((IRIS.hover_command,) * 4, DT)
        return -sim.state.velocity_ned_m_s[2]

    assert abs(climb_after(1.0)) < 0.01
    # All four at 80 %: 0.2 g short, for 0.1 s (inflow aside).
    assert climb_after(0.8) == pytest.approx(-0.2 * 9.80665 * 0.1, rel=0.1)


@pytest.mark.parametrize(("motor", "fraction"), [(0, 0.5), (5, 0.5), (1, 1.5), (1, math.nan)])
def test_impossible_motor_faults_are_refused(motor: int, fraction: float) -> None:
    with pytest.raises(SimInputError):
        Simulator(IRIS).set_motor_thrust(motor, fraction)


def test_baro_drift_grows_from_when_it_is_set_and_the_noise_stream_goes_on() -> None:
    sim = Simulator(IRIS, sensors=SensorConfig(baro_noise_std_pa=0.0), seed=3)
    sim.reset()
    for _ in range(1000):
        sim.step((0.0,) * 4, DT)
    before = sim.read_sensors().pressure_pa
    sim.set_sensors(SensorConfig(baro_drift_pa_s=-12.0))  # reads as a 1 m/s climb
    for _ in range(2000):
        sim.step((0.0,) * 4, DT)
    assert sim.read_sensors().pressure_pa - before == pytest.approx(-24.0, abs=0.1)


def test_a_gps_offset_moves_the_gps_only() -> None:
    sim = Simulator(IRIS)
    sim.reset()
    clean = sim.read_sensors()
    sim.set_sensors(SensorConfig(gps_offset_ne_m=(10.0, -5.0)))
    glitched = sim.read_sensors()
    assert glitched.position_ned_m == clean.position_ned_m  # the truth stays true
    lon0, lat0, _ = clean.geodetic
    lon1, lat1, _ = glitched.geodetic
    assert (lat1 - lat0) * 111_319.5 == pytest.approx(10.0, rel=0.01)
    assert (lon1 - lon0) * 111_319.5 == pytest.approx(-5.0, rel=0.01)


def test_a_wind_step_takes_effect_at_once() -> None:
    sim = Simulator(IRIS)
    assert sim.wind_ned_m_s == (0.0, 0.0, 0.0)
    sim.set_wind(Wind((3.0, -4.0, 0.0)))
    assert sim.wind_ned_m_s == pytest.approx((3.0, -4.0, 0.0))
    sim.set_wind(None)
    assert sim.wind_ned_m_s == (0.0, 0.0, 0.0)


# -- the catalog ---------------------------------------------------------------------------
def spec(kind: str, **params: object) -> FaultSpec:
    return read_fault_spec(
        {"kind": kind, "at_s": 5.0, **params}, where="x.toml", number=1, run_s=60.0
    )


def test_rc_loss_auto_is_silence_where_frames_stop_and_the_switch_on_a_stock_46() -> None:
    on_master = make_fault(spec("rc_loss"), MASTER)
    on_46 = make_fault(spec("rc_loss"), V46)
    assert on_master.title == "RC lost (silence)" and on_master.switches == ()
    assert on_46.switches == ((27, 2),) and on_46.takes_sticks
    # A lockstep 4.6.0 counting receiver frames loses its link as master does.
    counting = profile_for("1.47", "4.6.0", BuildOptions(receiver_frames=True))
    assert counting.rc.rxloss_after_silence_s == pytest.approx(0.15)
    assert make_fault(spec("rc_loss"), counting).title == "RC lost (silence)"
    # ... when it is flown at a rate: with a frame in every packet it is a stock receiver.
    assert with_rc_link(counting, 150.0) is counting
    per_packet = with_rc_link(counting, None)
    assert per_packet.rc.rxloss_after_silence_s is None
    assert make_fault(spec("rc_loss"), per_packet).switches == ((27, 2),)
    with pytest.raises(FaultNotSupportedError, match="holds the last sticks"):
        make_fault(spec("rc_loss", method="silence"), per_packet)
    assert with_rc_link(MASTER, None) is MASTER  # its UDP receiver times out either way


def test_silence_on_46_is_refused_with_what_works_there() -> None:
    with pytest.raises(FaultNotSupportedError, match="holds the last sticks.*switch"):
        make_fault(spec("rc_loss", method="silence"), V46)
    assert make_fault(spec("rc_loss", method="invalid_pulses"), V46).title.endswith(
        "(invalid pulses)"
    )
    assert LOST_PULSE_US < 885  # below rx_min_usec: a lost channel to every firmware


def test_gps_faults_follow_the_firmware() -> None:
    with pytest.raises(FaultNotSupportedError, match="keeps a 12-satellite fix"):
        make_fault(spec("gps_loss"), V46_GPS)
    with pytest.raises(FaultNotSupportedError, match="firmware with GPS"):
        make_fault(spec("gps_glitch", north_m=5.0), V46)
    assert make_fault(spec("gps_loss"), MASTER).title == "GPS lost"
    assert make_fault(spec("gps_glitch", north_m=5.0), V46_GPS).takes_sticks is False


@pytest.mark.parametrize(
    ("kind", "params", "message"),
    [
        ("rc_loss", {"method": "radio off"}, "not one of"),
        ("motor_thrust", {"motor": 7, "fraction": 0.5}, "motor = 1..4"),
        ("motor_thrust", {"motor": 1, "fraction": 2.0}, r"fraction = 2.0 must be a number in 0..1"),
        ("motor_thrust", {"motor": 1, "fraction": 0.7, "speed": 3}, "no parameter"),
        ("gyro_noise", {}, "needs std_deg_s"),
        ("earthquake", {}, "unknown fault kind 'earthquake'"),
    ],
)
def test_bad_fault_tables_name_the_fault_and_the_key(kind: str, params: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as caught:
        spec(kind, **params)  # refused when the file is read, on any firmware
    assert str(caught.value).startswith("x.toml, fault 1: ")


def test_a_fault_table_is_read_once_with_its_defaults_filled_in() -> None:
    glitch = spec("gps_glitch", north_m=5)
    assert glitch.params == (("east_m", 0.0), ("north_m", 5.0))
    assert spec("rc_loss").param("method") == "auto"
    assert spec("wind", east_m_s=3).param("gust_std_m_s") == 0.0
    with pytest.raises(ScenarioError, match=r"fault 1 at_s = 80.0 must be a number in 0..60"):
        spec("gps_loss", at_s=80.0)


class Vehicle:
    """What a fault touches of a vehicle: its sticks and its disturbance surface."""

    def __init__(self, backend) -> None:
        self.backend = backend
        self.disturbances = backend.disturbances
        self.rc_command = RcCommand()

    def set_rc(self, command: RcCommand) -> None:
        self.rc_command = command


def embedded_vehicle() -> tuple[Vehicle, Simulator]:
    from bfsitl.backend.embedded import RealTimeBackend

    simulator = Simulator(IRIS)
    return Vehicle(RealTimeBackend(simulator, speed=1.0, progress=print)), simulator


def test_each_fault_acts_through_the_disturbance_surface_and_undoes_exactly() -> None:
    vehicle, simulator = embedded_vehicle()
    before = (simulator.motor_thrust, simulator.sensor_config, simulator.wind)
    for kind, params in (
        ("motor_thrust", {"motor": 3, "fraction": 0.6}),
        ("gps_glitch", {"north_m": 5.0}),
        ("gyro_bias", {"z_deg_s": 2.0}),
        ("baro_drift", {"rate_m_s": 0.5}),
        ("wind", {"north_m_s": 4.0}),
    ):
        undo = make_fault(spec(kind, **params), MASTER).apply(vehicle)  # type: ignore[arg-type]
        assert (simulator.motor_thrust, simulator.sensor_config, simulator.wind) != before
        undo()
        assert (simulator.motor_thrust, simulator.sensor_config, simulator.wind) == before
    switch = make_fault(spec("rc_loss"), V46)
    undo = switch.apply(vehicle)  # type: ignore[arg-type]
    assert vehicle.rc_command.aux_us[2] == 1800
    undo()
    assert vehicle.rc_command.aux_us[2] == 1000


def test_a_fault_on_a_backend_that_cannot_express_it_says_why() -> None:
    from bfsitl.backend import Backend
    from bfsitl.errors import DisturbanceUnavailableError

    board = Vehicle(Backend())
    with pytest.raises(DisturbanceUnavailableError, match="embedded physics"):
        make_fault(spec("motor_thrust", motor=1, fraction=0.5), MASTER).apply(board)  # type: ignore[arg-type]
    with pytest.raises(DisturbanceUnavailableError, match="RC link"):
        make_fault(spec("rc_loss"), MASTER).apply(board)  # type: ignore[arg-type]
