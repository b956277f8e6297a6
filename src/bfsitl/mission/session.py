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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Self

from bfsitl.backend.base import SitlBackend
from bfsitl.backend.factory import LockstepExchange, check_speed, make_backend
from bfsitl.errors import BfsitlError, MspErrorReply, SitlError, SitlExitedError
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.provisioning import (
    ANGLE_ON_AUX2,
    ARM_ON_AUX1,
    Profile,
    ProvisionResult,
    provision,
)
from bfsitl.mission.vehicle import DEFAULT_ARM_TIMEOUT_S, Progress, Vehicle
from bfsitl.physics import Simulator
from bfsitl.physics.params import IRIS, QuadParams
from bfsitl.physics.sensors import SensorConfig
from bfsitl.physics.wind import Wind
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.sim.bridge import SitlBridge
from bfsitl.sim.lockstep import LockstepBridge
from bfsitl.sitl.firmware import find_firmware
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
    """Everything a session needs to know before it starts; all of it has a default.

    Attributes:
        firmware: A SITL binary's path or a cached build's name; None searches as
            :func:`~bfsitl.sitl.firmware.find_firmware` does.
        workdir: The SITL's run directory; its ``eeprom.bin`` persists.  None: a fresh
            temporary one.
        isolate: Run the SITL in a private network namespace, so a stale SITL cannot share
            its ports.
        speed: Simulation speed as a multiple of wall time.  None: real time (1.0) with a
            stock SITL, as fast as possible with a lockstep build.  Real time allows 0.05 to
            4 (0.5 is the faithful speed on a busy 2-core machine); lockstep any positive
            speed, ``math.inf`` the most.
        lockstep: Step the firmware's clock with the physics (a ``--lockstep`` build is
            needed).  None: whenever the firmware is a lockstep build.
        profile: What to provision (mode ranges and CLI lines); None flies with whatever the
            FC already holds.  The default is ARM on AUX1 and ANGLE on AUX2.
        angle_mode: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
        sensors: The simulated sensors' errors; by default half a pascal of barometer noise
            and 0.05 metres per second squared of accelerometer noise
            (:func:`fly_sensors`), which dither the steps 4.6.0 truncates its readings to.
        arm_timeout_s: Seconds :meth:`FlightSession.arm` waits for the FC's blockers to
            clear and for it to arm.
        physics: ``"embedded"`` (bfsitl's simulator and bridge) or ``"gazebo"`` (``gz sim``
            with the BetaflightPlugin, started in the SITL's namespace; no simulated truth is
            then known).
        gz_plugin_dir: Where libBetaflightPlugin.so is, for ``physics="gazebo"``; None
            uses Gazebo's search path.
        wind: Wind and gusts of the embedded physics; None is still air.
        quad: The simulated quad of the embedded physics: Gazebo's IRIS unless told
            otherwise.
        seed: Seeds the sensor noise and the gusts: the same seed gives the same
            disturbances.
        initial_heading_deg: The quad's heading when the flight starts, degrees clockwise
            from north (the embedded physics).  A firmware without a compass believes north
            at boot whatever it is.
        rc_link: Send RC over UDP (the SITL's usual receiver).  False leaves RC to someone
            else: a :class:`~bfsitl.mission.board.BoardVehicle` sending MSP_SET_RAW_RC
            through the serial bridge (real time only).
        configurator_port: Serve the Configurator during the flight: a WebSocket bridge on
            127.0.0.1 at this port relays to the FC's UART2.  None: no bridge; 0: any free
            port (:attr:`FlightSession.configurator_url` says which).
        allow_origins: Web page origins the Configurator bridge accepts beyond the
            Configurator's own.
        lockstep_spin: Lockstep: busy-wait for each other's packets instead of sleeping;
            fastest when the run has cores to itself, off when runs share the cores.
        lockstep_exchange: Lockstep: how packets pass between the physics and the firmware:
            ``"auto"`` (shared memory where the build and the machine have it, else UDP),
            ``"shm"`` or ``"udp"``.  Either gives the same flight.
    """

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
    #: The quad's heading when the flight starts (the embedded physics), degrees clockwise
    #: from north.  A firmware without a compass believes north at boot whatever it is.
    initial_heading_deg: float = 0.0
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
    #: Lockstep: how packets pass between the physics and the firmware: ``"auto"`` (shared
    #: memory where the build and the machine have it, else UDP), ``"shm"`` or ``"udp"``.
    #: Either gives the same flight (bfsitl.link.shm_exchange).
    lockstep_exchange: LockstepExchange = "auto"

    @classmethod
    def for_autopilot(cls, *, control_rate_hz: float = 100.0, gps_noise: bool = False,
                      baro_noise_std_pa: float | None = None,
                      accel_noise_std_m_s2: float | None = None,
                      profile: Profile | None = FLY_PROFILE, **fields: Any) -> SessionConfig:
        """What bfsitl's own flights use (``bfsitl fly``, :func:`~bfsitl.launch_sitl`,
        scenario runs): ``profile`` with the serial task at 1 kHz when the control loop runs
        above 50 Hz (:data:`FAST_SERIAL_LINE`), the default sensor errors
        (:func:`fly_sensors`, plus a typical receiver's GPS errors with ``gps_noise``), and
        any other field as given.

        Args:
            control_rate_hz: The rate the autopilot's loop will run at, steps per second;
                above 50 the serial task is set to 1 kHz.
            gps_noise: Put a typical receiver's errors on the GPS.
            baro_noise_std_pa: Barometer noise, standard deviation in pascals; None is the
                default half a pascal.
            accel_noise_std_m_s2: Accelerometer noise, standard deviation in metres per
                second squared; None is the default 0.05.
            profile: What to provision; None flies with what the FC holds (and sets no
                serial rate).
            **fields: Any other :class:`SessionConfig` field, by name.

        Returns:
            The configuration.

        Raises:
            TypeError: A name in ``fields`` is no field of :class:`SessionConfig`.
        """
        sensors = fly_sensors(baro_noise_std_pa=baro_noise_std_pa,
                              accel_noise_std_m_s2=accel_noise_std_m_s2)
        if gps_noise:
            sensors = sensors.with_typical_gps()
        if profile is not None and control_rate_hz > FAST_SERIAL_ABOVE_HZ:
            profile = with_fast_serial(profile)
        return cls(sensors=sensors, profile=profile, **fields)


