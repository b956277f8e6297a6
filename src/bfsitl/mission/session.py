"""A flight session: one SITL, the embedded physics, a provisioned FC and an RC link.

The order of things is what makes a SITL flight reliable (``shared/FIRMWARE_FACTS.md``):

1. the physics bridge binds its motor port, then the SITL starts in its own network namespace
   and is *probed* until it answers MSP (never a fixed sleep);
2. the bridge starts feeding fdm packets (without them ANGLE blocks arming forever);
3. the FC is provisioned (ARM on AUX1, ANGLE on AUX2) by MSP, saved without a reboot; if a
   user's CLI line needs one, the process ends and is restarted on the same run directory;
4. only now the UDP RC stream starts: an rc packet that reaches 4.6.0 while it boots leaves it
   in RXLOSS forever;
5. :meth:`FlightSession.arm` waits until the FC's own blockers clear (boot grace, calibration),
   then raises the ARM switch.

With a ``--lockstep`` build (:mod:`bfsitl.sim.lockstep`) steps 2 and 4 change: the SITL boots,
answers and is provisioned while its clock free-runs, then the lockstep bridge takes over: the
physics steps only when asked, RC rides in the fdm packets, MSP requests step the simulation
until they are answered, and the mission's waits are steps too (:attr:`FlightSession.clock`).

On the way out everything stops in reverse: the RC link sends disarm and low throttle (the
SITL holds the last sticks forever when UDP goes quiet), then the bridge stops, then the SITL.
That happens on success, on any exception and on Ctrl-C alike.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Protocol

from bfsitl.errors import (
    ArmingBlockedError,
    BfsitlError,
    LinkError,
    MspError,
    MspErrorReply,
    SitlError,
    SitlExitedError,
)
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.fc.msp_client import MspClient, Telemetry
from bfsitl.fc.provisioning import (
    ANGLE_ON_AUX2,
    ARM_ON_AUX1,
    Profile,
    ProvisionResult,
    provision,
)
from bfsitl.fc.rc_link import RC_MIN_US, RcCommand, RcLinkStats, UdpRcLink
from bfsitl.protocol import msp_messages as msg
from bfsitl.protocol.boxes import BoxId
from bfsitl.sim import Simulator
from bfsitl.sim.bridge import BridgeStats, SitlBridge, bridged_sitl, wait_for_replies
from bfsitl.sim.frames import betaflight_attitude_deg
from bfsitl.sim.health import HealthMonitor, lock_clock
from bfsitl.sim.lockstep import LockstepBridge, LockstepClock, LockstepRc, SteppedLink
from bfsitl.sim.params import Wind
from bfsitl.sim.sensors import SensorConfig
from bfsitl.sitl.process import SitlProcess

#: What ``bfsitl fly`` provisions: ARM on AUX1 and self-levelling (ANGLE) on AUX2.
FLY_PROFILE = Profile(mode_ranges=(ARM_ON_AUX1, ANGLE_ON_AUX2))
#: The serial task at 1 kHz instead of the default 100 Hz: an MSP reply then waits at most
#: 1 ms of FC time for the task that answers it, where a 100 Hz task caps a control loop of
#: one sample per step at 100 steps/s.  The firmware reads it at boot only, so a run directory
#: that does not hold it yet costs one reboot (1.6 s more to arm at 1x on a stock SITL).
FAST_SERIAL_LINE = "set serial_update_rate_hz = 1000"
#: Control rates above this get FAST_SERIAL_LINE from ``bfsitl fly`` (``with_fast_serial``).
FAST_SERIAL_ABOVE_HZ = 50.0


def with_fast_serial(profile: Profile) -> Profile:
    """``profile`` plus :data:`FAST_SERIAL_LINE` (once)."""
    if FAST_SERIAL_LINE in profile.cli_lines:
        return profile
    return dataclasses.replace(profile, cli_lines=(*profile.cli_lines, FAST_SERIAL_LINE))
#: Switch positions sent for "on": inside the 1700-2100 us ranges above, with margin.
SWITCH_ON_US = 1800
SWITCH_OFF_US = RC_MIN_US
#: The FC's boot grace is 5 s of FC time; calibration and the first fdm packets add a little.
DEFAULT_ARM_TIMEOUT_S = 15.0
_POLL_INTERVAL_S = 0.05
#: See SessionConfig.sensors; measured: FC altitude within 1-2 cm of the truth on average.
DEFAULT_BARO_NOISE_PA = 0.5
#: Accelerometer noise by default, m/s^2 per physics step.  sitl.c truncates the fdm's
#: acceleration to whole LSB (0.038 m/s^2); without noise a hovering vehicle's reading sits
#: on one side of a step, an error of up to one LSB that integrating it turns into drift (it
#: was 2-3 cm/s after a few seconds of hover).  0.05 m/s^2 (about 5 mg, less than a real MEMS
#: accelerometer shows) dithers the steps so they average out.
DEFAULT_ACCEL_NOISE_M_S2 = 0.05


def fly_sensors(*, baro_noise_std_pa: float | None = None,
                accel_noise_std_m_s2: float | None = None) -> SensorConfig:
    """The sensor errors ``bfsitl fly`` simulates by default; a value given replaces one."""
    return SensorConfig(
        baro_noise_std_pa=(DEFAULT_BARO_NOISE_PA if baro_noise_std_pa is None
                           else baro_noise_std_pa),
        accel_noise_std_m_s2=(DEFAULT_ACCEL_NOISE_M_S2 if accel_noise_std_m_s2 is None
                              else accel_noise_std_m_s2))

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class SessionConfig:
    """Everything a session needs to know before it starts; all of it has a default."""

    firmware: str | Path | None = None
    #: Run directory of the SITL; its ``eeprom.bin`` persists.  None: a fresh temporary one.
    workdir: str | Path | None = None
    #: Run the SITL in a private network namespace (so a stale SITL cannot share its ports).
    isolate: bool = True
    #: Simulation speed, x wall time.  None: real time (1.0) with a stock SITL, as fast as
    #: possible with a lockstep build.  Real time allows 0.05..4 (0.5 is the faithful speed on
    #: a busy 2-core machine, see the README); lockstep any positive speed, ``math.inf`` = max.
    speed: float | None = None
    #: Lockstep (a ``--lockstep`` build is needed).  None: whenever the firmware is one.
    lockstep: bool | None = None
    #: What to provision.  None flies with whatever the FC already holds.
    profile: Profile | None = FLY_PROFILE
    #: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
    angle_mode: bool = True
    #: Barometer and accelerometer noise by default (:func:`fly_sensors`): 4.6.0 SITL
    #: truncates the fdm pressure to whole pascals (~8.3 cm of altitude), so a noiseless
    #: barometer gives the FC a staircase it cannot resolve inside a step.  Half a pascal of
    #: noise (about what a board's barometer shows) dithers it: the FC's own filter then
    #: averages to the true sub-pascal value.  The accelerometer likewise.
    sensors: SensorConfig = field(default_factory=fly_sensors)
    arm_timeout_s: float = DEFAULT_ARM_TIMEOUT_S
    #: "embedded" (bfsitl's simulator and bridge) or "gazebo" (``gz sim`` with the
    #: BetaflightPlugin, started in the SITL's namespace; no simulated truth is then known).
    physics: str = "embedded"
    #: Where libBetaflightPlugin.so is, for ``physics="gazebo"`` (default: the search path).
    gz_plugin_dir: str | Path | None = None
    #: Wind and gusts of the embedded physics (None: still air).
    wind: Wind | None = None
    #: Seeds the sensor noise and the gusts: the same seed gives the same disturbances.
    seed: int = 0


class SessionClock(Protocol):
    """The mission clock (simulation time) and how to let some of it pass."""

    def now_s(self) -> float: ...

    def sleep_s(self, seconds: float) -> None: ...


class RealTimeClock:
    """A real-time session's clock: the physics runs on its own thread at ``speed`` x wall
    time, so letting simulation time pass is a wall-clock sleep."""

    def __init__(self, session: FlightSession) -> None:
        self.session = session

    def now_s(self) -> float:
        return self.session.time_s

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            speed = self.session.real_time_speed if self.session.simulator is not None else 1.0
            time.sleep(seconds / speed)


@dataclass(frozen=True, slots=True)
class FlightSample:
    """One look at the flight: what the FC reports next to the simulated truth."""

    time_s: float               # simulation time: the mission clock
    wall_s: float               # time.monotonic() when the sample was taken
    fc_alt_m: float             # MSP_ALTITUDE, up positive, zeroed by the FC at arming
    fc_climb_m_s: float         # MSP_ALTITUDE vario, up positive
    fc_accel_up_m_s2: float     # MSP_RAW_IMU z and MSP_ATTITUDE: vertical acceleration,
                                # gravity removed
    roll_deg: float             # MSP_ATTITUDE
    pitch_deg: float            # positive nose down (Betaflight's convention)
    yaw_deg: float              # MSP_ATTITUDE's whole degree + 0.5 (it truncates)
    sim_alt_m: float            # true height above the take-off point
    sim_climb_m_s: float        # true vertical speed, up positive
    sim_tilt_deg: float         # true angle between the body z axis and the vertical
    sim_roll_deg: float         # true attitude in Betaflight's convention (as MSP_ATTITUDE)
    sim_pitch_deg: float
    sim_yaw_deg: float
    on_ground: bool             # the simulated skids touch the ground
    armed: bool
    arming_blockers: tuple[str, ...]
    flight_modes: tuple[str, ...]
    motors: tuple[float, float, float, float]  # applied motor commands 0..1, Betaflight M1..M4
    rc: RcCommand               # what the RC link is sending
    sim_north_m: float = math.nan  # true position from the start point, NED metres
    sim_east_m: float = math.nan


@dataclass(frozen=True, slots=True)
class GpsPosition:
    """The FC's GPS (MSP_RAW_GPS) made local: metres from where it was at the first reading."""

    north_m: float
    east_m: float
    v_north_m_s: float       # ground speed along the ground course
    v_east_m_s: float
    has_fix: bool
    satellites: int


