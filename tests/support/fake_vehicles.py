"""Vehicles without a SITL for the flight loop: :class:`FakeVehicle`, a point mass whose climb
rate follows the throttle (an FC altitude that lags it), :class:`PlanarVehicle`, the same
with a horizontal point mass steered by the sticks through the ANGLE-mode curve, and the
controllers that fly them."""

from __future__ import annotations

from dataclasses import dataclass, replace

from bfsitl.fc.rc_link import RcCommand, RcLinkStats
from bfsitl.mission.loop import FlightLoop
from bfsitl.mission.vehicle import SWITCH_ON_US, FlightSample, Vehicle

HOVER_US = 1500.0


@dataclass
class _Config:
    speed: float = 1.0


class FakeClock:
    """The mission clock of the fake: sampling moves time; waits are only counted."""

    def __init__(self, vehicle: FakeVehicle) -> None:
        self.vehicle = vehicle
        self.slept_s = 0.0

    def now_s(self) -> float:
        return self.vehicle.time_s

    def sleep_s(self, seconds: float) -> None:
        self.slept_s += seconds


class FakeVehicle(Vehicle):
    """Time advances 20 ms per sample; climb rate = (throttle - hover) / 200 m/s.

    A :class:`Vehicle` whose FC is this point mass: what the base class does over MSP
    (arming, sampling) is replaced here."""

    # Plain attributes where the base class has properties: the fake sets them.
    time_s: float = 0.0  # type: ignore[assignment]
    has_gps: bool = False  # type: ignore[assignment]

    def __init__(
        self,
        *,
        tilt_deg: float = 0.0,
        arm_error: Exception | None = None,
        fail_after: int | None = None,
        failure: BaseException | None = None,
    ) -> None:
        super().__init__()
        self.config = _Config(speed=50.0)
        self.clock = FakeClock(self)  # the runner waits on it, never on the wall clock
        self.time_s = 0.0
        self.altitude_m = 0.0
        self.climb_m_s = 0.0
        self.armed = False
        self.armed_after_s: float | None = None
        self.rc = self
        self.sitl = None
        self.command = RcCommand(aux_us=(1000, 1000))
        self.tilt_deg = tilt_deg
        self.arm_error = arm_error
        self.samples = 0
        self.fail_after = fail_after
        self.failure = failure

    # the parts of FlightSession the runner uses
    def arm(self) -> None:
        if self.arm_error is not None:
            raise self.arm_error
        self.armed, self.armed_after_s = True, 5.2
        self.command = replace(self.command, aux_us=(SWITCH_ON_US, SWITCH_ON_US))

    def disarm(self) -> bool:
        self.command = replace(self.command, throttle_us=1000, aux_us=(1000, 1000))
        self.armed = False
        return True

    @property
    def rc_command(self) -> RcCommand:
        return self.command

    def set_rc(self, command: RcCommand) -> None:
        self.command = command

    def set_throttle(self, throttle_us: float) -> None:
        self.command = replace(self.command, throttle_us=throttle_us)

    def sample(self) -> FlightSample:
        self.samples += 1
        if self.fail_after is not None and self.samples > self.fail_after:
            assert self.failure is not None
            raise self.failure
        climb = (self.command.throttle_us - HOVER_US) / 200.0 if self.armed else 0.0
        accel_up = (climb - self.climb_m_s) / 0.02
        self.climb_m_s = climb
        self.altitude_m = max(0.0, self.altitude_m + climb * 0.02)
        self.time_s += 0.02
        on_ground = self.altitude_m <= 0.0
        return FlightSample(
            time_s=self.time_s,
            wall_s=self.time_s,
            fc_alt_m=round(self.altitude_m, 2),
            fc_climb_m_s=climb,
            fc_accel_up_m_s2=accel_up,
            roll_deg=0.0,
            pitch_deg=0.0,
            yaw_deg=0.0,
            sim_alt_m=self.altitude_m,
            sim_climb_m_s=0.0 if on_ground else climb,
            sim_tilt_deg=self.tilt_deg,
            sim_roll_deg=self.tilt_deg,
            sim_pitch_deg=0.0,
            sim_yaw_deg=0.0,
            on_ground=on_ground,
            armed=self.armed,
            arming_blockers=(),
            flight_modes=("ARM",),
            motors=(0.5,) * 4,
            rc=self.command,
        )

    def rc_stats(self) -> RcLinkStats:
        return RcLinkStats(10, 10.0, 10.5, 11.0, 0)

    def bridge_stats(self) -> None:
        return None


