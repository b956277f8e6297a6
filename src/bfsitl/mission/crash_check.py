"""When a flight counts as crashed: the rules the flight loop raises on, and the scenario
expectations and the gym tasks apply to the recorded truth once nobody flies."""

from __future__ import annotations

import math

from bfsitl.errors import CrashDetectedError, MissionError
from bfsitl.mission.vehicle import FlightSample

#: Tilt beyond which the vehicle is taken as crashed (ANGLE mode limits it to about 55 deg).
CRASH_TILT_DEG = 70.0
#: Hitting the ground faster than this is a crash, not a landing.
CRASH_TOUCHDOWN_M_S = 2.5


def check_flying(sample: FlightSample, doing: str) -> None:
    """Raise if the vehicle is no longer flying as it should.

    Args:
        sample: The latest sample of the FC and the truth.
        doing: What the flight is doing (its phase), for the message.

    Raises:
        CrashDetectedError: It tipped over or hit the ground too fast.
        MissionError: The FC disarmed.
    """
    # The truth when the physics is ours; the FC's attitude otherwise (Gazebo).
    tilt_deg = (
        sample.sim_tilt_deg
        if math.isfinite(sample.sim_tilt_deg)
        else max(abs(sample.roll_deg), abs(sample.pitch_deg))
    )
    if tilt_deg > CRASH_TILT_DEG:
        raise CrashDetectedError(
            f"the vehicle tipped over ({tilt_deg:.0f} deg from level at t={sample.time_s:.1f} s)"
        )
    if sample.on_ground and sample.sim_climb_m_s < -CRASH_TOUCHDOWN_M_S:
        raise CrashDetectedError(f"hit the ground at {-sample.sim_climb_m_s:.1f} m/s")
    if not sample.armed:
        names = ", ".join(sample.arming_blockers) or "no blocker reported"
        raise MissionError(f"the FC disarmed during {doing} ({names})")
