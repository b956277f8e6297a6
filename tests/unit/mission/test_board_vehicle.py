"""A real flight controller as a vehicle (:class:`~bfsitl.mission.board.BoardVehicle`) against
the in-memory FC of tests/support/fake_fc.py: who it is, its accelerometer's scale measured at rest,
RC by MSP in the receiver's order with disarm on the way out, telemetry in the board's own
scale, no truth and no disturbances, and start-up errors that say what to do.

The fake FC is test_provisioning's :class:`StoringFc` (mode ranges kept like msp.c) with a
board's identity, sensors and receiver added.  ``BoardVehicle`` opens its link with the
``link_opener`` it is given (the fake board's here); ``connect()`` builds its own vehicle, so
for it the module's ``open_link`` is replaced.  The real ``open_link`` is used only where the
URI itself is the point.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Iterator

import pytest
from support.fake_fc import FakeFcLink, fixed, multiple_msp, telemetry_handlers
from support.storing_fc import STATUS, StoringFc

from bfsitl.backend import SITL_IMU, ImuScale
from bfsitl.backend.board import BoardBackend
from bfsitl.errors import (
    BoardSetupError,
    DisturbanceUnavailableError,
    LinkError,
    SitlError,
)
from bfsitl.fc.provisioning import ANGLE_ON_AUX2, ARM_ON_AUX1
from bfsitl.fc.rc_link import MspRcLink, RcCommand, RcFault
from bfsitl.mission import board
from bfsitl.mission.board import BOARD_MSP_TIMEOUT_S, BoardVehicle
from bfsitl.mission.session import FLY_PROFILE
from bfsitl.mission.vehicle import ALIVE_CHECK_S
from bfsitl.physics.wind import Wind
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import SITL_DEFAULT_BOX_IDS
from bfsitl.protocol.firmware_profile import Generation
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import MspFrame

URI = "serial:///dev/ttyACM0?baud=115200"
#: Betaflight's feature bits: RX_MSP (14), AIRMODE (22), ANTI_GRAVITY (28).
RX_MSP_AIRMODE_ANTI_GRAVITY = 1 << 14 | 1 << 22 | 1 << 28
AIRMODE_ANTI_GRAVITY = 1 << 22 | 1 << 28
#: The sticks at disarm in the receiver's order: roll, pitch, throttle, yaw, AUX1, AUX2.
DISARMED = (1500, 1500, 1000, 1500, 1000, 1000)
#: Rolled 12.3 deg right, pitched 4.5 deg (nose up), heading 270 (MSP_ATTITUDE's units).
TILTED = msg.Attitude(123, -45, 270)
#: What the rest of the link waits for at most (never reached when the code is right).
WAIT_S = 3.0


class RcSeen:
    """The MSP_SET_RAW_RC frames the FC has received, in order; a test can wait for one."""

    def __init__(self) -> None:
        self.frames: list[tuple[int, ...]] = []
        self._changed = threading.Condition()

    def handle(self, request: MspFrame) -> bytes:
        with self._changed:
            self.frames.append(msg.SetRawRc.decode(request.payload).channels_us)
            self._changed.notify_all()
        return b""

    def wait_for(self, channels: tuple[int, ...]) -> None:
        """Until the FC has received ``channels`` (a wait on the RC thread, not a sleep)."""
        with self._changed:
            if not self._changed.wait_for(lambda: channels in self.frames, timeout=WAIT_S):
                raise AssertionError(f"the FC never received {channels}; got {self.frames[-5:]}")


class Board(StoringFc):
    """StoringFc plus what a board answers at connection: MSP_API_VERSION / FC_VERSION
    (4.6.0), MSP_RAW_GPS (or ``!`` without a GPS), the accelerometer at rest, the configured
    features, telemetry (MSP_MULTIPLE_MSP), and MSP_SET_RAW_RC recorded."""

    def __init__(
        self,
        *,
        acc_raw: tuple[int, int, int] = (0, 0, 4096),
        features: int = RX_MSP_AIRMODE_ANTI_GRAVITY,
        gps: bool = True,
        status: msg.StatusEx = STATUS,
        attitude: msg.Attitude = TILTED,
    ) -> None:
        super().__init__()
        self.rc = RcSeen()
        handlers = self.link.handlers
        handlers.update(
            telemetry_handlers(
                attitude=attitude,
                altitude=msg.Altitude(1234, -50),
                status=status,
                analog=msg.Analog(126, 0, 0, 0, 1260),
                rc=msg.Rc((1500, 1500, 1000, 1500, 1000, 1000)),
                motor=msg.Motor((1000,) * 8),
                imu=msg.RawImu(acc_raw, (0, 0, 0), (0, 0, 0)),
                box_ids=SITL_DEFAULT_BOX_IDS,
            )
        )
        handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(handlers)
        handlers[MspCommand.API_VERSION] = fixed(msg.ApiVersion(0, 1, 47).encode())
        handlers[MspCommand.FC_VERSION] = fixed(msg.FcVersion(4, 6, 0).encode())
        handlers[MspCommand.FEATURE_CONFIG] = fixed(msg.FeatureConfig(features).encode())
        if gps:
            handlers[MspCommand.RAW_GPS] = fixed(
                msg.RawGps(2, 12, 473_977_000, 85_456_000, 400, 0, 0).encode()
            )
        handlers[MspCommand.SET_RAW_RC] = self.rc.handle
        self.links: list[FakeFcLink] = []
        self.opened: list[tuple[str, float]] = []

    def open_link(self, uri: str, *, timeout_s: float) -> FakeFcLink:
        """What ``open_link`` gives the vehicle: a new connection to this FC each time."""
        self.opened.append((uri, timeout_s))
        link = self.link if not self.links else FakeFcLink(self.link.handlers)
        self.links.append(link)
        return link

    def sent(self, command: int) -> int:
        return sum(1 for link in self.links for c in link.sent_commands if c == command)


@pytest.fixture
def plug_in(monkeypatch: pytest.MonkeyPatch) -> Callable[..., Board]:
    """Connect ``board.open_link`` to a fake board; returns it."""

    def plug(**options: object) -> Board:
        fc = Board(**options)  # type: ignore[arg-type]
        monkeypatch.setattr(board, "open_link", fc.open_link)
        return fc

    return plug


@pytest.fixture
def started() -> Iterator[list[BoardVehicle]]:
    """Vehicles a test starts, closed at its end whatever happened."""
    vehicles: list[BoardVehicle] = []
    yield vehicles
    for vehicle in vehicles:
        vehicle.close()


def start(vehicles: list[BoardVehicle], **options: object) -> BoardVehicle:
    vehicle = BoardVehicle(URI, link_opener=board.open_link, **options)  # type: ignore[arg-type]
    vehicles.append(vehicle)
    return vehicle.start()


# -- connecting ---------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("acc_raw", "scale"),
    [
        ((30, -40, 4100), ImuScale(4096.0)),  # a +-8 g part, nearly level
        ((0, 700, 1925), ImuScale(2048.0)),  # +-16 g, tilted 20 deg: the magnitude counts
        ((0, 0, 255), SITL_IMU),  # a SITL behind a serial bridge: its truncation too
    ],
)
def test_start_identifies_the_board_and_measures_its_accelerometer_at_rest(
    plug_in, started, acc_raw, scale
) -> None:
    fc = plug_in(acc_raw=acc_raw)
    lines: list[str] = []
    vehicle = start(started, progress=lines.append)
    assert fc.opened == [(URI, BOARD_MSP_TIMEOUT_S)]
    assert isinstance(vehicle.backend, BoardBackend) and vehicle.backend.imu == scale
    assert vehicle.clock is vehicle.backend.clock  # wall time, the backend's
    assert vehicle.firmware is not None and vehicle.firmware.generation is Generation.V4_6
    assert vehicle.has_gps
    # Measured before the RC starts: five readings at rest, none after the first RC frame.
    fc.rc.wait_for(DISARMED)
    commands = fc.link.sent_commands
    imu_reads = [i for i, c in enumerate(commands) if c == MspCommand.RAW_IMU]
    assert len(imu_reads) == 5 and imu_reads[-1] < commands.index(MspCommand.SET_RAW_RC)
    assert lines[0] == (
        f"connected to {URI}: 4.6.0 (4.6 conventions +GPS), accelerometer "
        f"{scale.acc_1g_lsb:g} LSB per g"
    )


def test_a_started_vehicle_is_returned_as_it_is_and_connects_once(plug_in, started) -> None:
    fc = plug_in()
    vehicle = start(started)
    client = vehicle.client
    assert vehicle.start() is vehicle and vehicle.client is client
    assert len(fc.opened) == 1 and fc.sent(MspCommand.API_VERSION) == 1


def test_without_a_gps_it_flies_the_altitude_only_and_says_so(plug_in, started) -> None:
    plug_in(gps=False)
    lines: list[str] = []
    vehicle = start(started, progress=lines.append)
    assert not vehicle.has_gps
    assert ", no GPS (altitude only)" in lines[0]


# -- RC -----------------------------------------------------------------------------------------
def test_rc_goes_out_by_msp_in_the_receivers_order_and_closing_sends_disarm(
    plug_in, started
) -> None:
    fc = plug_in()
    vehicle = start(started, rc_rate_hz=100.0)
    assert isinstance(vehicle.rc, MspRcLink) and vehicle.rc.rate_hz == 100.0
    fc.rc.wait_for(DISARMED)  # from the start: sticks at disarm
    assert fc.rc.frames[0] == DISARMED
    vehicle.set_rc(
        RcCommand(roll_us=1400, pitch_us=1600, throttle_us=1300, yaw_us=1550, aux_us=(1800, 1000))
    )
    fc.rc.wait_for((1400, 1600, 1300, 1550, 1800, 1000))  # AETR, then AUX1, AUX2
    vehicle.close()
    # The farewell goes out before the link closes: three frames at disarm, the last ones.
    assert fc.rc.frames[-3:] == [DISARMED] * 3
    assert vehicle.rc.closed and fc.link.closed
    sent = len(fc.rc.frames)
    vehicle.close()  # twice is fine: nothing more goes out
    assert len(fc.rc.frames) == sent


def test_throttle_alone_keeps_the_switches_where_they_are(plug_in, started) -> None:
    fc = plug_in()
    vehicle = start(started, rc_rate_hz=100.0)
    vehicle.set_rc(RcCommand(aux_us=(1800, 1800)))
    vehicle.set_throttle(1420)
    fc.rc.wait_for((1500, 1500, 1420, 1500, 1800, 1800))
    assert vehicle.rc_command.throttle_us == 1420


# -- telemetry, truth, disturbances ---------------------------------------------------------------
def test_telemetry_is_read_in_the_boards_own_accelerometer_scale(plug_in, started) -> None:
    """At rest a +-8 g part reads 4096: 1 g up, no acceleration once gravity is removed.  In
    the default board scale (2048) the same reading would be a 1 g climb."""
    plug_in(acc_raw=(0, 0, 4096), attitude=msg.Attitude(0, 0, 90))
    level = start(started).sample()
    assert level.fc_accel_up_m_s2 == pytest.approx(0.0, abs=0.01)
    assert level.fc_accel_flu_m_s2 == pytest.approx((0.0, 0.0, 9.80665), abs=0.01)


def test_telemetry_reads_the_fcs_view(plug_in, started) -> None:
    plug_in(attitude=TILTED)
    sample = start(started).sample()
    assert (sample.fc_alt_m, sample.fc_climb_m_s) == (12.34, -0.5)
    assert (sample.roll_deg, sample.pitch_deg, sample.yaw_deg) == pytest.approx((12.3, -4.5, 270.5))
    assert not sample.armed and sample.rc.aux_us == (1000, 1000)
    assert math.isfinite(sample.time_s) and sample.time_s >= 0.0


def test_a_sample_asks_whether_the_fc_side_runs_at_most_every_alive_check_s(
    plug_in, started, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A lockstep flight samples every fraction of a millisecond of wall time: the check
    (a select on the SITL's pidfd) is made once per ALIVE_CHECK_S, a real-time step's every
    time; a round trip that fails asks at once."""
    plug_in()
    vehicle = start(started)
    checks: list[float] = []
    now_s = [0.0]
    vehicle._wall_clock = lambda: now_s[0]
    monkeypatch.setattr(vehicle, "check_alive", lambda: checks.append(now_s[0]))
    for step in range(6):
        now_s[0] = step * (ALIVE_CHECK_S / 2)  # halves, doubled: exact in binary
        vehicle.sample()
    assert checks == [0.0, ALIVE_CHECK_S, 2 * ALIVE_CHECK_S]


