"""Betaflight's attitude as a Foxglove transform: ENU world, FLU body, a unit quaternion.

Foxglove's 3D panel, like ROS (REP 103), expects right-handed frames with z up: the world
x east, y north, z up (ENU), the body x forward, y left, z up (FLU).  Betaflight reports roll
right-wing-down positive, pitch nose-DOWN positive and yaw as the heading clockwise from north
(MSP_ATTITUDE; bfsitl's simulated truth is given in the same convention).  The conversion goes
through the aerospace frames, where those angles are the usual Z-Y-X Euler angles (with the
pitch's sign flipped: aerospace pitch is nose up): R_ned_frd = Rz(yaw) Ry(pitch_up) Rx(roll),
then R_enu_flu = T R_ned_frd F, with T swapping north/east and flipping down, F flipping the
body's right and down axes.
"""

from __future__ import annotations

import math

Matrix = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


def _multiply(a: Matrix, b: Matrix) -> Matrix:
    return tuple(  # type: ignore[return-value]
        tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)) for i in range(3)
    )


#: NED vector -> ENU vector, and FLU body vector -> FRD body vector.
_NED_TO_ENU: Matrix = ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, -1.0))
_FLU_TO_FRD: Matrix = ((1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, -1.0))


def enu_flu_rotation(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Matrix:
    """The rotation taking FLU body vectors to ENU world vectors, from Betaflight's angles."""
    phi, theta, psi = (math.radians(roll_deg), math.radians(-pitch_deg), math.radians(yaw_deg))
    cf, sf, ct, st, cp, sp = (
        math.cos(phi),
        math.sin(phi),
        math.cos(theta),
        math.sin(theta),
        math.cos(psi),
        math.sin(psi),
    )
    ned_frd: Matrix = (
        (cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf),
        (sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf),
        (-st, ct * sf, ct * cf),
    )
    return _multiply(_multiply(_NED_TO_ENU, ned_frd), _FLU_TO_FRD)


def quaternion_xyzw(rotation: Matrix) -> tuple[float, float, float, float]:
    """A rotation matrix as a unit quaternion (x, y, z, w) with w >= 0."""
    (m00, m01, m02), (m10, m11, m12), (m20, m21, m22) = rotation
    trace = m00 + m11 + m22
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = 2.0 * math.sqrt(1.0 + m00 - m11 - m22)
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = 2.0 * math.sqrt(1.0 + m11 - m00 - m22)
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + m22 - m00 - m11)
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    if w < 0.0:
        x, y, z, w = -x, -y, -z, -w
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    return x / norm, y / norm, z / norm, w / norm


def betaflight_to_enu_quaternion(
    roll_deg: float, pitch_deg: float, yaw_deg: float
) -> tuple[float, float, float, float]:
    """Betaflight's roll/pitch/yaw as the (x, y, z, w) quaternion of the FLU body in ENU."""
    return quaternion_xyzw(enu_flu_rotation(roll_deg, pitch_deg, yaw_deg))
