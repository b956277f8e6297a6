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
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from bfsitl.backend.base import SitlBackend
from bfsitl.backend.factory import check_speed, make_backend
from bfsitl.backend.options import Timing, World
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
from bfsitl.protocol import messages as msg
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.sim.bridge import SitlBridge
from bfsitl.sim.lockstep import LockstepBridge
from bfsitl.sim.rc_frames import DEFAULT_RC_RATE_HZ, check_rc_rate
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


@dataclass(frozen=True, slots=True)
class SitlLaunch:
    """How the SITL process is launched: which binary, where it runs, in which network.

    Attributes:
        firmware: A SITL binary's path or a cached build's name; None searches as
            :func:`~bfsitl.sitl.firmware.find_firmware` does.
        workdir: The SITL's run directory; its ``eeprom.bin`` persists.  None: a fresh
            temporary one.
        isolate: Run the SITL in a private network namespace, so a stale SITL cannot share
            its ports.
        env: Environment variables for the SITL process beyond the backend's (a log's
            replay asks a lockstep build for ``BFSITL_LOCKSTEP_RX_FRAMES``).
    """

    firmware: str | Path | None = None
    workdir: str | Path | None = None
    isolate: bool = True
    #: Environment variables for the SITL process beyond the backend's, as (name, value).
    env: tuple[tuple[str, str], ...] = ()


@dataclass(frozen=True, slots=True)
class FcSetup:
    """What the flight controller is given: its provisioning, its switches and its RC.

    Attributes:
        profile: What to provision (mode ranges and CLI lines); None flies with whatever the
            FC already holds.  The default is ARM on AUX1 and ANGLE on AUX2.
        angle_mode: Hold AUX2 on while armed (ANGLE, when the profile puts ANGLE there).
        arm_timeout_s: Seconds :meth:`FlightSession.arm` waits for the FC's blockers to
            clear and for it to arm.
        rc_link: Send RC over UDP (the SITL's usual receiver).  False leaves RC to someone
            else: a :class:`~bfsitl.mission.board.BoardVehicle` sending MSP_SET_RAW_RC
            through the serial bridge (real time only).
        attachable: Serve MSP on UART2 too and advertise the flight, so a second MSP client
            (``bfsitl top``) finds it and can watch it (``bfsitl fly`` does this).
        rc_rate_hz: The RC link's frame rate on a lockstep build, frames per second of
            simulation time, each with the latest sticks, as a real receiver's (16 to 1000;
            4.6.0 and master size RC smoothing and feedforward by it, and lose the link when
            frames stop).  None: a frame in every fdm packet, and 4.6.0's stock SITL
            receiver, which calls every check a frame (bfsitl before 2026-11-29).
    """

    profile: Profile | None = FLY_PROFILE
    angle_mode: bool = True
    arm_timeout_s: float = DEFAULT_ARM_TIMEOUT_S
    #: Real time only: a lockstep SITL takes RC in its fdm packets.
    rc_link: bool = True
    #: Serve MSP on UART2 (TCP 5762) as well and advertise the flight
    #: (:mod:`bfsitl.sitl.running_flights`), so ``bfsitl top`` can attach while it flies.
    #: Read at boot: a run directory without it costs one reboot.  Needs a profile.
    attachable: bool = False
    #: An ELRS link's rate by default (:mod:`bfsitl.sim.rc_frames`).
    rc_rate_hz: float | None = DEFAULT_RC_RATE_HZ

    def __post_init__(self) -> None:
        check_rc_rate(self.rc_rate_hz)  # refused when the configuration is made


