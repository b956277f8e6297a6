"""The analysers' thresholds, each with what it is set from."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Limits:
    """The analysers' thresholds."""

    #: Vertical speed at ground contact: a free fall from 0.46 m reaches 3 m/s, more than
    #: a multirotor's legs take; half of it is three times ArduPilot's 0.5 m/s final
    #: landing speed (LAND_SPEED), firm but survivable.
    crash_speed_m_s: float = 3.0
    hard_landing_speed_m_s: float = 1.5
    #: Tilt on the ground (or at contact) that is no landing: on its side or worse.
    tipped_over_deg: float = 60.0
    #: A log's accelerometer peak that is an impact (1 g at rest, about 2 g in a hard
    #: manoeuvre) ...
    impact_g: float = 3.0
    #: ... when the motors explain no more than this much less of it: a 5-inch's punch-out
    #: reads 6 g of thrust (real logs: 5.8-6.4 g with every motor near full), an impact
    #: comes on top of what the motors push.
    impact_over_thrust_g: float = 2.0
    #: A landing ends at rest (1 g, the gyro quiet) this soon after its impact, or the log
    #: ends: a bump the quad flies on from is no landing.
    landing_rest_within_s: float = 2.0
    #: How far beyond the farthest target the vehicle may go before it is flying away.
    fly_away_margin_m: float = 25.0
    #: Betaflight's ANGLE mode limits the tilt to angle_limit (60 deg by default) and GPS
    #: Rescue to less; past 75 deg the FC is not holding the attitude it commands.
    lost_attitude_deg: float = 75.0
    upside_down_deg: float = 90.0
    #: Gyro against setpoint (roll and pitch, mean absolute error over the window).
    rate_error_deg_s: float = 200.0
    rate_error_window_s: float = 0.25
    #: Oscillation: a swing's RMS and its frequency, sustained over consecutive windows.  In
    #: a flight's record, the motors' roll and pitch split (a share of full throttle):
    #: measured, at most 0.063 RMS in the shipped scenarios and a square in 3 m/s wind with
    #: 1 m/s gusts, 0.19-0.47 with the gyro filtered at 15 Hz and P at 200.  In a log, the
    #: gyro's error from its setpoint.
    oscillation_motor_rms: float = 0.15
    oscillation_min_motor_hz: float = 2.0
    oscillation_rate_rms_deg_s: float = 30.0
    oscillation_min_rate_hz: float = 3.0
    oscillation_windows: int = 2
    #: A motor this close to full counts as saturated; for this long it is a finding.
    saturated_motor: float = 0.98
    saturation_min_s: float = 0.25
    #: A throttle at or above this share of the stick asks for full power (a punch-out):
    #: motors at full then do what the pilot asked, no control is lost.
    punch_out_throttle: float = 0.9
    #: The FC's GPS this far off the truth is a glitch; moving this far during one is
    #: following it.
    gps_glitch_m: float = 10.0
    gps_followed_m: float = 5.0
    #: Off the held target (after the first seconds of a hold, which settle).
    altitude_excursion_m: tuple[float, float] = (2.0, 5.0)
    position_excursion_m: tuple[float, float] = (3.0, 10.0)
    hold_settle_s: float = 3.0
    #: The FC's altitude against the truth (warning, failure).
    altitude_estimate_m: tuple[float, float] = (2.0, 5.0)
