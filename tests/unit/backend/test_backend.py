"""The backend interface without a SITL: the factory's choice and refusals, the disturbance
surface each backend offers, the truth's origin, a board's measured IMU scale, and the MSP
policy a link brings."""

from __future__ import annotations

import math

import pytest
from support.fake_fc import FakeFcLink

from bfsitl.backend import BOARD_IMU, SITL_IMU, Backend, SitlBackend
from bfsitl.backend.board import BoardBackend, imu_scale_at_rest
from bfsitl.backend.embedded import LockstepBackend, RealTimeBackend
from bfsitl.backend.factory import make_backend
from bfsitl.backend.options import Timing, World
from bfsitl.build.binary_scan import RX_FRAMES_ENV, RX_FRAMES_MARKER, clear_cache
from bfsitl.build.lockstep import MARKER
from bfsitl.errors import (
    BfsitlError,
    BoardSetupError,
    DisturbanceUnavailableError,
    GazeboNotFoundError,
    SimInputError,
)
from bfsitl.fc.msp_client import DEFAULT_WAKE_INTERVAL_S, MspClient
from bfsitl.fc.rc_link import RcCommand, RcFault, RcLinkStats
from bfsitl.link.serial_link import SerialLink
from bfsitl.link.tcp_link import TcpLink
from bfsitl.mission.session import FcSetup, FlightSession, SessionConfig
from bfsitl.mission.vehicle import Vehicle
from bfsitl.physics import Simulator
from bfsitl.physics.wind import Wind
from bfsitl.sim.lockstep import SITL_SPIN_ENV
from bfsitl.sim.lockstep_io import SteppedLink
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ
from bfsitl.sitl.firmware import FirmwareBinary


@pytest.fixture
def stock(tmp_path) -> FirmwareBinary:
    path = tmp_path / "betaflight_4.6.0_SITL"
    path.write_bytes(b"\x00" * 64 + b"usage\x00")
    clear_cache()
    return FirmwareBinary(path, "test")


@pytest.fixture
def lockstep(tmp_path) -> FirmwareBinary:
    path = tmp_path / "betaflight_lockstep_SITL"
    path.write_bytes(b"\x00" * 64 + MARKER.encode() + b": FC time follows\x00")
    clear_cache()
    return FirmwareBinary(path, "test")


def make(
    firmware: FirmwareBinary,
    *,
    world: World | None = None,
    rc_link: bool = True,
    rc_rate_hz: float | None = DEFAULT_RC_RATE_HZ,
    **timing,
) -> SitlBackend:
    return make_backend(
        world or World(),
        Timing(**timing),
        firmware,
        rc_link=rc_link,
        rc_rate_hz=rc_rate_hz,
        progress=lambda _line: None,
    )


# -- the factory -------------------------------------------------------------------------------
def test_the_build_record_picks_the_backend(stock, lockstep) -> None:
    assert type(make(stock)) is RealTimeBackend
    assert type(make(lockstep)) is LockstepBackend
    assert type(make(lockstep, lockstep=False)) is RealTimeBackend  # flown on the wall clock
    assert make(lockstep).lockstep and not make(stock).lockstep


def test_impossible_combinations_are_refused_before_anything_starts(stock, lockstep) -> None:
    with pytest.raises(BfsitlError, match="firmware build --lockstep"):
        make(stock, lockstep=True)
    with pytest.raises(BfsitlError, match="firmware build --lockstep"):
        make(stock, speed=math.inf)
    with pytest.raises(BfsitlError, match="outside 0.05..4"):
        make(stock, speed=10.0)
    with pytest.raises(BfsitlError, match="positive"):
        make(lockstep, speed=-1.0)
    with pytest.raises(BfsitlError, match="rc_link=False"):
        make(lockstep, rc_link=False)
    with pytest.raises(BfsitlError, match="embedded or gazebo"):
        make(stock, world=World(physics="bullet"))
    with pytest.raises(BfsitlError, match="Gazebo sets its own pace"):
        make(stock, world=World(physics="gazebo"), speed=2.0)
    with pytest.raises(GazeboNotFoundError):  # not installed here: refused with the fix
        make(stock, world=World(physics="gazebo"))


