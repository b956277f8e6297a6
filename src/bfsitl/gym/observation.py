"""The observation vector: 23 numbers, the same layout for the FC's view and for the truth.

=====  ==================================================================  =======
index  what                                                                unit
=====  ==================================================================  =======
0-2    the target minus the position: north, east, up                      m
3-5    velocity: north, east, up                                           m/s
6-7    roll (right wing down +), pitch (nose down +)                       rad
8-9    sin and cos of the heading (clockwise from north)                   -
10-12  body rates, FLU (x forward, y left, z up)                           rad/s
13-15  specific force, FLU (+9.81 on z at rest)                            m/s^2
16-19  motor outputs M1..M4 (Betaflight's order)                           0..1
20-22  the leg after this one: the next target minus the target: N, E, up  m
=====  ==================================================================  =======

``observation="fc"`` fills it only from what the FC says over MSP: the GPS (position,
velocity), MSP_ALTITUDE (height, vario), MSP_ATTITUDE, MSP_RAW_IMU and MSP_MOTOR.  On a build
without a GPS the horizontal position and velocity are 0: use a GPS build
(``bfsitl firmware build --gps --lockstep``).  ``observation="truth"`` fills the same slots
from the simulation, for comparison.

Slots 20-22 let a course be flown through a point rather than to it (Waypoints-v0 knows where
it turns next); they are 0 where there is no next point: a hover, a recovery, the last
waypoint.  The first 20 slots are the layout before them (``bfsitl.gym.observation/20``), so a
policy exported with that layout still flies (:class:`~bfsitl.gym.onnx_policy.OnnxPolicy`).
"""

from __future__ import annotations

import math
from typing import Literal, get_args

import numpy as np
from gymnasium import spaces

from bfsitl.gym.snapshot import FcView, Snapshot, TrueView, Vec3

OBSERVATION_SIZE = 23
#: The layout before the next leg's slots: a policy exported then reads these first slots.
FIRST_LAYOUT_SIZE = 20
#: What fills the observation: what the FC reports (``fc``) or the simulation (``truth``).
ObservationSource = Literal["fc", "truth"]
OBSERVATIONS: tuple[ObservationSource, ...] = get_args(ObservationSource)

#: Bounds of each slot, far outside a flight (a 2000 deg/s gyro is 35 rad/s, a 16 g
#: accelerometer 157 m/s^2); a value beyond them is clipped, so every observation is inside
#: the space.
_HIGH = np.array(
    [1000.0] * 3
    + [100.0] * 3
    + [math.pi] * 2
    + [1.0] * 2
    + [100.0] * 3
    + [1000.0] * 3
    + [1.0] * 4
    + [1000.0] * 3,
    dtype=np.float32,
)
_LOW = np.concatenate([-_HIGH[:16], np.zeros(4, dtype=np.float32), -_HIGH[20:]])


def observation_space() -> spaces.Box:
    """The space every observation is in."""
    return spaces.Box(_LOW, _HIGH, dtype=np.float32)


def observe(
    snapshot: Snapshot, target: Vec3, which: ObservationSource, next_target: Vec3 | None = None
) -> np.ndarray:
    """The observation of ``snapshot`` towards ``target`` (north, east, up), then
    ``next_target`` (None: there is no next point)."""
    return observe_view(snapshot.fc if which == "fc" else snapshot.truth, target, next_target)


def observe_view(
    view: FcView | TrueView, target: Vec3, next_target: Vec3 | None = None
) -> np.ndarray:
    """The observation of one view (the FC's or the truth) towards ``target`` (north, east,
    up), then ``next_target`` (None: none, the slots are 0): what a trained policy is given
    in training and wherever it flies."""
    after = target if next_target is None else next_target
    # The FC's climb rate is MSP_ALTITUDE's vario; the truth's is its vertical velocity.
    v_up = view.climb_m_s if isinstance(view, FcView) else view.v_up_m_s
    values = (
        target[0] - view.north_m,
        target[1] - view.east_m,
        target[2] - view.alt_m,
        view.v_north_m_s,
        view.v_east_m_s,
        v_up,
        view.roll_rad,
        view.pitch_rad,
        math.sin(view.yaw_rad),
        math.cos(view.yaw_rad),
        *view.rates_flu_rad_s,
        *view.accel_flu_m_s2,
        *view.motors,
        after[0] - target[0],
        after[1] - target[1],
        after[2] - target[2],
    )
    return np.clip(np.asarray(values, dtype=np.float32), _LOW, _HIGH)
