"""A hand-written policy for the environments: the yardstick a learned one is measured with.

It reads only the observation (so it flies ``observation="fc"`` as well as ``"truth"``): the
target's offset and the velocity turned into the body's heading, then proportional-derivative
sticks in ANGLE mode (forward stick is nose down, so it moves the quad forward; right stick
rolls right), and throttle about the hover point with the height error and climb rate.
"""

from __future__ import annotations

import numpy as np

from bfsitl.physics.params import QuadParams
from bfsitl.vehicles.throttle import IRIS_HOVER_THROTTLE_US, THROTTLE_LOW_US, hover_throttle_us

#: A stick of -1..1 spans 1000..2000 us.
STICK_MID_US, STICK_HALF_US = 1500.0, 500.0

#: The throttle stick (-1..1) about which the IRIS of the embedded physics hovers in ANGLE
#: mode on 4.6.0 (measured: 0.05 and 0.15 hold worse than this).
HOVER_THROTTLE = 0.1


def hover_stick(quad: QuadParams) -> float:
    """The throttle stick (-1..1) about which ``quad`` hovers: IRIS's, carried over as its
    hover throttle is (:mod:`bfsitl.vehicles.throttle`); exactly :data:`HOVER_THROTTLE` on
    IRIS."""
    iris_us = STICK_MID_US + HOVER_THROTTLE * STICK_HALF_US
    scale = (hover_throttle_us(quad) - THROTTLE_LOW_US) / (IRIS_HOVER_THROTTLE_US - THROTTLE_LOW_US)
    return (THROTTLE_LOW_US + (iris_us - THROTTLE_LOW_US) * scale - STICK_MID_US) / STICK_HALF_US


_POSITION_GAIN, _VELOCITY_GAIN, _TILT_STICK_LIMIT = 0.15, 0.25, 0.4
_HEIGHT_GAIN, _CLIMB_GAIN = 0.25, 0.3


def hand_policy(observation: np.ndarray, hover_throttle: float = HOVER_THROTTLE) -> np.ndarray:
    """Sticks (roll, pitch, throttle, yaw) that fly towards the observation's target."""
    d_north, d_east, d_up, v_north, v_east, v_up = observation[:6].tolist()
    sin_yaw, cos_yaw = observation[8:10].tolist()
    forward = d_north * cos_yaw + d_east * sin_yaw
    right = -d_north * sin_yaw + d_east * cos_yaw
    v_forward = v_north * cos_yaw + v_east * sin_yaw
    v_right = -v_north * sin_yaw + v_east * cos_yaw
    pitch = _clip(_POSITION_GAIN * forward - _VELOCITY_GAIN * v_forward, _TILT_STICK_LIMIT)
    roll = _clip(_POSITION_GAIN * right - _VELOCITY_GAIN * v_right, _TILT_STICK_LIMIT)
    throttle = _clip(hover_throttle + _HEIGHT_GAIN * d_up - _CLIMB_GAIN * v_up, 1.0)
    return np.array([roll, pitch, throttle, 0.0], dtype=np.float32)


def _clip(value: float, limit: float) -> float:
    # Plain floats: numpy's clip on one number costs more than the rest of the policy.
    return -limit if value < -limit else (limit if value > limit else value)