def test_reads_asked_for_with_each_sample_ride_in_its_round_trip(plug_in, started) -> None:
    """The GPS a control loop reads every step comes in the sample's MSP_MULTIPLE_MSP: one
    exchange with the FC per step, not two; without the sample it is read on its own."""
    fc = plug_in()
    vehicle = start(started)
    before = fc.sent(MspCommand.RAW_GPS), fc.sent(MspCommand.MULTIPLE_MSP)
    plain = vehicle.sample()
    assert plain.replies == {}
    vehicle.read_with_samples(msg.RawGps, msg.RawGps)  # asked twice: read once
    sample = vehicle.sample()
    assert list(sample.replies) == [MspCommand.RAW_GPS]
    gps = vehicle.gps_position(sample)
    assert (gps.has_fix, gps.satellites) == (True, 12)
    assert vehicle.reading(msg.RawGps, sample).lat_e7 == 473_977_000
    assert (fc.sent(MspCommand.RAW_GPS), fc.sent(MspCommand.MULTIPLE_MSP)) == (
        before[0],
        before[1] + 2,
    )
    vehicle.gps_position()  # no sample: a round trip of its own
    assert fc.sent(MspCommand.RAW_GPS) == before[0] + 1


def test_a_read_the_fc_cannot_answer_in_a_batch_is_asked_alone_to_say_why(plug_in, started) -> None:
    from bfsitl.errors import MspErrorReply

    plug_in(gps=False)
    vehicle = start(started)
    vehicle.read_with_samples(msg.RawGps)
    sample = vehicle.sample()
    assert sample.replies == {MspCommand.RAW_GPS: b""}
    with pytest.raises(MspErrorReply):
        vehicle.gps_position(sample)


