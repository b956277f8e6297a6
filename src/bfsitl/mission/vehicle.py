"""A vehicle: what an autopilot flies, simulated or real.

:class:`Vehicle` holds what does not depend on where the flight controller is: arming (wait
for the FC's blockers, raise the ARM switch), disarming, the RC command, one look at the
flight (:class:`FlightSample`: the FC's view over MSP, next to the truth when it is known),
the FC's GPS made local, a clock.  :class:`~bfsitl.mission.session.FlightSession` is the
simulated one (SITL, physics, UDP or lockstep RC, simulation time, the truth);
:class:`~bfsitl.mission.board.BoardVehicle` a flight controller on a serial port (RC by MSP,
wall time, no truth).  A :class:`~bfsitl.mission.loop.FlightLoop` flies either.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, ClassVar, Protocol, Self, TypeVar

from bfsitl.backend.base import (
    Backend,
    ImuScale,
    RcSender,
    SessionClock,
    Truth,
)
from bfsitl.backend.disturbances import Disturbances
from bfsitl.errors import ArmingBlockedError, LinkError, MspError, SitlError
from bfsitl.fc.msp_client import MspClient, Telemetry
from bfsitl.fc.rc_link import RC_MIN_US, RcCommand, RcLinkStats
from bfsitl.fc.telemetry import blocker_names, mode_names, vertical_accel_m_s2
from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2
from bfsitl.physics.params import QuadParams
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import BoxId

if TYPE_CHECKING:
    from bfsitl.physics import Simulator
    from bfsitl.protocol.firmware_profile import FirmwareProfile
    from bfsitl.sim.bridge import BridgeStats

#: Switch positions sent for "on": inside the 1700-2100 us mode ranges, with margin.
SWITCH_ON_US = 1800
SWITCH_OFF_US = RC_MIN_US
#: The FC's boot grace is 5 s of FC time; calibration and the first fdm packets add a little.
DEFAULT_ARM_TIMEOUT_S = 15.0
_POLL_INTERVAL_S = 0.05
#: Wall seconds between a sample's checks that the FC side still runs (a real-time control
#: step is longer: every one checks).
ALIVE_CHECK_S = 0.01
#: Metres per degree of latitude (and of longitude at the equator): the FC's own figure
#: (``EARTH_RADIUS`` based, gps.c), which is what makes its GPS local.
METRES_PER_DEGREE = 111_319.5

Progress = Callable[[str], None]


def accel_flu_m_s2(raw: msg.RawImu, imu: ImuScale) -> tuple[float, float, float]:
    """MSP_RAW_IMU's accelerometer in m/s^2 (the FC's own scale; the SITL's z truncation
    added back, as for the vertical)."""
    scale = STANDARD_GRAVITY_M_S2 / imu.acc_1g_lsb
    ax, ay, az = raw.acc_raw
    return (ax * scale, ay * scale, (az + imu.acc_truncation_lsb) * scale)


def _gyro_flu_rad_s(raw: msg.RawImu) -> tuple[float, float, float]:
    gx, gy, gz = raw.gyro_dps()
    return (math.radians(gx), math.radians(gy), math.radians(gz))


#: What :meth:`Vehicle.sample` reads of the FC, in one MSP_MULTIPLE_MSP round trip with the
#: reads of :meth:`Vehicle.read_with_samples`: what a sample carries (a whole
#: :class:`Telemetry` also has the battery, the RC channels and the motors).
SAMPLE_COMMANDS: tuple[int, ...] = (
    msg.Attitude.COMMAND,
    msg.Altitude.COMMAND,
    msg.StatusEx.COMMAND,
    msg.RawImu.COMMAND,
)


@dataclass(frozen=True, slots=True)
class FlightSample:
    """One look at the flight: what the FC reports next to the simulated truth."""

    time_s: float  # simulation time: the mission clock
    wall_s: float  # time.monotonic() when the sample was taken
    fc_alt_m: float  # MSP_ALTITUDE, up positive, zeroed by the FC at arming
    fc_climb_m_s: float  # MSP_ALTITUDE vario, up positive
    fc_accel_up_m_s2: float  # MSP_RAW_IMU z and MSP_ATTITUDE: vertical acceleration,
    # gravity removed
    roll_deg: float  # MSP_ATTITUDE
    pitch_deg: float  # positive nose down (Betaflight's convention)
    yaw_deg: float  # MSP_ATTITUDE's whole degree + 0.5 (it truncates)
    sim_alt_m: float  # true height above the take-off point
    sim_climb_m_s: float  # true vertical speed, up positive
    sim_tilt_deg: float  # true angle between the body z axis and the vertical
    sim_roll_deg: float  # true attitude in Betaflight's convention (as MSP_ATTITUDE)
    sim_pitch_deg: float
    sim_yaw_deg: float
    on_ground: bool  # the simulated skids touch the ground
    armed: bool
    arming_blockers: tuple[str, ...]
    flight_modes: tuple[str, ...]
    motors: tuple[float, float, float, float]  # applied motor commands 0..1, Betaflight M1..M4
    rc: RcCommand  # what the RC link is sending
    sim_north_m: float = math.nan  # true position from the start point, NED metres
    sim_east_m: float = math.nan
    #: MSP_RAW_IMU's accelerometer in m/s^2, Betaflight's FLU body axes (specific force).
    fc_accel_flu_m_s2: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    #: MSP_RAW_IMU's gyro in rad/s, the same axes (the default 2000 deg/s range's scale).
    fc_gyro_flu_rad_s: tuple[float, float, float] = (math.nan, math.nan, math.nan)
    #: The replies read in the sample's round trip (``Vehicle.read_with_samples``), by MSP
    #: command id: empty for one the FC could not answer in a batch.
    replies: Mapping[int, bytes] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class GpsPosition:
    """The FC's GPS (MSP_RAW_GPS) made local: metres from where it was at the first reading."""

    north_m: float
    east_m: float
    v_north_m_s: float  # ground speed along the ground course
    v_east_m_s: float
    has_fix: bool
    satellites: int


