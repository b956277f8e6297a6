"""The disturbance surface: what can be done to a flight from outside the flight controller.

Faults (``bfsitl.scenario.faults``) and users (``vehicle.disturbances``) act only through
this, so a fault never reaches into a bridge or a simulator, and a backend that cannot do
something says so in one way: :class:`~bfsitl.errors.DisturbanceUnavailableError`, naming
the backend.  What each backend offers:

==================  ========================  ==================================================
backend             RC (faults on the link)   GPS loss, motors, sensors, wind, a hand
==================  ========================  ==================================================
real time           yes                       yes (bfsitl's physics)
lockstep            yes                       yes (bfsitl's physics)
Gazebo              yes                       a constant wind (Gazebo's WindEffects); no other
a real board        no                        no
==================  ========================  ==================================================

Every setter acts from the next physics step (the next RC packet for RC); every getter
reads what is set now, so a fault can undo itself exactly.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Protocol

from bfsitl.errors import DisturbanceUnavailableError

if TYPE_CHECKING:
    from bfsitl.fc.rc_link import RcFault, RcSender
    from bfsitl.physics import Simulator
    from bfsitl.physics.sensors import SensorConfig
    from bfsitl.physics.wind import Wind


class WindSurface(Protocol):
    """The wind of a physics that is not bfsitl's (Gazebo's)."""

    @property
    def wind(self) -> Wind | None: ...

    def set_wind(self, wind: Wind | None) -> None: ...


class Disturbances:
    """Typed handles on the RC link, the GPS, the motors, the sensors and the wind."""

    def __init__(
        self,
        backend: str,
        *,
        rc: Callable[[], RcSender | None] | None = None,
        simulator: Simulator | None = None,
        gps_lost: Callable[[bool], None] | None = None,
        wind: Callable[[], WindSurface | None] | None = None,
    ) -> None:
        self._backend = backend
        self._rc = rc
        self._wind = wind
        self._simulator = simulator
        self._set_gps_lost = gps_lost
        self._gps_lost = False

    # -- what is available ---------------------------------------------------------------------
    @property
    def has_rc(self) -> bool:
        return self._rc is not None

    @property
    def has_physics(self) -> bool:
        """Motors, sensors, wind and GPS loss: the physics is bfsitl's."""
        return self._simulator is not None

    def _unavailable(self, what: str, why: str) -> DisturbanceUnavailableError:
        return DisturbanceUnavailableError(
            f"{what} cannot be disturbed with {self._backend}: {why}"
        )

    def _sim(self, what: str) -> Simulator:
        if self._simulator is None:
            raise self._unavailable(
                what, "it acts in bfsitl's embedded physics (physics = embedded)"
            )
        return self._simulator

    # -- RC ------------------------------------------------------------------------------------
    def _sender(self) -> RcSender:
        sender = self._rc() if self._rc is not None else None
        if sender is None:
            raise self._unavailable(
                "the RC link", "an RC fault needs bfsitl's RC link (the session has none)"
            )
        return sender

    @property
    def rc_fault(self) -> RcFault | None:
        return self._sender().fault

    def set_rc_fault(self, fault: RcFault | None) -> None:
        """What reaches the FC's receiver from the next packet on (None: healthy again)."""
        self._sender().fault = fault

    # -- GPS -----------------------------------------------------------------------------------
    @property
    def gps_lost(self) -> bool:
        return self._gps_lost

    def set_gps_lost(self, lost: bool) -> None:
        """The virtual GPS stops (the firmware's loss sentinel) or comes back."""
        if self._set_gps_lost is None:
            raise self._unavailable(
                "the GPS", "it acts in bfsitl's embedded physics (physics = embedded)"
            )
        self._set_gps_lost(lost)
        self._gps_lost = lost

    # -- physics -------------------------------------------------------------------------------
    @property
    def motor_thrust(self) -> tuple[float, float, float, float]:
        """Each rotor's thrust as a fraction of a healthy one's (Betaflight order M1..M4)."""
        return self._sim("a motor").motor_thrust

    def set_motor_thrust(self, motor: int, fraction: float) -> None:
        """Motor ``motor`` (1..4, Betaflight's numbering) gives ``fraction`` of its thrust."""
        self._sim("a motor").set_motor_thrust(motor, fraction)

    @property
    def sensors(self) -> SensorConfig:
        return self._sim("the sensors").sensor_config

    def set_sensors(self, config: SensorConfig) -> None:
        """The sensor errors from now on (the noise generators go on where they were)."""
        self._sim("the sensors").set_sensors(config)

    def change_sensors(self, **fields: Any) -> SensorConfig:
        """Change some sensor error fields; returns the configuration before."""
        before = self.sensors
        self.set_sensors(replace(before, **fields))
        return before

    def _wind_surface(self) -> WindSurface | Simulator:
        if self._wind is None:
            return self._sim("the wind")
        surface = self._wind()
        if surface is None:
            raise self._unavailable("the wind", "the physics has not started yet")
        return surface

    @property
    def wind(self) -> Wind | None:
        return self._wind_surface().wind

    def set_wind(self, wind: Wind | None) -> None:
        """The wind from now on (None: still air)."""
        self._wind_surface().set_wind(wind)

    # -- a hand on the vehicle -------------------------------------------------------------------
    def place(
        self,
        position_ned_m: tuple[float, float, float],
        *,
        yaw_deg: float = 0.0,
        motor_speeds_rad_s: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
    ) -> None:
        """Put the vehicle at ``position_ned_m`` (world NED), level, heading ``yaw_deg``, at
        rest, its rotors at ``motor_speeds_rad_s``: a hand that picks it up and sets it there.
        The firmware sees a jump in its sensors, as it would."""
        self._sim("the vehicle's pose").reset(
            position_ned_m, yaw_deg=yaw_deg, motor_speeds_rad_s=motor_speeds_rad_s
        )

    def let_go(
        self,
        position_ned_m: tuple[float, float, float],
        *,
        quaternion_wxyz: tuple[float, float, float, float],
        velocity_ned_m_s: tuple[float, float, float],
        angular_velocity_frd_rad_s: tuple[float, float, float],
    ) -> None:
        """A throw: the vehicle at ``position_ned_m`` (world NED) in the attitude
        ``quaternion_wxyz`` (body FRD to NED), moving and spinning as given, its rotors
        stopped, and nothing holding it any more (:meth:`hold_still` released)."""
        simulator = self._sim("the vehicle's pose")
        simulator.reset(
            position_ned_m,
            quaternion_wxyz=quaternion_wxyz,
            velocity_ned_m_s=velocity_ned_m_s,
            angular_velocity_frd_rad_s=angular_velocity_frd_rad_s,
        )
        simulator.hold(False)

    def hold_still(self, held: bool) -> None:
        """Hold the vehicle where it is (a test stand: it reads level and at rest while the
        motors spin), or let it go."""
        self._sim("the vehicle's pose").hold(held)