def test_a_board_has_no_truth_and_nothing_to_disturb(plug_in, started) -> None:
    plug_in()
    vehicle = start(started)
    sample = vehicle.sample()
    assert vehicle.truth is None and not vehicle.lockstep and vehicle.bridge_stats() is None
    for unknown in (
        sample.sim_alt_m,
        sample.sim_climb_m_s,
        sample.sim_tilt_deg,
        sample.sim_north_m,
        sample.sim_east_m,
        *sample.motors,
    ):
        assert math.isnan(unknown)
    assert not sample.on_ground  # unknown, not "landed"
    disturbances = vehicle.disturbances
    for act in (
        lambda: disturbances.set_wind(Wind((3.0, 0.0, 0.0))),
        lambda: disturbances.set_motor_thrust(1, 0.5),
        lambda: disturbances.set_gps_lost(True),
        lambda: disturbances.set_rc_fault(RcFault(silent=True)),
    ):
        with pytest.raises(DisturbanceUnavailableError, match="a real board"):
            act()


# -- provisioning ---------------------------------------------------------------------------------
def test_the_fly_profile_is_provisioned_once_and_saved_without_a_reboot(plug_in, started) -> None:
    fc = plug_in()
    lines: list[str] = []
    first = start(started, profile=FLY_PROFILE, progress=lines.append)
    assert fc.slots[:2] == [ARM_ON_AUX1, ANGLE_ON_AUX2] and fc.eeprom_writes == 1
    assert first.provisioned is not None and first.provisioned.changed
    assert lines[-1] == "provisioned: written and saved"
    first.close()
    lines.clear()
    again = start(started, profile=FLY_PROFILE, progress=lines.append)
    assert again.provisioned is not None and not again.provisioned.changed
    assert fc.eeprom_writes == 1 and lines[-1] == "provisioned: already configured, nothing written"