class FlightSession(Vehicle):
    """Start, provision, arm and feed one simulated flight; stop all of it on the way out.

    >>> with FlightSession() as session:                    # doctest: +SKIP
    ...     session.arm()
    ...     session.set_throttle(1550)
    ...     print(session.sample().sim_alt_m)

    Nothing starts when it is made: :meth:`start` (or entering the ``with`` block) does.

    Args:
        config: What to fly and how; None takes every default of :class:`SessionConfig`.
        progress: Called with one line of text at each step of the start.

    Raises:
        BfsitlError: The speed is no positive number, or ``configurator_port`` is given
            without a profile to provision.
    """

    #: With the serial task at 1 kHz (``with_fast_serial``, what launch_sitl provisions).
    control_rate_hz = 100.0

    def __init__(self, config: SessionConfig | None = None, *,
                 progress: Progress | None = None) -> None:
        config = config or SessionConfig()
        super().__init__(progress=progress, arm_timeout_s=config.arm_timeout_s,
                         angle_mode=config.angle_mode)
        self.config = config
        check_speed(config.speed)
        self.sitl: SitlProcess | None = None
        #: Chosen at start, from the firmware's build record (bfsitl.backend.factory).
        self.sitl_backend: SitlBackend | None = None
        self.provisioned: ProvisionResult | None = None
        #: The Configurator bridge's ws:// URL while one serves (``configurator_port``).
        self.configurator_url: str | None = None
        if config.configurator_port is not None and config.profile is None:
            raise BfsitlError("the Configurator bridge needs provisioning (it puts MSP on "
                              "UART2 as well): drop --no-provision, or leave out --configurator")

    # -- lifecycle ---------------------------------------------------------------------------
    def start(self) -> Self:
        """Start everything (see the module docstring); a started session is returned as it
        is (``with launch_sitl(...) as vehicle`` enters a started one).

        Returns:
            This session, started; on any error everything started so far is stopped first.

        Raises:
            FirmwareNotFoundError: No SITL binary by that name or anywhere searched.
            SitlError: The SITL would not start or answer (``SitlNotReadyError``,
                ``SitlExitedError``, ``PortInUseError`` are kinds of it).
            ProvisioningError: The FC's configuration could not be applied.
            BfsitlError: A backend this firmware or machine cannot have (Gazebo missing, a
                speed out of range for a stock build, the Configurator's port taken).
        """
        if self.sitl is not None:
            return self
        config = self.config
        if config.configurator_port:
            from bfsitl.bridges import check_listen_port

            check_listen_port(SITL_HOST, config.configurator_port, "--configurator-port")
        try:
            firmware = find_firmware(config.firmware)
            backend = make_backend(config, firmware, progress=self._progress,
                                   alive=self.check_alive)
            self.backend = self.sitl_backend = backend
            self.sitl = SitlProcess(firmware, workdir=config.workdir, isolate=config.isolate,
                                    progress=self._progress, env=backend.sitl_env,
                                    hooks=backend.hooks)
            backend.start(self.sitl, self._stack)
            self.clock = backend.clock
            self._provision()
            if config.rc_link:
                # Only now: an RC packet during boot leaves 4.6.0 in RXLOSS for good.
                self._start_rc(backend.rc_sender(self.sitl))
        except BaseException:
            self.close()
            raise
        return self

    def _reboot(self) -> None:
        """A CLI line needed a reboot: in SITL the process ends, so start it again."""
        assert self.sitl is not None and self.sitl_backend is not None
        self._progress("the configuration needs a reboot; restarting the SITL")
        self.sitl_backend.reboot(self.sitl, self.client)

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
    def simulator(self) -> Simulator | None:
        """bfsitl's simulated vehicle, once started with the embedded physics."""
        return self.backend.simulator

    @property
    def bridge(self) -> SitlBridge | LockstepBridge | None:
        """The exchange with the firmware, once started with the embedded physics."""
        return self.sitl_backend.bridge if self.sitl_backend is not None else None

    @property
    def has_gps(self) -> bool:
        """The firmware has a GPS (position control needs it)."""
        return self.sitl is not None and self.sitl.profile.has_gps

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
        failure = self.backend.failure()
        if failure is not None:
            raise SitlError(failure)

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