@dataclass(frozen=True, slots=True)
class _Truth:
    time_s: float
    altitude_m: float
    climb_m_s: float
    tilt_deg: float
    attitude_deg: tuple[float, float, float]  # Betaflight's roll, pitch, yaw
    on_ground: bool
    motors: tuple[float, float, float, float]
    north_m: float = math.nan
    east_m: float = math.nan


#: Metres per degree of latitude (and of longitude at the equator): the FC's own figure
#: (``EARTH_RADIUS`` based, gps.c), which is what makes its GPS local.
METRES_PER_DEGREE = 111_319.5


class FlightSession:
    """Start, provision, arm and feed one simulated flight; stop all of it on the way out.

    >>> with FlightSession() as session:                    # doctest: +SKIP
    ...     session.arm()
    ...     session.set_throttle(1550)
    ...     print(session.sample().sim_alt_m)
    """

    def __init__(self, config: SessionConfig | None = None, *,
                 progress: Progress | None = None) -> None:
        self.config = config or SessionConfig()
        speed = self.config.speed
        if speed is not None and not (speed > 0 and not math.isnan(speed)):
            raise BfsitlError(f"speed {speed} must be a positive number")
        self._progress = progress or (lambda _message: None)
        self.created_at_s = time.monotonic()
        self.sitl: SitlProcess | None = None
        self.simulator: Simulator | None = None
        self.bridge: SitlBridge | LockstepBridge | None = None
        self.rc: UdpRcLink | LockstepRc | None = None
        #: The mission clock: simulation time, and how to let some of it pass.
        self.clock: SessionClock = RealTimeClock(self)
        self.provisioned: ProvisionResult | None = None
        #: Wall seconds from the session's creation to the FC reporting armed.
        self.armed_after_s: float | None = None
        self._stack = ExitStack()
        self._ground_alt_m = 0.0
        #: Where the vehicle stood at arming (NED, the truth) and its GPS then (1e-7 deg).
        self._start_ned: tuple[float, float] = (0.0, 0.0)
        self._gps_origin_e7: tuple[int, int] | None = None
        self._base = RcCommand(aux_us=(SWITCH_OFF_US, SWITCH_OFF_US))

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> FlightSession:
        config = self.config
        try:
            if config.physics == "gazebo":
                self._start_with_gazebo()
            elif config.physics == "embedded":
                self.sitl = SitlProcess(config.firmware, workdir=config.workdir,
                                        isolate=config.isolate, progress=self._progress)
                self.simulator = Simulator(sensors=config.sensors, wind=config.wind,
                                           seed=config.seed)
                if self._wants_lockstep():
                    self._start_lockstep()
                    return self
                speed = self.real_time_speed
                self.bridge = self._stack.enter_context(
                    bridged_sitl(self.sitl, self.simulator, speed=speed))
                self._progress(f"physics running at {speed:g}x real time")
            else:
                raise BfsitlError(f"unknown physics {config.physics!r}: embedded or gazebo")
            assert self.sitl is not None
            if self.real_time_speed != 1.0 and isinstance(self.bridge, SitlBridge):
                self._progress(f"locking the firmware clock to {self.real_time_speed:g}x")
                lock_clock(HealthMonitor(self.bridge, self.client))
            if config.profile is not None:
                self.provisioned = provision(self.client, self._flight_profile(config.profile),
                                             reboot=self._reboot)
                self._progress("provisioned: " + (
                    "written and saved" + (", rebooted" if self.provisioned.rebooted else "")
                    if self.provisioned.changed else "already configured, nothing written"))
            # Only now: an RC packet during boot leaves 4.6.0 in RXLOSS for good.
            assert self.sitl.network is not None
            self.rc = UdpRcLink(self.sitl.network)
            self.rc.set(self._base)
            self.rc.start()
            self._stack.callback(self.rc.close)  # closes first: disarm goes out before the rest
        except BaseException:
            self.close()
            raise
        return self

    @property
    def real_time_speed(self) -> float:
        """The speed of a real-time (not lockstep) session, checked against its range."""
        speed = 1.0 if self.config.speed is None else self.config.speed
        if not 0.05 <= speed <= 4.0:
            raise BfsitlError(
                f"speed {speed:g} is outside 0.05..4 for a stock SITL, which runs on the wall "
                f"clock; faster (or --speed max) needs a lockstep build: `bfsitl firmware "
                f"build --lockstep`, then --firmware with its name")
        return speed

    def _wants_lockstep(self) -> bool:
        assert self.sitl is not None
        is_lockstep = self.sitl.firmware.lockstep
        if self.config.lockstep and not is_lockstep:
            raise BfsitlError(
                f"lockstep asked for, but {self.sitl.firmware.path} is not a lockstep build: "
                f"build one with `bfsitl firmware build --lockstep` and pass its name")
        return is_lockstep if self.config.lockstep is None else self.config.lockstep

    def _start_lockstep(self) -> None:
        """The SITL locked to the physics from its first pass (see the module doc)."""
        config, sitl, simulator = self.config, self.sitl, self.simulator
        assert sitl is not None and simulator is not None
        speed = None if config.speed is None or math.isinf(config.speed) else config.speed
        bridge = LockstepBridge(simulator, sitl.prepare_network(), speed=speed,
                                profile=profile_of_binary(sitl.firmware.path))
        self.bridge = bridge
        bridge.bind()
        self._stack.callback(bridge.close)
        bridge.alive = self.check_alive  # a wait that runs long asks whether the SITL ended
        sitl.on_spawn = bridge.lock
        sitl.link_wrapper = lambda link: SteppedLink(link, bridge)
        sitl.client_clock = lambda: bridge.sim_time_s
        self.clock = LockstepClock(bridge)
        self._stack.callback(sitl.stop)
        sitl.start()
        bridge.set_profile(sitl.profile)
        pace = "as fast as it goes" if speed is None else f"paced to {speed:g}x real time"
        self._progress(f"lockstep: the FC's clock follows the physics, {pace}")
        if config.profile is not None:
            self.provisioned = provision(self.client, self._flight_profile(config.profile),
                                         reboot=self._reboot)
            self._progress("provisioned: " + (
                "written and saved" + (", rebooted" if self.provisioned.rebooted else "")
                if self.provisioned.changed else "already configured, nothing written"))
        self.rc = LockstepRc(bridge)
        self.rc.set(self._base)
        self._stack.callback(self.rc.close)  # closes first: disarm is stepped in before the rest

    def _start_with_gazebo(self) -> None:
        """``gz sim`` with the BetaflightPlugin in the SITL's network, then the SITL.

        Gazebo starts first and must have bound UDP 9002 before the SITL boots, as in the
        tutorial; both live in the same namespace because both ends use fixed loopback ports.
        """
        from bfsitl.gazebo import (
            check_gazebo,
            check_plugin_port_free,
            plan_gazebo_launch,
            stop_gazebo,
            wait_for_plugin,
        )
        from bfsitl.gazebo.world import world_for_profile

        config = self.config
        if config.speed not in (None, 1.0):
            raise BfsitlError("--speed applies to the embedded physics only; Gazebo sets its "
                              "own pace")
        install = check_gazebo(config.gz_plugin_dir)  # fails early, with the fix, first
        self.sitl = SitlProcess(config.firmware, workdir=config.workdir,
                                isolate=config.isolate, progress=self._progress)
        sitl = self.sitl
        self._stack.callback(sitl.stop)  # runs last: after Gazebo has stopped
        if sitl.firmware.lockstep:
            raise BfsitlError(
                f"{sitl.firmware.path} is a lockstep build: its clock follows bfsitl's "
                f"own physics, and Gazebo's plugin reads only stock motor packets. Use a "
                f"stock build with --physics gazebo")
        # Gazebo starts before the SITL can say who it is: the binary's profile (its build
        # record, else its bytes) picks the world's frame transform and motor channels.
        world = world_for_profile(profile_of_binary(sitl.firmware.path), sitl.workdir)
        launch = plan_gazebo_launch(world, install=install)
        network = sitl.prepare_network()
        check_plugin_port_free(network)
        self._progress(f"starting Gazebo: {launch.command_line()}")
        gazebo = network.spawn(launch.argv, sitl.workdir, sitl.workdir / "gazebo.log",
                               env=launch.env_dict())
        self._stack.callback(stop_gazebo, gazebo)
        wait_for_plugin(network, gazebo)
        sitl.start()

    def close(self) -> None:
        """RC link (disarm sent), bridge, SITL: stopped in that order.  Safe to call twice."""
        self._stack.close()

    def __enter__(self) -> FlightSession:
        return self.start()

    def __exit__(self, *exc_info: object) -> None:
        self.close()

    def _reboot(self) -> None:
        """A CLI line needed a reboot: in SITL the process ends, so start it again."""
        assert self.sitl is not None
        self._progress("the configuration needs a reboot; restarting the SITL")
        bridge = self.bridge if isinstance(self.bridge, SitlBridge) else None
        if bridge is not None:
            bridge.pause()
        self.client.reboot()
        if self.lockstep:
            # The FC acts on the reboot in a later pass: step until the process has ended.
            try:
                self.clock.sleep_s(10.0)
            except SitlExitedError:
                pass
        self.sitl.restart_after_reboot()
        if bridge is not None:
            bridge.resume()
            wait_for_replies(bridge)

    def on_close(self, callback: Callable[[], object]) -> None:
        """Call ``callback`` when the session closes (before the RC link, bridge and SITL
        stop): an autopilot's log is closed with the vehicle it records."""
        self._stack.callback(callback)

    # -- parts -------------------------------------------------------------------------------
    @property
    def fc(self) -> MspClient:
        """The flight controller's MSP client (the vehicle's name for :attr:`client`)."""
        return self.client

    @property
    def truth(self) -> Simulator | None:
        """The simulated vehicle (its state is the truth), or None with external physics."""
        return self.simulator

    @property
    def client(self) -> MspClient:
        """The FC's MSP client; in lockstep its waits step the simulation."""
        if self.sitl is None or self.sitl.client is None:
            raise SitlError("the session is not started")
        return self.sitl.client

    @property
    def has_gps(self) -> bool:
        """The firmware has a GPS (position control needs it)."""
        return self.sitl is not None and self.sitl.profile.has_gps

    @property
    def lockstep(self) -> bool:
        return isinstance(self.clock, LockstepClock)

    @property
    def time_s(self) -> float:
        """The mission clock: simulation time (wall time since start with Gazebo)."""
        if self.simulator is not None:
            return self.simulator.time_s
        return time.monotonic() - self.created_at_s

    def check_alive(self) -> None:
        """Raise :class:`SitlExitedError` (with the log tail) if the SITL or bridge has died."""
        if self.sitl is None:
            raise SitlError("the session is not started")
        code = self.sitl.poll()
        if code is not None:
            raise SitlExitedError(
                f"the SITL exited with code {code} during the flight; its log "
                f"({self.sitl.log_path}) ends with:\n{self.sitl.log_tail()}",
                code, self.sitl.log_tail())
        if self.bridge is not None and self.bridge.error is not None:
            raise SitlError(f"the physics bridge failed: {self.bridge.error!r}")

    # -- RC ----------------------------------------------------------------------------------
    @property
    def rc_command(self) -> RcCommand:
        return self.rc.command if self.rc is not None else self._base

    def set_rc(self, command: RcCommand) -> None:
        if self.rc is None:
            raise SitlError("the session is not started")
        self.rc.set(command)

    def set_throttle(self, throttle_us: float) -> None:
        """Throttle only; the switches stay as :meth:`arm` / :meth:`disarm` left them."""
        self.set_rc(replace(self.rc_command, throttle_us=throttle_us))

    # -- arming ------------------------------------------------------------------------------
    def arm(self, timeout_s: float | None = None) -> None:
        """Wait until nothing blocks arming, raise the ARM switch, wait for ARMED.

        Raises :class:`ArmingBlockedError` naming the blockers if it does not arm in time,
        and at once if no ARM mode range would react to the switch (a case the firmware has
        no flag for: it simply never arms).
        """
        timeout_s = self.config.arm_timeout_s if timeout_s is None else timeout_s
        client = self.client
        arm_ranges = [r for r in client.mode_ranges().ranges
                      if r.is_used and r.box_id == BoxId.ARM]
        if not any(r.aux_channel_index == 0 and r.start_us <= SWITCH_ON_US < r.end_us
                   for r in arm_ranges):
            found = ", ".join(f"AUX{r.aux_channel_index + 1} {r.start_us}-{r.end_us} us"
                              for r in arm_ranges) or "none"
            raise ArmingBlockedError(
                f"no ARM mode range on AUX1 covers {SWITCH_ON_US} us (ARM ranges: {found}); "
                f"provision with the default profile or add `aux 0 0 0 1700 2100 0 0`",
                ("NO_ARM_RANGE",))
        clock = self.clock
        deadline = clock.now_s() + timeout_s
        blockers = self._wait_unblocked(deadline)
        if blockers:
            raise self._blocked_error(blockers, timeout_s)
        aux2 = SWITCH_ON_US if self.config.angle_mode else SWITCH_OFF_US
        self.set_rc(replace(self.rc_command, throttle_us=RC_MIN_US,
                            aux_us=(SWITCH_ON_US, aux2)))
        while clock.now_s() < deadline:
            self.check_alive()
            status = client.status()
            if status.armed:
                self.armed_after_s = time.monotonic() - self.created_at_s
                truth = self._truth()
                self._ground_alt_m = truth.altitude_m if math.isfinite(truth.altitude_m) else 0.0
                if math.isfinite(truth.north_m):
                    # Positions count from the take-off point, like altitudes.
                    self._start_ned = (self._start_ned[0] + truth.north_m,
                                       self._start_ned[1] + truth.east_m)
                if self.sitl is not None and self.sitl.profile.has_gps:
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
        explained = "; ".join(f"{name}: {fixes.get(name, 'see `bfsitl doctor`')}"
                              for name in names)
        return ArmingBlockedError(f"the FC did not arm within {timeout_s:.0f} s, blocked by "
                                  f"{explained}", names)

    def disarm(self, timeout_s: float = 3.0) -> bool:
        """Throttle low, both switches off; True once the FC reports disarmed."""
        self.set_rc(replace(self.rc_command, throttle_us=RC_MIN_US,
                            aux_us=(SWITCH_OFF_US, SWITCH_OFF_US)))
        deadline = self.clock.now_s() + timeout_s
        while self.clock.now_s() < deadline:
            self.check_alive()
            if not self.client.status().armed:
                return True
            self.clock.sleep_s(_POLL_INTERVAL_S)
        return False

    # -- observation -------------------------------------------------------------------------
    def _truth(self) -> _Truth:
        if self.bridge is None or self.simulator is None:  # external physics: truth unknown
            nan = math.nan
            return _Truth(self.time_s, nan, nan, nan, (nan, nan, nan), False,
                          (nan, nan, nan, nan))
        simulator, bridge = self.simulator, self.bridge

        def read() -> _Truth:
            state = simulator.state
            w, x, y, z = state.quaternion_wxyz
            # Body z in world NED has z component 1 - 2(x^2 + y^2): cos(tilt).
            cos_tilt = max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y)))
            north, east, _down = state.position_ned_m
            return _Truth(state.time_s, simulator.altitude_m, -state.velocity_ned_m_s[2],
                          math.degrees(math.acos(cos_tilt)),
                          betaflight_attitude_deg(state.quaternion_wxyz), simulator.on_ground,
                          tuple(bridge.motors),  # type: ignore[arg-type]
                          north - self._start_ned[0], east - self._start_ned[1])

        # On the bridge thread, between two steps: one consistent state.
        return bridge.between_steps(read)

    def telemetry(self) -> Telemetry:
        try:
            return self.client.telemetry()
        except (LinkError, MspError):
            self.check_alive()  # a dead SITL explains itself better than a lost reply
            raise

    def sample(self) -> FlightSample:
        """The FC's view (one MSP round trip) and the simulated truth."""
        self.check_alive()
        telemetry = self.telemetry()
        truth = self._truth()
        return FlightSample(
            time_s=truth.time_s, wall_s=time.monotonic(),
            fc_alt_m=telemetry.altitude.altitude_m, fc_climb_m_s=telemetry.altitude.vario_m_s,
            fc_accel_up_m_s2=telemetry.accel_up_m_s2(
                offset_lsb=msg.SITL_ACC_TRUNCATION_LSB),
            roll_deg=telemetry.attitude.roll_deg, pitch_deg=telemetry.attitude.pitch_deg,
            # MSP_ATTITUDE truncates the heading to whole degrees: the middle of the degree
            # is the unbiased reading.
            yaw_deg=float(telemetry.attitude.yaw_deg) + 0.5,
            sim_alt_m=truth.altitude_m - self._ground_alt_m, sim_climb_m_s=truth.climb_m_s,
            sim_tilt_deg=truth.tilt_deg, sim_roll_deg=truth.attitude_deg[0],
            sim_pitch_deg=truth.attitude_deg[1], sim_yaw_deg=truth.attitude_deg[2],
            on_ground=truth.on_ground,
            armed=telemetry.armed, arming_blockers=telemetry.arming_blockers,
            flight_modes=telemetry.flight_modes, motors=truth.motors, rc=self.rc_command,
            sim_north_m=truth.north_m, sim_east_m=truth.east_m,
        )

    def _flight_profile(self, profile: Profile) -> Profile:
        """``profile``, plus the compass set-up the firmware needs (master: trust its virtual
        magnetometer) and the GPS set-up of a GPS build whose GPS is not on yet.

        A 4.6.0 ``--gps`` build boots with FEATURE_GPS off and needs a serial port carrying
        the GPS function (the profile's ``gps_setup_cli``), applied at boot only: a reboot.
        Its GPS answers MSP_RAW_GPS with no satellites until then.
        """
        assert self.sitl is not None
        compass = tuple(line for line in self.sitl.profile.compass_cli
                        if line not in profile.cli_lines)
        if compass:
            profile = dataclasses.replace(profile, cli_lines=(*profile.cli_lines, *compass))
        lines = self.sitl.profile.gps_setup_cli
        if not lines:
            return profile
        try:
            if self.client.get(msg.RawGps).satellites > 0:
                return profile  # on already (a persisted run directory)
        except MspErrorReply:
            return profile  # no GPS compiled in, whatever the build record says
        self._progress("switching the GPS build's virtual GPS on (needs a reboot)")
        return dataclasses.replace(profile, cli_lines=(*profile.cli_lines, *lines),
                                   reboot_when_changed=True)

    def gps_position(self) -> GpsPosition:
        """The FC's GPS, local to its first reading in this session (one MSP round trip).

        Only GPS builds answer (``bfsitl firmware build --gps`` for 4.6.0; master has it):
        others raise :class:`MspErrorReply`.  The conversion is the FC's flat-earth one, good
        to centimetres over a flying field.
        """
        gps = self.client.get(msg.RawGps)
        if self._gps_origin_e7 is None and gps.has_fix:
            self._gps_origin_e7 = (gps.lat_e7, gps.lon_e7)
        lat0, lon0 = self._gps_origin_e7 or (gps.lat_e7, gps.lon_e7)
        cos_lat = math.cos(math.radians(lat0 * 1e-7))
        course = math.radians(gps.course_decideg / 10.0)
        speed = gps.ground_speed_m_s
        return GpsPosition(
            north_m=(gps.lat_e7 - lat0) * 1e-7 * METRES_PER_DEGREE,
            east_m=(gps.lon_e7 - lon0) * 1e-7 * METRES_PER_DEGREE * cos_lat,
            v_north_m_s=speed * math.cos(course), v_east_m_s=speed * math.sin(course),
            has_fix=gps.has_fix, satellites=gps.satellites)

    def rc_stats(self) -> RcLinkStats | None:
        return self.rc.stats() if self.rc is not None else None

    def bridge_stats(self) -> BridgeStats | None:
        return self.bridge.stats() if self.bridge is not None else None