def test_without_a_profile_nothing_is_written(plug_in, started) -> None:
    fc = plug_in()
    vehicle = start(started, profile=None)
    assert vehicle.provisioned is None
    assert fc.sent(MspCommand.SET_MODE_RANGE) == 0 and fc.sent(MspCommand.EEPROM_WRITE) == 0
    assert fc.slots[0] == msg.ModeRange(0, 0, 0, 0)


def test_connect_provisions_the_autopilots_switches_unless_told_not_to(plug_in) -> None:
    from bfsitl.autopilot import Autopilot, connect

    fc = plug_in()
    with connect(URI, provision=False, rc_rate_hz=50.0) as vehicle:
        assert vehicle.profile is None and vehicle.rc is not None and vehicle.rc.rate_hz == 50.0
        # The autopilot's loop runs at what the board's serial budget allows by default.
        assert Autopilot(vehicle).loop.rate_hz == BoardVehicle.control_rate_hz == 25.0
    assert fc.slots[0] == msg.ModeRange(0, 0, 0, 0)
    with connect(URI) as vehicle:
        assert vehicle.profile == FLY_PROFILE
    assert fc.slots[:2] == [ARM_ON_AUX1, ANGLE_ON_AUX2]


# -- errors that say what to do -------------------------------------------------------------------
def assert_left_nothing_running(fc: Board, vehicle: BoardVehicle) -> None:
    assert all(link.closed for link in fc.links)
    assert vehicle.rc is None and fc.rc.frames == []  # no RC ever went out


