"""Position and heading control for the flight loop: the FC's GPS made local, the ANGLE
stick curve, the position loop's sticks and the heading hold.

A :class:`~bfsitl.mission.loop.FlightLoop` holds one :class:`PositionSteering` (its
``steering``) and asks it, once per step of a position manoeuvre, for the sticks
(:meth:`PositionSteering.steer_to`); the steering owns its state (the position and heading
controllers, the last target, the columns it adds to the loop's rows) and knows nothing of
the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from bfsitl.control.angle_sticks import AngleStickMap
from bfsitl.control.heading import HeadingController
from bfsitl.control.horizontal_estimator import (
    HorizontalEstimator,
    specific_force_north_east,
)
from bfsitl.control.position import PositionController, PositionGains, PositionInput
from bfsitl.errors import MissionError, MspErrorReply
from bfsitl.fc.rc_link import RC_MID_US, RcCommand
from bfsitl.mission.legs import LegPoint
from bfsitl.mission.vehicle import FlightSample, GpsPosition, Vehicle
from bfsitl.protocol import messages as msg

#: Time since the manoeuvre began -> where the position and altitude targets are.
PositionTarget = Callable[[float], LegPoint]


class PositionSteering:
    """Steers a vehicle to position targets through ANGLE mode, holding a heading."""

    def __init__(self, vehicle: Vehicle, rate_hz: float) -> None:
        """``rate_hz``: the loop's control rate (the position gains are tuned for it and for
        whether the vehicle's physics is in lockstep with the FC)."""
        self.vehicle = vehicle
        self.position = PositionController(
            PositionGains.for_loop_rate(rate_hz, lockstep=vehicle.lockstep)
        )
        #: Fuses the FC's accelerometer with its GPS for the position loop (None: the GPS
        #: alone, extrapolated by the gains' lead).
        self.horizontal: HorizontalEstimator | None = None
        #: The FC's ANGLE-mode stick curve, read from it at the first position manoeuvre.
        self.sticks: AngleStickMap | None = None
        self.last_gps: GpsPosition | None = None
        self.heading = HeadingController()
        #: The heading held during position control and turned to by ``yaw_to``.
        self.target_heading_deg: float | None = None
        #: The last position target (north, east): where the next leg starts (None before
        #: the first position manoeuvre).
        self.target_ne: tuple[float, float] | None = None
        #: What the step being recorded adds to its row: the FC's GPS and the target (position
        #: control only), and the waypoint being flown to or held (0: none).
        self.row_columns: dict[str, float] = {}
        self.waypoint = 0

    def reset(self, time_s: float) -> None:
        """At arming: nothing learnt of the wind yet, the estimator starts again."""
        self.position.reset(time_s)
        if self.horizontal is not None:
            self.horizontal.started = False

    @staticmethod
    def fixed(north_east: tuple[float, float], alt_m: float) -> PositionTarget:
        """A position target that stays put at ``alt_m``."""
        point = LegPoint(north_east[0], north_east[1], alt_m, 0.0, 0.0, 0.0, 0.0, True)
        return lambda _elapsed_s: point

    def position_target(self, north_m: float | None, east_m: float | None) -> tuple[float, float]:
        """The given coordinates, else the last target, else where the FC's GPS is now."""
        if self.target_ne is None:
            gps = self.read_gps()
            self.target_ne = (gps.north_m, gps.east_m)
        return (
            self.target_ne[0] if north_m is None else north_m,
            self.target_ne[1] if east_m is None else east_m,
        )

    def read_gps(self, sample: FlightSample | None = None) -> GpsPosition:
        """The FC's GPS (kept in :attr:`last_gps`): taken with ``sample``, else now; raises
        without a GPS or a fix."""
        try:
            gps = self.vehicle.gps_position(sample)
        except MspErrorReply as exc:
            raise MissionError(
                "position control needs the FC's GPS, and this firmware has none (it refused "
                "MSP_RAW_GPS): fly a GPS build (`bfsitl firmware build --gps`, add --lockstep "
                "for lockstep; master always has it)"
            ) from exc
        if not gps.has_fix:
            raise MissionError(
                f"the FC's GPS has no fix ({gps.satellites} satellites): position control needs one"
            )
        self.last_gps = gps
        return gps

    def stick_map(self) -> AngleStickMap:
        if self.sticks is None:
            client = self.vehicle.client
            self.sticks = AngleStickMap.from_replies(
                client.get(msg.RcTuning), client.get(msg.PidAdvanced)
            )
        return self.sticks

    def set_sticks(
        self,
        *,
        roll_us: float | None = None,
        pitch_us: float | None = None,
        yaw_us: float | None = None,
    ) -> None:
        """Roll, pitch and yaw (those given); the throttle and switches stay as they are."""
        rc = self.vehicle.rc_command
        self.vehicle.set_rc(
            RcCommand(
                rc.roll_us if roll_us is None else roll_us,
                rc.pitch_us if pitch_us is None else pitch_us,
                rc.throttle_us,
                rc.yaw_us if yaw_us is None else yaw_us,
                rc.aux_us,
            )
        )

    def steer_heading(self, sample: FlightSample) -> None:
        """Yaw towards :attr:`target_heading_deg` (set to the heading now if there is none)."""
        self.set_sticks(yaw_us=self._heading_stick_us(sample))

    def _heading_stick_us(self, sample: FlightSample) -> float:
        """The yaw stick towards :attr:`target_heading_deg` (set to the heading now if there
        is none), which goes into the row's columns."""
        if self.target_heading_deg is None:
            self.target_heading_deg = sample.yaw_deg % 360.0
        rate = self.heading.rate_deg_s(sample.yaw_deg, self.target_heading_deg)
        self.row_columns["target_heading_deg"] = self.target_heading_deg
        return self.stick_map().yaw_stick_us(rate)

    def steer_to(
        self, target: PositionTarget, waypoint: int
    ) -> Callable[[FlightSample], float | None]:
        """Position and heading control towards ``target`` from now on (the position loop
        resumes here): the step it returns sets the roll, pitch and yaw sticks and returns the
        altitude target.  :meth:`end` ends it."""
        sticks = self.stick_map()
        started_s = self.vehicle.time_s
        self.position.resume(started_s)
        # Each step reads the GPS: in the sample's round trip, not one of its own.
        self.vehicle.read_with_samples(msg.RawGps)

        def steer(sample: FlightSample) -> float | None:
            gps = self.read_gps(sample)
            point = target(sample.time_s - started_s)
            north, east = point.north_m, point.east_m
            here = (gps.north_m, gps.east_m, gps.v_north_m_s, gps.v_east_m_s)
            if self.horizontal is not None and all(map(math.isfinite, sample.fc_accel_flu_m_s2)):
                a_north, a_east = specific_force_north_east(
                    sample.fc_accel_flu_m_s2, sample.roll_deg, sample.pitch_deg, sample.yaw_deg
                )
                fused = self.horizontal.update(sample.time_s, a_north, a_east, here)
                here = (fused.north_m, fused.east_m, fused.v_north_m_s, fused.v_east_m_s)
            tilt = self.position.update(
                PositionInput(
                    sample.time_s,
                    *here,
                    sample.yaw_deg,
                    north,
                    east,
                    point.v_north_m_s,
                    point.v_east_m_s,
                    point.a_north_m_s2,
                    point.a_east_m_s2,
                )
            )
            self.row_columns = {
                "fc_north_m": gps.north_m,
                "fc_east_m": gps.east_m,
                "target_north_m": north,
                "target_east_m": east,
            }
            self.waypoint = waypoint
            # The three sticks in one command (one RC change per step, not two).
            self.set_sticks(
                roll_us=sticks.stick_us("roll", tilt.roll_deg),
                pitch_us=sticks.stick_us("pitch", tilt.pitch_deg),
                yaw_us=self._heading_stick_us(sample),
            )
            return point.alt_m

        return steer

    def end(self) -> None:
        """Position control is over: no columns, no waypoint, roll, pitch and yaw centred."""
        self.row_columns, self.waypoint = {}, 0
        self.set_sticks(roll_us=RC_MID_US, pitch_us=RC_MID_US, yaw_us=RC_MID_US)