def test_a_lockstep_backend_paces_as_asked(lockstep) -> None:
    assert make(lockstep).speed is None  # type: ignore[attr-defined]
    assert make(lockstep, speed=math.inf).speed is None  # type: ignore[attr-defined]
    assert make(lockstep, speed=30.0).speed == 30.0  # type: ignore[attr-defined]
    assert make(lockstep, lockstep_spin=False).sitl_env == {SITL_SPIN_ENV: "0"}
    assert make(lockstep).sitl_env is None


def test_a_46_build_counting_frames_is_asked_to_when_the_link_has_a_rate(tmp_path) -> None:
    path = tmp_path / "betaflight_4.6.0_SITL"
    path.write_bytes(b"\x00" * 64 + MARKER.encode() + b": FC time follows\x00" + RX_FRAMES_MARKER)
    clear_cache()
    counting = FirmwareBinary(path, "test")
    assert counting.rx_frames
    assert make(counting).sitl_env == dict([RX_FRAMES_ENV])
    assert make(counting, rc_rate_hz=150.0).rc_rate_hz == 150.0  # type: ignore[attr-defined]
    assert make(counting, rc_rate_hz=None).sitl_env is None  # the stock receiver: per check
    with pytest.raises(SimInputError, match="16 to 1000 Hz"):
        FcSetup(rc_rate_hz=2000.0)  # refused when the configuration is made


def test_a_lockstep_backend_hooks_every_link_into_the_steps(lockstep) -> None:
    hooks = make(lockstep).hooks
    assert hooks.on_spawn is not None and hooks.client_clock is not None
    assert hooks.link_wrapper is not None
    with pytest.raises(BfsitlError, match="not started"):
        hooks.client_clock()  # before start there is no simulation time
    assert make(lockstep, lockstep=False).hooks.link_wrapper is None


def test_a_session_checks_its_speed_when_made_and_has_no_backend_before_start() -> None:
    with pytest.raises(BfsitlError, match="positive"):
        FlightSession(SessionConfig(timing=Timing(speed=-1.0)))
    session = FlightSession()
    assert session.sitl_backend is None and not session.lockstep and session.truth is None


# -- the disturbance surface ------------------------------------------------------------------
class Sender:
    """An RC sender that only remembers."""

    def __init__(self) -> None:
        self.command = RcCommand()
        self.fault: RcFault | None = None

    def set(self, command: RcCommand) -> None:
        self.command = command

    def start(self) -> Sender:
        return self

    def stats(self) -> RcLinkStats:
        return RcLinkStats(0, 0.0, 0.0, 0.0, 0)

    def close(self) -> None:
        pass


def test_a_board_offers_no_disturbance_and_says_why() -> None:
    disturbances = Backend().disturbances
    assert not disturbances.has_rc and not disturbances.has_physics
    for act in (
        lambda: disturbances.set_motor_thrust(1, 0.5),
        lambda: disturbances.set_wind(None),
        lambda: disturbances.set_gps_lost(True),
        lambda: disturbances.set_rc_fault(RcFault(silent=True)),
    ):
        with pytest.raises(DisturbanceUnavailableError, match="a real board"):
            act()


def test_external_physics_offers_rc_only(stock) -> None:
    backend = SitlBackend()
    with pytest.raises(DisturbanceUnavailableError, match="has none"):
        backend.disturbances.set_rc_fault(RcFault(silent=True))  # no RC link yet
    backend.rc = sender = Sender()
    backend.disturbances.set_rc_fault(RcFault(silent=True))
    assert sender.fault == RcFault(silent=True) == backend.disturbances.rc_fault
    with pytest.raises(DisturbanceUnavailableError, match="embedded physics"):
        backend.disturbances.set_motor_thrust(2, 0.5)