def test_a_receiver_that_is_not_msp_stops_the_start_with_the_fix(plug_in) -> None:
    fc = plug_in(features=AIRMODE_ANTI_GRAVITY)
    vehicle = BoardVehicle(URI, profile=FLY_PROFILE, link_opener=fc.open_link)
    with pytest.raises(BoardSetupError) as caught:
        vehicle.start()
    text = str(caught.value)
    assert "receiver is not MSP (features: AIRMODE, ANTI_GRAVITY)" in text
    assert "Switch the receiver to MSP" in text and "reboot, and connect again" in text
    assert_left_nothing_running(fc, vehicle)
    assert fc.sent(MspCommand.SET_MODE_RANGE) == 0  # refused before provisioning


def test_a_board_that_moves_while_connecting_is_refused_with_what_to_do(plug_in) -> None:
    fc = plug_in(acc_raw=(0, 0, 3000))
    vehicle = BoardVehicle(URI, link_opener=fc.open_link)
    with pytest.raises(BoardSetupError, match="keep the board still and calibrate"):
        vehicle.start()
    assert_left_nothing_running(fc, vehicle)


def test_settings_that_need_a_reboot_say_how_to_reboot(plug_in) -> None:
    import dataclasses

    fc = plug_in(status=dataclasses.replace(STATUS, config_state=1))
    vehicle = BoardVehicle(URI, profile=FLY_PROFILE, link_opener=fc.open_link)
    with pytest.raises(BoardSetupError, match=r"power-cycle or reboot the board .*connect again"):
        vehicle.start()
    assert fc.eeprom_writes == 1  # saved; only the reboot is missing
    assert_left_nothing_running(fc, vehicle)


def test_before_start_it_says_it_is_not_started() -> None:
    vehicle = BoardVehicle(URI)
    with pytest.raises(SitlError, match="not started"):
        vehicle.client  # noqa: B018
    with pytest.raises(SitlError, match="not started"):
        vehicle.set_rc(RcCommand())
    assert vehicle.firmware is None and not vehicle.has_gps
    vehicle.close()  # nothing to close: fine


def test_an_unknown_link_says_which_ones_exist() -> None:
    vehicle = BoardVehicle("usb://fc")
    with pytest.raises(LinkError, match=r"unknown link; use tcp://.*serial:///dev/ttyACM0"):
        vehicle.start()
    assert vehicle.rc is None


# -- the firmware's GPS ---------------------------------------------------------------------
def test_the_firmware_profile_agrees_with_the_gps_the_board_answered(plug_in, started) -> None:
    plug_in(gps=True)
    vehicle = start(started)
    assert vehicle.has_gps
    assert vehicle.firmware is not None and vehicle.firmware.has_gps
