"""The scriptable front: launch a simulated vehicle, fly it with an autopilot.

    from bfsitl import Autopilot, launch_sitl

    with launch_sitl(firmware="master-lockstep") as vehicle:
        pilot = Autopilot(vehicle)
        pilot.takeoff(2.0)
        pilot.goto(10.0, 0.0, 2.0)
        pilot.yaw_to(90.0)
        pilot.land()

:func:`launch_sitl` starts a SITL with the embedded physics, provisioned for autonomous flight
(ARM and ANGLE switches, the 1 kHz serial task a 100 Hz loop needs) and returns the started
:class:`~bfsitl.mission.session.FlightSession`: the vehicle, with ``fc`` (its MSP client),
``rc`` (the RC sender), ``clock`` (simulation time) and ``truth`` (the simulator).  Leaving
the ``with`` block disarms and stops everything, on an exception or Ctrl-C too.

:class:`Autopilot` owns the sticks: one altitude controller, the position and heading loops
(on a GPS build), every manoeuvre a closed loop on the vehicle's clock.  :func:`connect`
gives the same autopilot a flight controller on a serial port (RC by MSP, wall time).  It
is a thin layer over :class:`~bfsitl.mission.loop.FlightLoop`, which holds the loops and the
record.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from bfsitl.backend.options import Physics, Timing, World, fly_sensors
from bfsitl.control import DEFAULT_CONTROLLER, make_controller
from bfsitl.control.base import AltitudeController
from bfsitl.control.horizontal_estimator import HorizontalEstimator
from bfsitl.control.position import PositionController
from bfsitl.errors import MissionError
from bfsitl.mission.board import BoardVehicle
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.legs import LegStats
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.phase import Phase
from bfsitl.mission.plan import MissionPlan
from bfsitl.mission.plan_driver import fly_plan
from bfsitl.mission.results import MissionResult
from bfsitl.mission.session import FLY_PROFILE, FlightSession, SessionConfig, SitlLaunch
from bfsitl.mission.stick_pilot import StickPilot
from bfsitl.mission.vehicle import Vehicle
from bfsitl.physics.params import QuadParams
from bfsitl.physics.wind import Wind
from bfsitl.records.outputs import FlightOutputs, OutputOptions
from bfsitl.vehicles import load_vehicle

#: Armed at idle before the first take-off: the FC's altitude settles, and the fused
#: controller learns the barometer's zero from the vehicle at rest.
GROUND_WAIT_S = 2.0


def launch_sitl(
    firmware: str | Path | None = None,
    *,
    physics: Physics = "embedded",
    vehicle: str | Path | QuadParams = "iris",
    wind: Wind | None = None,
    speed: float | None = None,
    seed: int = 0,
    gps_noise: bool = False,
    workdir: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
) -> FlightSession:
    """Start a SITL with its physics, provisioned for an :class:`Autopilot`; the started
    vehicle is returned (use it in a ``with`` block, or call ``close()``).

    Args:
        firmware: A SITL binary's path or a cached build's name (``master-lockstep``); None
            searches as :func:`~bfsitl.sitl.firmware.find_firmware` does.
        physics: ``"embedded"`` (bfsitl's simulator) or ``"gazebo"`` (``gz sim`` with the
            BetaflightPlugin; the truth is then Gazebo's own state).
        vehicle: The embedded physics' quad: ``"iris"`` (Gazebo's, the default), a shipped
            profile's name (``"5inch-freestyle"``), a profile file, or its parameters.
        wind: Wind and gusts of the embedded physics; None is still air.
        speed: Simulation speed as a multiple of real time.  None: real time on a stock
            build, as fast as possible on a lockstep one.
        seed: Seeds the sensor noise and the gusts: the same seed, the same disturbances.
        gps_noise: Put a typical receiver's errors on the GPS (a GPS build).
        workdir: The SITL's run directory, whose ``eeprom.bin`` persists between runs;
            None is a fresh temporary one.
        progress: Called with one line of text at each step of the start.

    Returns:
        The started vehicle (a :class:`~bfsitl.mission.session.FlightSession`).

    Raises:
        FirmwareNotFoundError: No SITL binary by that name or anywhere searched.
        SitlError: The SITL would not start or answer (``SitlNotReadyError``,
            ``SitlExitedError``, ``PortInUseError`` are kinds of it).
        ProvisioningError: The FC's configuration could not be applied.
        VehicleProfileError: ``vehicle`` is no known name and no readable profile.
        BfsitlError: Anything else bfsitl refuses (a speed out of range, a missing extra).
    """
    quad = vehicle if isinstance(vehicle, QuadParams) else load_vehicle(vehicle)
    config = SessionConfig.for_autopilot(
        control_rate_hz=FlightSession.control_rate_hz,
        sitl=SitlLaunch(firmware=firmware, workdir=workdir),
        timing=Timing(speed=speed),
        world=World(
            physics=physics,
            quad=quad,
            wind=wind,
            seed=seed,
            sensors=fly_sensors(gps_noise=gps_noise),
        ),
    )
    return FlightSession(config, progress=progress).start()


def connect(
    uri: str,
    *,
    provision: bool = True,
    rc_rate_hz: float = 25.0,
    progress: Callable[[str], None] | None = None,
) -> BoardVehicle:
    """A flight controller on a serial port (``serial:///dev/ttyACM0?baud=115200``), started
    as a vehicle: identified, checked for an MSP receiver, provisioned with ARM on AUX1 and
    ANGLE on AUX2 (``provision=False`` flies with what it holds), RC by MSP at ``rc_rate_hz``.
    Its clock is wall time and it has no truth.  **Propellers off** until you trust it: see
    docs/real-board.md.

    Args:
        uri: The board's link, ``serial:///dev/ttyACM0?baud=115200`` (or ``tcp://HOST:PORT``).
        provision: Write ARM on AUX1 and ANGLE on AUX2 when the board lacks them; False flies
            with the mode ranges it holds.
        rc_rate_hz: RC frames per second sent by MSP (MSP_SET_RAW_RC).
        progress: Called with one line of text at each step of the start.

    Returns:
        The started :class:`~bfsitl.mission.board.BoardVehicle`.

    Raises:
        LinkError: The port cannot be opened (``ExtraMissingError`` without pyserial).
        MspError: The board does not answer MSP.
        BoardSetupError: Its receiver is not MSP, or a setting needs a reboot first.
        ProvisioningError: The mode ranges could not be written or read back.
    """
    vehicle = BoardVehicle(
        uri, profile=FLY_PROFILE if provision else None, rc_rate_hz=rc_rate_hz, progress=progress
    )
    return vehicle.start()


class Autopilot:
    """Flies a started vehicle: take-off, legs to positions, heading, holds, landing.

    Positions are metres north and east of the take-off point, altitudes metres above it.
    Position manoeuvres need a GPS build (`bfsitl firmware build --gps`, master has one);
    without one ``goto`` raises :class:`~bfsitl.errors.MissionError` and ``hold`` holds the
    altitude only.  Every method raises on trouble (a crash, a timeout, a disarm); the
    record so far stays in :attr:`rows` and the log.

    Args:
        vehicle: A started vehicle: :func:`launch_sitl`'s or :func:`connect`'s.
        controller: The altitude controller, by name (``"fused"``, ``"cascade"``, ...: see
            :func:`~bfsitl.control.make_controller`) or as an object.
        rate_hz: Control steps per second of the vehicle's clock; None takes the vehicle's
            own rate (100 on a SITL, 25 on a board).
        log: A file the flight is written to as it is flown, in the format its suffix names
            (``.csv`` or ``.mcap``); None writes none.
        fuse_accelerometer: Fuse the FC's accelerometer with its GPS for the position loop
            (better with a slow, late receiver; no better in SITL).
        on_event: Called with each event of the flight as a line of text ("armed ...").

    Raises:
        MissionError: ``log`` names a format that cannot be written as it flies, or the
            rate is outside 1 to 200 Hz.
        ControllerConfigError: ``controller`` names no controller.
    """

    def __init__(
        self,
        vehicle: Vehicle,
        controller: str | AltitudeController = DEFAULT_CONTROLLER,
        *,
        rate_hz: float | None = None,
        log: str | Path | None = None,
        fuse_accelerometer: bool = False,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        self.vehicle = vehicle
        self.controller = (
            make_controller(controller, quad=vehicle.quad)
            if isinstance(controller, str)
            else controller
        )
        # The record format comes from the file's suffix (bfsitl.records.sinks): rows and
        # events stream to it as they are flown, and it is closed with the vehicle.
        self._outputs = FlightOutputs(OutputOptions(extra_paths=(log,) if log is not None else ()))
        self._on_event = on_event
        if rate_hz is None:
            rate_hz = vehicle.control_rate_hz
        # Made before the log is opened: a bad rate opens no file.
        self.loop = FlightLoop(
            vehicle,
            self.controller,
            rate_hz=rate_hz,
            on_row=self._outputs.on_row,
            on_event=self._event,
        )
        self._outputs.start()
        if any(not sink.streams for sink in self._outputs.sinks):
            self._outputs.close()
            raise MissionError(
                f"log {log}: the Autopilot's log is written as it flies; name "
                f"a .csv or .mcap file (plots and summaries come from "
                f"`bfsitl fly --plot/--summary`)"
            )
        vehicle.on_close(self._outputs.close)
        if fuse_accelerometer:
            # The GPS fused with the FC's accelerometer for the position loop: as good as the
            # GPS alone in SITL, where the fix is fresh; better with a slow, late receiver
            # (control/horizontal_estimator.py).
            self.loop.steering.horizontal = HorizontalEstimator()
            self.loop.steering.position = PositionController(
                replace(self.loop.steering.position.gains, lead_s=0.0)
            )

    # -- the record ---------------------------------------------------------------------------
    @property
    def rows(self) -> list[FlightRow]:
        return self.loop.rows

    @property
    def legs(self) -> list[LegStats]:
        """One entry per :meth:`goto`: arrival error and cross-track, from the truth."""
        return self.loop.legs

    @property
    def armed(self) -> bool:
        return self.loop.phase not in (Phase.ARMING, Phase.LANDED)

    # -- manoeuvres ---------------------------------------------------------------------------
    def takeoff(self, height_m: float, *, timeout_s: float = 20.0) -> float:
        """Arm (if needed, with a short wait on the ground), climb to ``height_m``; on a GPS
        build the take-off point is held on the way up.

        Args:
            height_m: Metres above the take-off point.
            timeout_s: Seconds of the vehicle's clock allowed for the climb to be reached
                and settled.

        Returns:
            Seconds the climb took, on the vehicle's clock.

        Raises:
            ArmingBlockedError: The FC did not arm; ``blockers`` names why.
            MissionTimeoutError: The height was not reached in ``timeout_s``.
            CrashDetectedError: The vehicle tipped over or hit the ground.
            MissionError: The FC disarmed on the way up.
            SitlExitedError: The SITL ended during the climb.
        """
        if not self.armed:
            self.loop.arm()
            self.loop.wait_on_ground(GROUND_WAIT_S)
        return self.loop.takeoff(height_m, timeout_s=timeout_s, hold_position=self.vehicle.has_gps)

    def goto(
        self,
        north_m: float,
        east_m: float,
        alt_m: float | None = None,
        *,
        speed_m_s: float | None = None,
        timeout_s: float | None = None,
    ) -> LegStats:
        """A straight leg to a position and altitude (default: the altitude held).

        Args:
            north_m: Metres north of the take-off point.
            east_m: Metres east of the take-off point.
            alt_m: Metres above the take-off point; None keeps the altitude held.
            speed_m_s: Speed along the leg, metres per second; None is the position loop's
                top speed (2 m/s).
            timeout_s: Seconds allowed to arrive; None gives 20 s plus three times the leg's
                planned duration.

        Returns:
            How the leg went: arrival error and cross-track, from the truth.

        Raises:
            MissionError: The vehicle is on the ground, the firmware has no GPS, or the FC
                disarmed.
            MissionTimeoutError: It did not arrive in ``timeout_s``.
            CrashDetectedError: The vehicle tipped over or hit the ground.
        """
        self._require_airborne("goto")
        self.loop.fly_to(
            north_m,
            east_m,
            alt_m,
            speed_m_s=speed_m_s,
            timeout_s=timeout_s,
            waypoint=len(self.loop.legs) + 1,
        )
        return self.loop.legs[-1]

    def hold(self, duration_s: float) -> None:
        """Hold the position (GPS builds) and the altitude for ``duration_s``.

        Args:
            duration_s: Seconds of the vehicle's clock.

        Raises:
            MissionError: The vehicle is on the ground, or the FC disarmed.
            CrashDetectedError: The vehicle tipped over or hit the ground.
        """
        self._require_airborne("hold")
        if self.vehicle.has_gps:
            self.loop.hold_position(duration_s)
        else:
            self.loop.hold(duration_s)

    def yaw_to(self, heading_deg: float, *, tolerance_deg: float = 2.0) -> float:
        """Turn to ``heading_deg`` (clockwise from north) where the vehicle is.

        Args:
            heading_deg: Degrees clockwise from north.
            tolerance_deg: Degrees off the heading that count as there, held for half a
                second.

        Returns:
            Seconds the turn took, on the vehicle's clock.

        Raises:
            MissionError: The vehicle is on the ground, the heading is not a number, or the
                FC disarmed.
            MissionTimeoutError: The heading was not reached in 30 seconds.
        """
        self._require_airborne("yaw_to")
        if not math.isfinite(heading_deg):
            raise MissionError(f"heading {heading_deg} is not a number")
        return self.loop.yaw_to(heading_deg, tolerance_deg=tolerance_deg)

    def fly_sticks(self, pilot: StickPilot, duration_s: float) -> None:
        """Give every stick to ``pilot`` for ``duration_s`` (a trained policy:
        :class:`~bfsitl.gym.policy_pilot.PolicyPilot`); the autopilot's next manoeuvre goes
        on from where the pilot left the vehicle.  The autopilot must run at the pilot's
        rate (``Autopilot(vehicle, rate_hz=pilot.rate_hz)``).

        Args:
            pilot: Turns each sample into the RC command (see
                :class:`~bfsitl.mission.stick_pilot.StickPilot`).
            duration_s: Seconds of the vehicle's clock.

        Raises:
            MissionError: The vehicle is on the ground, the rates differ, the pilot failed,
                or the FC disarmed.
            CrashDetectedError: The vehicle tipped over or hit the ground.
        """
        self._require_airborne("fly_sticks")
        self.loop.fly_sticks(duration_s, pilot)

    def land(self, *, timeout_s: float = 30.0) -> None:
        """Descend (holding the position after position control), touch down, disarm.

        Args:
            timeout_s: Seconds of the vehicle's clock allowed to touch down.

        Raises:
            MissionError: The vehicle is on the ground already, or the FC did not disarm
                after touch-down.
            MissionTimeoutError: It did not touch down in ``timeout_s``.
            CrashDetectedError: It hit the ground too fast.
        """
        self._require_airborne("land")
        self.loop.land(timeout_s=timeout_s)

    def fly(self, plan: MissionPlan) -> MissionResult:
        """A whole plan from the ground, every ending turned into an outcome (never raises
        for a failed flight): the same as ``bfsitl fly --mission``.

        Args:
            plan: What to fly; :func:`~bfsitl.mission.plan.load_mission` reads one from a
                file.

        Returns:
            How it ended and its figures; the rows and legs are this plan's only.

        Raises:
            MissionError: The vehicle is in the air (land first).
        """
        if self.armed:
            raise MissionError("fly(plan) starts from the ground: land first")
        return fly_plan(self.loop, plan, keep_flying=True)

    def _event(self, text: str) -> None:
        self._outputs.on_event(text)
        if self._on_event is not None:
            self._on_event(text)

    def _require_airborne(self, what: str) -> None:
        if not self.armed:
            raise MissionError(f"{what}: the vehicle is on the ground, disarmed; take off first")