@dataclass(frozen=True, slots=True)
class ConfiguratorBridge:
    """Serving the Configurator during the flight: provisioning puts MSP on UART2 (TCP 5762)
    as well, and a WebSocket bridge on 127.0.0.1 relays to it, while bfsitl keeps UART1.

    Attributes:
        port: The bridge's port; 0 is any free port (:attr:`FlightSession.configurator_url`
            says which).
        allow_origins: Web page origins the bridge accepts beyond the Configurator's own.
    """

    port: int = 0
    allow_origins: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class SessionConfig:
    """Everything a session needs to know before it starts, grouped by what it configures;
    every group has its defaults.

    >>> SessionConfig(sitl=SitlLaunch(firmware="master"), world=World(seed=3))
    ... # doctest: +SKIP

    Attributes:
        sitl: The SITL process: its binary, run directory and network namespace.
        timing: The simulation's pace and the lockstep with the firmware's clock.
        fc: The flight controller's provisioning, switches and RC link.
        world: The simulated world: physics, quad, wind, sensor errors, seed, heading.
        configurator: Serve the Configurator during the flight; None serves nothing.
    """

    sitl: SitlLaunch = SitlLaunch()
    timing: Timing = Timing()
    fc: FcSetup = FcSetup()
    world: World = World()
    configurator: ConfiguratorBridge | None = None

    @classmethod
    def for_autopilot(cls, *, control_rate_hz: float = 100.0, **groups: Any) -> SessionConfig:
        """What bfsitl's own flights use (``bfsitl fly``, :func:`~bfsitl.launch_sitl`,
        scenario runs, the gym environments): the groups as given, with the serial task at
        1 kHz in the profile when the control loop runs above 50 Hz
        (:data:`FAST_SERIAL_LINE`).

        Args:
            control_rate_hz: The rate the autopilot's loop will run at, steps per second;
                above 50 the serial task is set to 1 kHz (unless ``fc.profile`` is None).
            **groups: Any group of :class:`SessionConfig`, by name (``sitl``, ``timing``,
                ``fc``, ``world``, ``configurator``).

        Returns:
            The configuration.

        Raises:
            TypeError: A name in ``groups`` is no field of :class:`SessionConfig`.
        """
        config = cls(**groups)
        profile = config.fc.profile
        if profile is None or control_rate_hz <= FAST_SERIAL_ABOVE_HZ:
            return config
        return dataclasses.replace(
            config, fc=dataclasses.replace(config.fc, profile=with_fast_serial(profile))
        )


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
        BfsitlError: The speed is no positive number, or the Configurator is to be served
            without a profile to provision.
    """

    #: With the serial task at 1 kHz (``with_fast_serial``, what launch_sitl provisions).
    control_rate_hz = 100.0

    def __init__(
        self, config: SessionConfig | None = None, *, progress: Progress | None = None
    ) -> None:
        config = config or SessionConfig()
        super().__init__(
            progress=progress,
            arm_timeout_s=config.fc.arm_timeout_s,
            angle_mode=config.fc.angle_mode,
        )
        self.config = config
        if config.world.physics == "embedded":
            self.quad = config.world.quad
        check_speed(config.timing.speed)
        self.sitl: SitlProcess | None = None
        #: Chosen at start, from the firmware's build record (bfsitl.backend.factory).
        self.sitl_backend: SitlBackend | None = None
        self.provisioned: ProvisionResult | None = None
        #: The Configurator bridge's ws:// URL while one serves (``config.configurator``).
        self.configurator_url: str | None = None
        if config.configurator is not None and config.fc.profile is None:
            raise BfsitlError(
                "the Configurator bridge needs provisioning (it puts MSP on "
                "UART2 as well): drop --no-provision, or leave out --configurator"
            )
        if config.fc.attachable and config.fc.profile is None:
            raise BfsitlError(
                "an attachable flight needs provisioning (it puts MSP on UART2 as well): "
                "give a profile, or set fc.attachable=False"
            )

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
        if config.configurator is not None and config.configurator.port:
            from bfsitl.bridges import check_listen_port

            check_listen_port(SITL_HOST, config.configurator.port, "--configurator-port")
        try:
            firmware = find_firmware(config.sitl.firmware)
            backend = make_backend(
                config.world,
                config.timing,
                firmware,
                progress=self._progress,
                rc_link=config.fc.rc_link,
                rc_rate_hz=config.fc.rc_rate_hz,
                alive=self.check_alive,
            )
            self.backend = self.sitl_backend = backend
            self.sitl = SitlProcess(
                firmware,
                workdir=config.sitl.workdir,
                isolate=config.sitl.isolate,
                progress=self._progress,
                env={**(backend.sitl_env or {}), **dict(config.sitl.env)} or None,
                hooks=backend.hooks,
            )
            backend.start(self.sitl, self._stack)
            self.clock = backend.clock
            self._provision()
            if config.fc.rc_link:
                # Only now: an RC packet during boot leaves 4.6.0 in RXLOSS for good.
                self._start_rc(backend.rc_sender(self.sitl))
            if config.fc.attachable:
                self._advertise()
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
                code,
                self.sitl.log_tail(),
            )
        failure = self.backend.failure()
        if failure is not None:
            raise SitlError(failure)

    def _provision(self) -> None:
        """Apply the configured profile; then serve the Configurator if asked."""
        config = self.config
        if config.fc.profile is None:
            return
        self.provisioned = provision(
            self.client, self._flight_profile(config.fc.profile), reboot=self._reboot
        )
        self._progress(
            "provisioned: "
            + (
                "written and saved" + (", rebooted" if self.provisioned.rebooted else "")
                if self.provisioned.changed
                else "already configured, nothing written"
            )
        )
        if config.configurator is not None:
            self._serve_configurator(config.configurator)

    def _serve_configurator(self, bridge: ConfiguratorBridge) -> None:
        """The WebSocket bridge to UART2 (TCP 5762), in the SITL's network, until close."""
        from bfsitl.bridges import Upstream
        from bfsitl.bridges.origin_policy import OriginPolicy
        from bfsitl.bridges.websocket_relay import WebSocketRelay, connect_hint

        assert self.sitl is not None and self.sitl.network is not None
        upstream = Upstream(SITL_HOST, SECOND_MSP_PORT, socket_factory=self.sitl.network.socket)
        relay = WebSocketRelay(
            upstream,
            port=bridge.port,
            origins=OriginPolicy.with_extra(bridge.allow_origins),
            on_event=lambda line: self._progress(f"configurator: {line}"),
            port_option="--configurator-port",
        )
        self.configurator_url = self._stack.enter_context(relay.running())
        url = self.configurator_url
        self._progress(
            f"the Configurator can watch this flight at {url} (MSP on UART2, TCP "
            f"{SECOND_MSP_PORT}); {connect_hint(url)}. Leaving its CLI tab or "
            f"saving reboots the FC and ends the flight"
        )

    def _advertise(self) -> None:
        """Say where ``bfsitl top`` reaches this flight, until the session closes.  A cache
        that cannot be written costs the advert, never the flight."""
        from bfsitl.sitl.running_flights import FlightAdvert, FlightRegistry

        assert self.sitl is not None and self.sitl.network is not None
        if not self.sitl.profile.second_msp_cli:
            return  # a firmware bfsitl cannot give a second MSP port
        advert = FlightAdvert.for_this_process(
            firmware=self.sitl.profile.name,
            host=SITL_HOST,
            port=SECOND_MSP_PORT,
            netns_pid=self.sitl.network.netns_pid,
            workdir=str(self.sitl.workdir),
        )
        registry = FlightRegistry()
        try:
            self._stack.enter_context(registry.advertised(advert))
        except OSError as exc:
            self._progress(f"cannot advertise the flight for `bfsitl top` ({exc}); flying on")
            return
        self._progress(
            f"`bfsitl top` can watch this flight ({advert.key}; MSP on UART2, TCP "
            f"{SECOND_MSP_PORT})"
        )

    def _flight_profile(self, profile: Profile) -> Profile:
        """``profile``, plus the compass set-up the firmware needs (master: trust its virtual
        magnetometer) and the GPS set-up of a GPS build whose GPS is not on yet.

        A 4.6.0 ``--gps`` build boots with FEATURE_GPS off and needs a serial port carrying
        the GPS function (the profile's ``gps_setup_cli``), applied at boot only: a reboot.
        Its GPS answers MSP_RAW_GPS with no satellites until then.
        """
        assert self.sitl is not None
        compass = tuple(
            line for line in self.sitl.profile.compass_cli if line not in profile.cli_lines
        )
        if compass:
            profile = dataclasses.replace(profile, cli_lines=(*profile.cli_lines, *compass))
        if self.config.configurator is not None or self.config.fc.attachable:
            # Read at boot only; provisioning compares them, so this reboots once per run
            # directory.
            profile = dataclasses.replace(
                profile,
                cli_lines=(*profile.cli_lines, *self.sitl.profile.second_msp_cli),
                reboot_when_changed=True,
            )
        lines = self.sitl.profile.gps_setup_cli
        if not lines:
            return profile
        try:
            if self.client.get(msg.RawGps).satellites > 0:
                return profile  # on already (a persisted run directory)
        except MspErrorReply:
            return profile  # no GPS compiled in, whatever the build record says
        self._progress("switching the GPS build's virtual GPS on (needs a reboot)")
        return dataclasses.replace(
            profile, cli_lines=(*profile.cli_lines, *lines), reboot_when_changed=True
        )