class _Readable(Protocol):
    """A message whose request takes no payload: its command id and how its reply decodes."""

    COMMAND: ClassVar[int]

    @classmethod
    def decode(cls, payload: bytes) -> Self: ...


_ReadableT = TypeVar("_ReadableT", bound=_Readable)
_T = TypeVar("_T")


class Vehicle:
    """The parts of a flight that only need the FC: see the module docstring.

    What is under the FC is the vehicle's :attr:`backend`: the clock, the truth, the
    disturbances and the accelerometer's scale come from it.  Subclasses start the FC side
    (:meth:`start`), set :attr:`rc` once RC flows, and say whether the FC has a GPS
    (:attr:`has_gps`).

    Args:
        backend: What is under the FC; None is a board's: wall time, no truth, nothing to
            disturb.
        progress: Called with one line of text at each step (arming waits, provisioning).
        arm_timeout_s: Seconds :meth:`arm` waits by default for the FC's blockers to clear
            and for it to arm.
        angle_mode: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
    """

    def __init__(
        self,
        *,
        backend: Backend | None = None,
        progress: Progress | None = None,
        arm_timeout_s: float = DEFAULT_ARM_TIMEOUT_S,
        angle_mode: bool = True,
    ) -> None:
        self._progress = progress or (lambda _message: None)
        self.arm_timeout_s = arm_timeout_s
        #: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
        self.angle_mode = angle_mode
        self.created_at_s = time.monotonic()
        #: What is under the FC (a board by default: wall time, no truth, nothing to disturb).
        self.backend: Backend = backend or Backend()
        self.rc: RcSender | None = None
        #: The mission clock, and how to let some of it pass (the backend's).
        self.clock: SessionClock = self.backend.clock
        #: Wall seconds from the vehicle's creation to the FC reporting armed.
        self.armed_after_s: float | None = None
        self._stack = ExitStack()
        self._ground_alt_m = 0.0
        #: Where the vehicle stood at arming (NED, the truth) and its GPS then (1e-7 deg).
        self._start_ned: tuple[float, float] = (0.0, 0.0)
        self._gps_origin_e7: tuple[int, int] | None = None
        self._base = RcCommand(aux_us=(SWITCH_OFF_US, SWITCH_OFF_US))
        #: Reads taken with each sample, in its round trip (:meth:`read_with_samples`).
        self._sample_extras: tuple[int, ...] = ()
        #: The wall time a sample last asked whether the FC side still runs, on this clock.
        self._alive_checked_s = -math.inf
        self._wall_clock: Callable[[], float] = time.monotonic

    #: The control loop rate an autopilot asks for by default: what the vehicle's MSP
    #: budget sustains (a SITL with the fast serial task: 100; a board at the default
    #: serial rate: less).
    control_rate_hz: float = 50.0
    #: The simulated quad, when bfsitl knows its physics (None: a board, or Gazebo's world):
    #: the controllers' defaults are carried over to it.
    quad: QuadParams | None = None

    # -- to be given by the kind of vehicle -----------------------------------------------------
    def start(self) -> Self:
        return self

    @property
    def client(self) -> MspClient:
        raise SitlError("the vehicle is not started")

    @property
    def has_gps(self) -> bool:
        """The firmware has a GPS (position control needs it)."""
        return False

    def check_alive(self) -> None:
        """Raise if the FC side has gone (a SITL that exited); a board says so by I/O errors."""

    @property
    def firmware(self) -> FirmwareProfile | None:
        """Who the FC is (version, conventions, GPS), once known."""
        return None

    def has_exited(self) -> bool:
        """True when the FC side has ended (a SITL process that exited)."""
        return False

    # -- what the backend gives ----------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """The mission clock: simulation time, or wall time where nothing is simulated."""
        return self.backend.time_s()

    @property
    def lockstep(self) -> bool:
        return self.backend.lockstep

    @property
    def truth(self) -> Simulator | None:
        """The simulated vehicle, to read its state; None on a board or with Gazebo.  To
        change the flight (motors, sensors, wind, RC, GPS) use :attr:`disturbances`."""
        return self.backend.simulator

    @property
    def disturbances(self) -> Disturbances:
        """What can be done to this flight from outside the FC (faults, tests)."""
        return self.backend.disturbances

    def bridge_stats(self) -> BridgeStats | None:
        return self.backend.stats()

    def _truth(self) -> Truth:
        """The truth now, positions from where the vehicle stood at arming (NaN: unknown)."""
        truth = self.backend.truth()
        if truth is None:
            return Truth.unknown(self.time_s)
        north0_m, east0_m = self._start_ned
        return Truth(
            truth.time_s,
            truth.altitude_m,
            truth.climb_m_s,
            truth.tilt_deg,
            truth.attitude_deg,
            truth.on_ground,
            truth.motors,
            truth.north_m - north0_m,
            truth.east_m - east0_m,
        )

    def _start_rc(self, rc: RcSender) -> None:
        """Send the sticks at disarm on ``rc`` from now on; it closes first on the way out,
        so its disarm goes out before anything else stops."""
        rc.set(self._base)
        rc.start()
        self.rc = rc
        self._stack.callback(rc.close)

    # -- lifecycle --------------------------------------------------------------------------------
    def close(self) -> None:
        """Stop in reverse order of starting (the RC link first: disarm goes out).  Safe to
        call twice."""
        self._stack.close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def on_close(self, callback: Callable[[], object]) -> None:
        """Call ``callback`` when the vehicle closes (before the RC link, bridge and SITL
        stop): an autopilot's log is closed with the vehicle it records.

        Args:
            callback: Called with no arguments; what it returns is ignored.
        """
        self._stack.callback(callback)

    # -- parts ------------------------------------------------------------------------
    @property
    def fc(self) -> MspClient:
        """The flight controller's MSP client (the vehicle's name for :attr:`client`)."""
        return self.client

    # -- RC ----------------------------------------------------------------------------------
    @property
    def rc_command(self) -> RcCommand:
        return self.rc.command if self.rc is not None else self._base

    def set_rc(self, command: RcCommand) -> None:
        """Send ``command`` from now on, until the next call.

        Args:
            command: The sticks and switches, in microseconds of pulse width.

        Raises:
            SitlError: The vehicle is not started (no RC link yet).
        """
        if self.rc is None:
            raise SitlError("the vehicle is not started")
        self.rc.set(command)

    def set_throttle(self, throttle_us: float) -> None:
        """Throttle only; the switches stay as :meth:`arm` / :meth:`disarm` left them.

        Args:
            throttle_us: The throttle channel's pulse width, microseconds; clamped to 1000
                to 2000 when sent.

        Raises:
            SitlError: The vehicle is not started (no RC link yet).
        """
        self.set_rc(self.rc_command.with_throttle(throttle_us))

    # -- arming ------------------------------------------------------------------------------
    def arm(self, timeout_s: float | None = None) -> None:
        """Wait until nothing blocks arming, raise the ARM switch, wait for ARMED.

        Args:
            timeout_s: Seconds of the vehicle's clock to wait, for the blockers and the
                arming together; None takes ``arm_timeout_s`` (15 by default).

        Raises:
            ArmingBlockedError: It did not arm in time (``blockers`` names what blocked it),
                or at once when no ARM mode range would react to the switch (a case the
                firmware has no flag for: it simply never arms).
            SitlExitedError: The SITL ended while waiting.
            MspError: The FC stopped answering.
        """
        timeout_s = self.arm_timeout_s if timeout_s is None else timeout_s
        client = self.client
        arm_ranges = [r for r in client.mode_ranges().ranges if r.is_used and r.box_id == BoxId.ARM]
        if not any(
            r.aux_channel_index == 0 and r.start_us <= SWITCH_ON_US < r.end_us for r in arm_ranges
        ):
            found = (
                ", ".join(
                    f"AUX{r.aux_channel_index + 1} {r.start_us}-{r.end_us} us" for r in arm_ranges
                )
                or "none"
            )
            raise ArmingBlockedError(
                f"no ARM mode range on AUX1 covers {SWITCH_ON_US} us (ARM ranges: {found}); "
                f"provision with the default profile or add `aux 0 0 0 1700 2100 0 0`",
                ("NO_ARM_RANGE",),
            )
        clock = self.clock
        deadline = clock.now_s() + timeout_s
        blockers = self._wait_unblocked(deadline)
        if blockers:
            raise self._blocked_error(blockers, timeout_s)
        aux2 = SWITCH_ON_US if self.angle_mode else SWITCH_OFF_US
        self.set_rc(replace(self.rc_command, throttle_us=RC_MIN_US, aux_us=(SWITCH_ON_US, aux2)))
        while clock.now_s() < deadline:
            self.check_alive()
            status = client.status()
            if status.armed:
                self.armed_after_s = time.monotonic() - self.created_at_s
                truth = self._truth()
                self._ground_alt_m = truth.altitude_m if math.isfinite(truth.altitude_m) else 0.0
                if math.isfinite(truth.north_m):
                    # Positions count from the take-off point, like altitudes.
                    self._start_ned = (
                        self._start_ned[0] + truth.north_m,
                        self._start_ned[1] + truth.east_m,
                    )
                if self.has_gps:
                    self._gps_origin_e7 = None
                    self.gps_position()  # the FC's GPS here is the origin from now on
                return
            clock.sleep_s(_POLL_INTERVAL_S)
        self.set_rc(replace(self.rc_command, aux_us=(SWITCH_OFF_US, SWITCH_OFF_US)))
        names = tuple(b.cli_name for b in client.status().arming_blockers)
        raise self._blocked_error(names or ("UNKNOWN",), timeout_s)

    def _wait_unblocked(self, deadline_s: float) -> tuple[str, ...]:
        """Blockers left at the deadline (empty when it may arm); reports each change."""
        seen: tuple[str, ...] | None = None
        while True:
            self.check_alive()
            names = tuple(b.cli_name for b in self.client.status().arming_blockers)
            if names != seen:
                if names:
                    self._progress("waiting for the FC: " + ", ".join(names))
                seen = names
            if not names or self.clock.now_s() >= deadline_s:
                return names
            self.clock.sleep_s(_POLL_INTERVAL_S)

    @staticmethod
    def _blocked_error(names: tuple[str, ...], timeout_s: float) -> ArmingBlockedError:
        from bfsitl.protocol.arming import all_arming_flags

        fixes = {info.cli_name: info.fix for info in all_arming_flags()}
        explained = "; ".join(f"{name}: {fixes.get(name, 'see `bfsitl doctor`')}" for name in names)
        return ArmingBlockedError(
            f"the FC did not arm within {timeout_s:.0f} s, blocked by {explained}", names
        )

    def disarm(self, timeout_s: float = 3.0) -> bool:
        """Throttle low, both switches off, and wait for the FC to report it.

        Args:
            timeout_s: Seconds of the vehicle's clock to wait for the FC to disarm.

        Returns:
            True once the FC reports disarmed; False if it still reports armed at the end.

        Raises:
            SitlExitedError: The SITL ended while waiting.
            MspError: The FC stopped answering.
        """
        self.set_rc(
            replace(self.rc_command, throttle_us=RC_MIN_US, aux_us=(SWITCH_OFF_US, SWITCH_OFF_US))
        )
        deadline = self.clock.now_s() + timeout_s
        while self.clock.now_s() < deadline:
            self.check_alive()
            if not self.client.status().armed:
                return True
            self.clock.sleep_s(_POLL_INTERVAL_S)
        return False

    # -- observation -------------------------------------------------------------------------
    def telemetry(self) -> Telemetry:
        return self._asked(self.client.telemetry)

    def _asked(self, read: Callable[..., _T], *args: object) -> _T:
        """``read(*args)`` of the FC; when it fails, a dead SITL explains itself better than
        a lost reply."""
        try:
            return read(*args)
        except (LinkError, MspError):
            self.check_alive()
            raise

    def read_with_samples(self, *message_types: type[_Readable]) -> None:
        """Take these parameterless reads in each :meth:`sample`'s round trip from now on
        (MSP_MULTIPLE_MSP), kept in the sample's ``replies``, so that :meth:`reading` of
        that sample needs no round trip of its own: what a control loop reads every step
        (the GPS, the debug values) costs one exchange with the FC instead of several.

        Args:
            message_types: Message classes of :mod:`bfsitl.protocol.messages` whose request
                takes no payload (``msg.RawGps``, ``msg.Debug``).
        """
        for message_type in message_types:
            if message_type.COMMAND not in self._sample_extras:
                self._sample_extras = (*self._sample_extras, message_type.COMMAND)

    def reading(
        self, message_type: type[_ReadableT], sample: FlightSample | None = None
    ) -> _ReadableT:
        """``message_type``'s reply: the one taken with ``sample`` when it was asked for
        (:meth:`read_with_samples`), else one round trip now.

        Args:
            message_type: A message class whose request takes no payload.
            sample: The sample whose round trip may hold it.

        Returns:
            The decoded reply.
        """
        payload = sample.replies.get(message_type.COMMAND) if sample is not None else None
        if payload:  # empty: the FC could not answer it in a batch; asked alone it says why
            return message_type.decode(payload)
        return self.client.get(message_type)

    def sample(self) -> FlightSample:
        """The FC's view (one MSP round trip, with the reads of :meth:`read_with_samples`)
        and the simulated truth."""
        # Asked at most every ALIVE_CHECK_S of wall time: a lockstep flight samples every
        # fraction of a millisecond, and a FC side that ended fails the round trip anyway,
        # which asks at once (_asked).
        now_s = self._wall_clock()
        if now_s - self._alive_checked_s >= ALIVE_CHECK_S:
            self.check_alive()
            self._alive_checked_s = now_s
        extras = self._sample_extras
        payloads = self._asked(self.client.multiple, (*SAMPLE_COMMANDS, *extras))
        box_ids = self.client.box_ids()
        attitude = msg.Attitude.decode(payloads[0])
        altitude = msg.Altitude.decode(payloads[1])
        status = msg.StatusEx.decode(payloads[2])
        raw_imu = msg.RawImu.decode(payloads[3])
        # The backend's truth, made local here (as _truth does) without a second Truth.
        truth = self.backend.truth()
        if truth is None:
            truth = Truth.unknown(self.time_s)
        north0_m, east0_m = self._start_ned
        imu = self.backend.imu
        return FlightSample(
            time_s=truth.time_s,
            wall_s=time.monotonic(),
            fc_alt_m=altitude.altitude_m,
            fc_climb_m_s=altitude.vario_m_s,
            fc_accel_up_m_s2=vertical_accel_m_s2(
                attitude, raw_imu, imu.acc_1g_lsb, imu.acc_truncation_lsb
            ),
            fc_accel_flu_m_s2=accel_flu_m_s2(raw_imu, imu),
            fc_gyro_flu_rad_s=_gyro_flu_rad_s(raw_imu),
            roll_deg=attitude.roll_deg,
            pitch_deg=attitude.pitch_deg,
            # MSP_ATTITUDE truncates the heading to whole degrees: the middle of the degree
            # is the unbiased reading.
            yaw_deg=float(attitude.yaw_deg) + 0.5,
            sim_alt_m=truth.altitude_m - self._ground_alt_m,
            sim_climb_m_s=truth.climb_m_s,
            sim_tilt_deg=truth.tilt_deg,
            sim_roll_deg=truth.attitude_deg[0],
            sim_pitch_deg=truth.attitude_deg[1],
            sim_yaw_deg=truth.attitude_deg[2],
            on_ground=truth.on_ground,
            armed=status.armed,
            arming_blockers=blocker_names(status),
            flight_modes=mode_names(status, box_ids),
            motors=truth.motors,
            rc=self.rc_command,
            sim_north_m=truth.north_m - north0_m,
            sim_east_m=truth.east_m - east0_m,
            replies=dict(zip(extras, payloads[len(SAMPLE_COMMANDS) :], strict=True)),
        )

    def gps_position(self, sample: FlightSample | None = None) -> GpsPosition:
        """The FC's GPS, local to its first reading since the vehicle started (taken with
        ``sample`` when :meth:`read_with_samples` asked for ``msg.RawGps``, else one round
        trip).

        Only GPS builds answer (``bfsitl firmware build --gps`` for 4.6.0; master has it):
        others raise :class:`MspErrorReply`.  The conversion is the FC's flat-earth one, good
        to centimetres over a flying field.

        Args:
            sample: The sample whose round trip may hold the GPS (None: read it now).

        Returns:
            Metres north and east of the origin, the ground velocity, the fix and the
            satellites.
        """
        return self.local_gps(self.reading(msg.RawGps, sample))

    def local_gps(self, gps: msg.RawGps) -> GpsPosition:
        """An MSP_RAW_GPS reply made local, as :meth:`gps_position` does (for a caller that
        asked for it in a batch of its own); its first fix becomes the origin.

        Args:
            gps: The decoded MSP_RAW_GPS reply.

        Returns:
            Metres north and east of the origin, the ground velocity, the fix and the
            satellites.
        """
        if self._gps_origin_e7 is None and gps.has_fix:
            self._gps_origin_e7 = (gps.lat_e7, gps.lon_e7)
        lat0, lon0 = self._gps_origin_e7 or (gps.lat_e7, gps.lon_e7)
        cos_lat = math.cos(math.radians(lat0 * 1e-7))
        course = math.radians(gps.course_decideg / 10.0)
        speed = gps.ground_speed_m_s
        return GpsPosition(
            north_m=(gps.lat_e7 - lat0) * 1e-7 * METRES_PER_DEGREE,
            east_m=(gps.lon_e7 - lon0) * 1e-7 * METRES_PER_DEGREE * cos_lat,
            v_north_m_s=speed * math.cos(course),
            v_east_m_s=speed * math.sin(course),
            has_fix=gps.has_fix,
            satellites=gps.satellites,
        )

    def rc_stats(self) -> RcLinkStats | None:
        return self.rc.stats() if self.rc is not None else None