def test_embedded_physics_disturbs_the_simulator_it_flies(stock) -> None:
    backend = make(stock)
    simulator = backend.simulator
    assert isinstance(simulator, Simulator)
    disturbances = backend.disturbances
    disturbances.set_motor_thrust(3, 0.7)
    assert simulator.motor_thrust == (1.0, 1.0, 0.7, 1.0) == disturbances.motor_thrust
    before = disturbances.change_sensors(gps_offset_ne_m=(6.0, -4.0))
    assert simulator.sensor_config.gps_offset_ne_m == (6.0, -4.0)
    assert before.gps_offset_ne_m == (0.0, 0.0)
    disturbances.set_wind(Wind((3.0, 0.0, 0.0)))
    assert simulator.wind == Wind((3.0, 0.0, 0.0)) == disturbances.wind
    disturbances.set_gps_lost(True)  # before the bridge exists: remembered, no error
    assert disturbances.gps_lost


# -- truth and IMU scale ----------------------------------------------------------------------
def test_the_truth_counts_from_where_the_vehicle_stood_at_arming(stock) -> None:
    backend = make(stock)
    vehicle = Vehicle(backend=backend)
    assert backend.truth() is None  # no bridge yet: nobody knows it
    assert math.isnan(vehicle._truth().altitude_m)

    class StillBridge:
        motors = (0.1, 0.2, 0.3, 0.4)

        def between_steps(self, action):
            return action()

    backend.bridge = StillBridge()  # type: ignore[assignment]
    assert backend.simulator is not None
    backend.simulator.reset((5.0, -2.0, -3.0))
    vehicle._start_ned = (4.0, 1.0)
    truth = vehicle._truth()
    assert (truth.north_m, truth.east_m) == (1.0, -3.0)
    assert truth.motors == (0.1, 0.2, 0.3, 0.4) and truth.tilt_deg == pytest.approx(0.0)
    assert truth.altitude_m == pytest.approx(backend.simulator.altitude_m)


def test_a_boards_accelerometer_scale_is_measured_at_rest() -> None:
    assert imu_scale_at_rest([(0, 0, 2048), (10, -12, 2040)]) == BOARD_IMU
    assert imu_scale_at_rest([(0, 0, 4100)]).acc_1g_lsb == 4096
    tilted = (0, int(2048 * math.sin(0.3)), int(2048 * math.cos(0.3)))
    assert imu_scale_at_rest([tilted]).acc_1g_lsb == 2048
    assert imu_scale_at_rest([(0, 0, 255)]) == SITL_IMU  # a SITL behind a serial bridge
    with pytest.raises(BoardSetupError, match="keep the board still"):
        imu_scale_at_rest([(0, 0, 3000)])
    with pytest.raises(BoardSetupError):
        imu_scale_at_rest([])
    readings = iter([(0, 0, 2050)] * 5)
    assert BoardBackend.measured(lambda: next(readings)).imu.acc_1g_lsb == 2048


def test_a_vehicle_reads_its_accelerometer_in_its_backends_scale() -> None:
    from bfsitl.mission.vehicle import accel_flu_m_s2

    class RawImu:  # shaped like MSP_RAW_IMU's reply
        acc_raw = (0, 0, 2048)

    board = accel_flu_m_s2(RawImu(), BOARD_IMU)  # type: ignore[arg-type]
    sitl = accel_flu_m_s2(RawImu(), SITL_IMU)  # type: ignore[arg-type]
    assert board[2] == pytest.approx(9.80665)
    assert sitl[2] == pytest.approx(9.80665 * 2048.5 / 256)


# -- the link brings its MSP policy ------------------------------------------------------------
def test_the_link_says_what_its_peer_needs() -> None:
    assert TcpLink.wants_wake_bytes and not SerialLink.wants_wake_bytes
    assert SerialLink.max_in_flight_bytes < TcpLink.max_in_flight_bytes
    fake = FakeFcLink()
    assert MspClient(fake).wake_interval_s is None
    fake.wants_wake_bytes = True
    assert MspClient(fake).wake_interval_s == DEFAULT_WAKE_INTERVAL_S
    # A stepped link wraps a TCP link but needs no wake bytes: its waits step the FC.
    stepped = SteppedLink(fake, bridge=None)  # type: ignore[arg-type]
    assert MspClient(stepped).wake_interval_s is None
    assert stepped.max_in_flight_bytes == fake.max_in_flight_bytes