class PController:
    """Climb-rate proportional to the error; enough to reach and hold in the fake."""

    name = "p"

    def __init__(self) -> None:
        self.resets = 0

    def reset(self, time_s: float) -> None:
        self.resets += 1

    def update(self, sample) -> float:  # type: ignore[no-untyped-def]
        return HOVER_US + 150.0 * (sample.target_alt_m - sample.altitude_m)


class Descend:
    name = "descend"

    def __init__(self) -> None:
        self.touched_down = False

    def reset(self, time_s: float) -> None:
        self.touched_down = False

    def update(self, sample) -> float:  # type: ignore[no-untyped-def]
        if sample.altitude_m <= 0.0:
            self.touched_down = True
            return 1000.0
        return HOVER_US - 100.0


class PlanarVehicle(FakeVehicle):
    """FakeVehicle plus a horizontal point mass driven by the roll/pitch sticks through the
    ANGLE-mode stick map, a heading driven by the yaw stick, and a GPS that reports the truth.

    A steady wind pushes it ``wind_push_m_s2`` north, so a controller that ignores position
    or has a sign wrong ends somewhere else.
    """

    def __init__(self, *, wind_push_m_s2: float = 0.3, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(**kwargs)
        from bfsitl.control.angle_sticks import AngleStickMap

        self.sticks = AngleStickMap.linear()
        self.north_m = self.east_m = self.v_north = self.v_east = 0.0
        self.heading_deg = 0.0
        self.wind_push_m_s2 = wind_push_m_s2
        self.has_gps = True

    def sample(self) -> FlightSample:
        import math

        sample = super().sample()
        dt = 0.02
        if self.armed and self.altitude_m > 0.05:
            from bfsitl.physics.constants import STANDARD_GRAVITY_M_S2 as g

            roll = math.radians(self.sticks.angle_deg("roll", self.command.roll_us))
            pitch = math.radians(self.sticks.angle_deg("pitch", self.command.pitch_us))
            a_fwd, a_right = g * math.tan(pitch), g * math.tan(roll)
            psi = math.radians(self.heading_deg)
            a_n = a_fwd * math.cos(psi) - a_right * math.sin(psi) + self.wind_push_m_s2
            a_e = a_fwd * math.sin(psi) + a_right * math.cos(psi)
            self.v_north += (a_n - 0.3 * self.v_north) * dt
            self.v_east += (a_e - 0.3 * self.v_east) * dt
            self.north_m += self.v_north * dt
            self.east_m += self.v_east * dt
            yaw_rate = self.sticks.yaw.setpoint((self.command.yaw_us - 1500.0) / 500.0)
            self.heading_deg = (self.heading_deg + yaw_rate * dt) % 360.0
        return replace(
            sample,
            yaw_deg=self.heading_deg,
            sim_yaw_deg=self.heading_deg,
            sim_north_m=self.north_m,
            sim_east_m=self.east_m,
        )

    def gps_position(self, sample=None):  # type: ignore[no-untyped-def]
        from bfsitl.mission.vehicle import GpsPosition

        return GpsPosition(self.north_m, self.east_m, self.v_north, self.v_east, True, 12)


def planar_loop(vehicle: PlanarVehicle, log=None) -> FlightLoop:  # type: ignore[no-untyped-def]
    loop = FlightLoop(vehicle, PController(), log=log)  # type: ignore[arg-type]
    loop.steering.sticks = vehicle.sticks  # the FC's curve would be read over MSP
    return loop
