"""A flight session: one SITL, the embedded physics, a provisioned FC and an RC link.

The order of things is what makes a SITL flight reliable (``docs/firmware-findings.md``):

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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Self

from bfsitl.errors import (
    BfsitlError,
    MspErrorReply,
    SitlError,
    SitlExitedError,
)
from bfsitl.fc.firmware_detect import profile_of_binary
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.provisioning import (
    ANGLE_ON_AUX2,
    ARM_ON_AUX1,
    Profile,
    ProvisionResult,
    provision,
)
from bfsitl.fc.rc_link import UdpRcLink

# The vehicle's parts, importable from here as before the split.
from bfsitl.mission.vehicle import (  # noqa: F401
    DEFAULT_ARM_TIMEOUT_S,
    METRES_PER_DEGREE,
    SWITCH_OFF_US,
    SWITCH_ON_US,
    FlightSample,
    GpsPosition,
    Progress,
    SessionClock,
    Truth,
    Vehicle,
    WallClock,
)
from bfsitl.physics import Simulator
from bfsitl.physics.frames import betaflight_attitude_deg
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.physics.sensors import SensorConfig
from bfsitl.physics.wind import Wind
from bfsitl.protocol import msp_messages as msg
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.sim.bridge import BridgeStats, SitlBridge, bridged_sitl, wait_for_replies
from bfsitl.sim.health import HealthMonitor, lock_clock
from bfsitl.sim.lockstep import (
    REPLY_SPIN_S,
    SITL_SPIN_ENV,
    LockstepBridge,
    LockstepClock,
    LockstepRc,
    SteppedLink,
)
from bfsitl.sitl.process import SITL_HOST, SitlProcess

#: UART2's TCP port (the SITL serves UARTn on 5760 + n).
SECOND_MSP_PORT = 5762

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
    #: The simulated quad (the embedded physics): Gazebo's IRIS unless told otherwise.
    quad: QuadParams = IRIS
    #: Seeds the sensor noise and the gusts: the same seed gives the same disturbances.
    seed: int = 0
    #: Send RC over UDP (the SITL's usual receiver).  False leaves RC to someone else: a
    #: :class:`~bfsitl.mission.board.BoardVehicle` sending MSP_SET_RAW_RC through the serial
    #: bridge, as to a real board (real time only: a lockstep SITL takes RC in its fdm).
    rc_link: bool = True
    #: Serve the Configurator during the flight: provisioning puts MSP on UART2 (TCP 5762)
    #: as well, and a WebSocket bridge on 127.0.0.1 at this port relays to it, while bfsitl
    #: keeps UART1.  None: no bridge.  0: any free port (:attr:`FlightSession.configurator_url`).
    configurator_port: int | None = None
    #: Web page origins the Configurator bridge accepts beyond the Configurator's own.
    allow_origins: tuple[str, ...] = ()
    #: Lockstep: busy-wait for each other's packets (bfsitl and the SITL) instead of
    #: sleeping: fastest when the run has cores to itself; off when runs share the cores
    #: (``bfsitl scenario run --jobs 2`` on two cores), where spinning steals time slices.
    lockstep_spin: bool = True


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


class FlightSession(Vehicle):
    """Start, provision, arm and feed one simulated flight; stop all of it on the way out.

    >>> with FlightSession() as session:                    # doctest: +SKIP
    ...     session.arm()
    ...     session.set_throttle(1550)
    ...     print(session.sample().sim_alt_m)
    """

    #: With the serial task at 1 kHz (``with_fast_serial``, what launch_sitl provisions).
    control_rate_hz = 100.0

    def __init__(self, config: SessionConfig | None = None, *,
                 progress: Progress | None = None) -> None:
        config = config or SessionConfig()
        super().__init__(progress=progress, arm_timeout_s=config.arm_timeout_s,
                         angle_mode=config.angle_mode)
        self.config = config
        speed = self.config.speed
        if speed is not None and not (speed > 0 and not math.isnan(speed)):
            raise BfsitlError(f"speed {speed} must be a positive number")
        self.sitl: SitlProcess | None = None
        self.simulator: Simulator | None = None
        self.bridge: SitlBridge | LockstepBridge | None = None
        #: The mission clock: simulation time, and how to let some of it pass.
        self.clock = RealTimeClock(self)
        self.provisioned: ProvisionResult | None = None
        #: The Configurator bridge's ws:// URL while one serves (``configurator_port``).
        self.configurator_url: str | None = None
        if config.configurator_port is not None and config.profile is None:
            raise BfsitlError("the Configurator bridge needs provisioning (it puts MSP on "
                              "UART2 as well): drop --no-provision, or leave out --configurator")

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> Self:
        """Start everything (see the module docstring); a started session is returned as it
        is (``with launch_sitl(...) as vehicle`` enters a started one)."""
        if self.sitl is not None:
            return self
        config = self.config
        if config.configurator_port:
            from bfsitl.bridges import check_listen_port

            check_listen_port(SITL_HOST, config.configurator_port, "--configurator-port")
        try:
            if config.physics == "gazebo":
                self._start_with_gazebo()
            elif config.physics == "embedded":
                self.sitl = SitlProcess(
                    config.firmware, workdir=config.workdir, isolate=config.isolate,
                    progress=self._progress,
                    env=None if config.lockstep_spin else {SITL_SPIN_ENV: "0"})
                self.simulator = Simulator(config.quad, sensors=config.sensors,
                                           wind=config.wind,
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
            self._provision()
            if config.rc_link:
                # Only now: an RC packet during boot leaves 4.6.0 in RXLOSS for good.
                assert self.sitl.network is not None
                self._start_rc(UdpRcLink(self.sitl.network))
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
        if not config.rc_link:
            raise BfsitlError("rc_link=False (RC from elsewhere, e.g. MSP through the serial "
                              "bridge) needs a real-time SITL: a lockstep build takes its RC "
                              "in the fdm packets bfsitl steps it with; use a stock build")
        assert sitl is not None and simulator is not None
        speed = None if config.speed is None or math.isinf(config.speed) else config.speed
        bridge = LockstepBridge(simulator, sitl.prepare_network(), speed=speed,
                                profile=profile_of_binary(sitl.firmware.path),
                                spin_s=REPLY_SPIN_S if config.lockstep_spin else 0.0)
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
        self._provision()
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

    # -- parts -------------------------------------------------------------------------------
    @property
    def client(self) -> MspClient:
        """The FC's MSP client; in lockstep its waits step the simulation."""
        if self.sitl is None or self.sitl.client is None:
            raise SitlError("the session is not started")
        return self.sitl.client

    @property
    def firmware(self) -> FirmwareProfile | None:
        return self.sitl.profile if self.sitl is not None else None

    def has_exited(self) -> bool:
        return self.sitl is not None and self.sitl.poll() is not None

    @property
    def truth(self) -> Simulator | None:
        """The simulated vehicle (its state is the truth), or None with external physics."""
        return self.simulator

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

    # -- observation -------------------------------------------------------------------------
    def _truth(self) -> Truth:
        if self.bridge is None or self.simulator is None:  # external physics: truth unknown
            return super()._truth()
        simulator, bridge = self.simulator, self.bridge

        def read() -> Truth:
            state = simulator.state
            w, x, y, z = state.quaternion_wxyz
            # Body z in world NED has z component 1 - 2(x^2 + y^2): cos(tilt).
            cos_tilt = max(-1.0, min(1.0, 1.0 - 2.0 * (x * x + y * y)))
            north, east, _down = state.position_ned_m
            return Truth(state.time_s, simulator.altitude_m, -state.velocity_ned_m_s[2],
                          math.degrees(math.acos(cos_tilt)),
                          betaflight_attitude_deg(state.quaternion_wxyz), simulator.on_ground,
                          tuple(bridge.motors),  # type: ignore[arg-type]
                          north - self._start_ned[0], east - self._start_ned[1])

        # On the bridge thread, between two steps: one consistent state.
        return bridge.between_steps(read)

    def _provision(self) -> None:
        """Apply the configured profile; then serve the Configurator if asked."""
        config = self.config
        if config.profile is None:
            return
        self.provisioned = provision(self.client, self._flight_profile(config.profile),
                                     reboot=self._reboot)
        self._progress("provisioned: " + (
            "written and saved" + (", rebooted" if self.provisioned.rebooted else "")
            if self.provisioned.changed else "already configured, nothing written"))
        if config.configurator_port is not None:
            self._serve_configurator(config.configurator_port)

    def _serve_configurator(self, port: int) -> None:
        """The WebSocket bridge to UART2 (TCP 5762), in the SITL's network, until close."""
        from bfsitl.bridges import Upstream
        from bfsitl.bridges.origin_policy import OriginPolicy
        from bfsitl.bridges.websocket_relay import WebSocketRelay, connect_hint

        assert self.sitl is not None and self.sitl.network is not None
        upstream = Upstream(SITL_HOST, SECOND_MSP_PORT, socket_factory=self.sitl.network.socket)
        relay = WebSocketRelay(upstream, port=port,
                               origins=OriginPolicy.with_extra(self.config.allow_origins),
                               on_event=lambda line: self._progress(f"configurator: {line}"),
                               port_option="--configurator-port")
        self.configurator_url = self._stack.enter_context(relay.running())
        url = self.configurator_url
        self._progress(f"the Configurator can watch this flight at {url} (MSP on UART2, TCP "
                       f"{SECOND_MSP_PORT}); {connect_hint(url)}. Leaving its CLI tab or "
                       f"saving reboots the FC and ends the flight")

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
        if self.config.configurator_port is not None:
            # Read at boot only; provisioning compares them, so this reboots once per run
            # directory.
            profile = dataclasses.replace(
                profile, cli_lines=(*profile.cli_lines, *self.sitl.profile.second_msp_cli),
                reboot_when_changed=True)
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

    def bridge_stats(self) -> BridgeStats | None:
        return self.bridge.stats() if self.bridge is not None else None

