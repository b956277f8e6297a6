"""Position and heading manoeuvres of the flight loop (GPS builds steer through ANGLE mode):
:class:`PositionManoeuvres`, which :class:`~bfsitl.mission.loop.FlightLoop` inherits."""

from __future__ import annotations

import math
from collections.abc import Callable

from bfsitl.control.base import AltitudeController
from bfsitl.control.heading import heading_error_deg
from bfsitl.fc.rc_link import RC_MID_US
from bfsitl.mission.flight_metrics import judged_position
from bfsitl.mission.flight_row import FlightRow
from bfsitl.mission.legs import LegPoint, LegReference, LegStats, leg_stats
from bfsitl.mission.phase import Phase
from bfsitl.mission.position_steering import PositionSteering, PositionTarget
from bfsitl.mission.vehicle import FlightSample, Vehicle

#: A turn is done once the heading has stayed within its tolerance this long.
TURNED_HOLD_S = 0.5


class PositionManoeuvres:
    """Hold a position, fly a leg, turn to a heading: the manoeuvres that steer the sticks
    as well as the throttle.  The flight loop supplies the state and the loop itself."""

    vehicle: Vehicle
    steering: PositionSteering
    target_alt_m: float
    stopped: str | None
    rows: list[FlightRow]
    legs: list[LegStats]
    _on_event: Callable[[str], None]
    #: The flight loop's inner loop (:meth:`FlightLoop._fly`).
    _fly: Callable[..., None]

    def hold_position(
        self,
        seconds: float,
        north_m: float | None = None,
        east_m: float | None = None,
        *,
        waypoint: int = 0,
    ) -> None:
        """Hold the altitude and a position (metres from the take-off point; default: the
        last position target, else where the FC's GPS is now) for ``seconds``, steering
        through ANGLE mode and holding the heading.

        Args:
            seconds: Seconds of simulation time.
            north_m: Metres north of the take-off point; None as said above.
            east_m: Metres east of the take-off point; None as said above.
            waypoint: The waypoint's number in the log (0: none).
        """
        if self.stopped:
            return
        target = self.steering.position_target(north_m, east_m)
        self._on_event(
            f"hold {target[0]:+.1f} m N {target[1]:+.1f} m E, "
            f"{self.target_alt_m:.2f} m up, for {seconds:g} s"
        )
        end_s = self.vehicle.time_s + seconds
        self._fly_position(
            Phase.HOLD,
            self._fixed(target),
            lambda s: s.time_s >= end_s,
            seconds + 5,
            waypoint=waypoint,
        )

    def fly_to(
        self,
        north_m: float,
        east_m: float,
        alt_m: float | None = None,
        *,
        speed_m_s: float | None = None,
        tolerance_m: float = 0.15,
        timeout_s: float | None = None,
        waypoint: int = 0,
    ) -> float:
        """Fly a straight leg to a position and altitude at ``speed_m_s``.

        The leg starts at the last position target (where the previous leg ended) or, before
        any, where the FC's GPS is.  It is reached once the travelling reference has stopped
        at the end and the FC's GPS puts the vehicle within ``tolerance_m`` of it, slower than
        0.3 m/s (tight, because the GPS's own error adds to it).  The leg's figures (arrival
        error and cross-track, from the truth) are appended to :attr:`legs`.

        Args:
            north_m: Metres north of the take-off point.
            east_m: Metres east of the take-off point.
            alt_m: Metres above the take-off point; None keeps the altitude held.
            speed_m_s: Metres per second along the leg; None is the gains' top speed.
            tolerance_m: Metres from the end, by the FC's GPS, that count as arrived.
            timeout_s: Seconds of simulation time; None: 20 plus 3 times the leg's plan.
            waypoint: The waypoint's number, for the log and the leg (0: the next one).

        Returns:
            Seconds of simulation time the leg took.
        """
        if self.stopped:
            return 0.0
        start = self.steering.position_target(None, None)
        start_alt_m = self.target_alt_m
        end = (north_m, east_m, start_alt_m if alt_m is None else alt_m)
        speed = self.steering.position.gains.max_speed_m_s if speed_m_s is None else speed_m_s
        reference = LegReference((start[0], start[1], start_alt_m), end, speed)
        if timeout_s is None:
            timeout_s = 20.0 + 3.0 * reference.duration_s
        label = f"waypoint {waypoint}: " if waypoint else ""
        # A leg too short to reach the speed asked says so (it peaks at what it can).
        short = (
            f": too short for it, peaks at {reference.peak_speed_m_s:.1f} m/s"
            if reference.peak_speed_m_s < speed - 0.05
            else ""
        )
        self._on_event(
            f"{label}fly to {north_m:+.1f} m N {east_m:+.1f} m E, {end[2]:.2f} m "
            f"up ({reference.length_m:.1f} m at {speed:g} m/s{short})"
        )
        started_s = self.vehicle.time_s
        first_row = len(self.rows)
        finished = [False]

        def target(elapsed_s: float) -> LegPoint:
            point = reference.at(elapsed_s)
            finished[0] = point.finished
            return point

        def arrived(_sample: FlightSample) -> bool:
            gps = self.steering.last_gps
            return (
                finished[0]
                and gps is not None
                and math.hypot(gps.north_m - north_m, gps.east_m - east_m) <= tolerance_m
                and math.hypot(gps.v_north_m_s, gps.v_east_m_s) < 0.3
            )

        self._fly_position(Phase.GOTO, target, arrived, timeout_s, waypoint=waypoint)
        if self.stopped:
            return self.vehicle.time_s - started_s  # not arrived: no leg to judge
        self.steering.target_ne = (north_m, east_m)
        took_s = self.vehicle.time_s - started_s
        self.legs.append(
            leg_stats(
                waypoint or len(self.legs) + 1,
                start,
                end,
                [judged_position(r) for r in self.rows[first_row:]],
                took_s,
            )
        )
        return took_s

    def yaw_to(
        self, heading_deg: float, *, tolerance_deg: float = 2.0, timeout_s: float = 30.0
    ) -> float:
        """Turn to ``heading_deg``, holding the altitude, and the position on a GPS build;
        reached when the FC's heading stays within ``tolerance_deg`` for half a second.

        Args:
            heading_deg: Degrees clockwise from north (taken modulo 360).
            tolerance_deg: Degrees off the heading that count as there.
            timeout_s: Seconds of simulation time for the turn.

        Returns:
            Seconds of simulation time the turn took.
        """
        if self.stopped:
            return 0.0
        target_deg = heading_deg % 360.0
        self._on_event(f"turn to heading {target_deg:.0f} deg")
        self.steering.target_heading_deg = target_deg
        started_s = self.vehicle.time_s
        within_since: list[float] = []

        def turned(sample: FlightSample) -> bool:
            if abs(heading_error_deg(target_deg, sample.yaw_deg)) > tolerance_deg:
                within_since.clear()
                return False
            if not within_since:
                within_since.append(sample.time_s)
            return sample.time_s - within_since[0] >= TURNED_HOLD_S

        if self.vehicle.has_gps:
            here = self.steering.position_target(None, None)
            self._fly_position(Phase.YAW, self._fixed(here), turned, timeout_s)
        else:
            self._fly(
                Phase.YAW,
                self.target_alt_m,
                turned,
                timeout_s=timeout_s,
                steer=self.steering.steer_heading,
            )
            self.steering.set_sticks(yaw_us=RC_MID_US)
        return self.vehicle.time_s - started_s

    def _fly_position(
        self,
        phase: Phase,
        target: PositionTarget,
        done: Callable[[FlightSample], bool],
        timeout_s: float,
        *,
        waypoint: int = 0,
        controller: AltitudeController | None = None,
    ) -> None:
        steer = self.steering.steer_to(target, waypoint)
        try:
            self._fly(
                phase,
                target(0.0).alt_m,
                done,
                timeout_s=timeout_s,
                steer=steer,
                controller=controller,
            )
        finally:
            self.steering.end()

    def _fixed(self, north_east: tuple[float, float]) -> PositionTarget:
        """A position target that stays put at the altitude held."""
        return self.steering.fixed(north_east, self.target_alt_m)
