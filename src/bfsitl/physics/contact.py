"""Ground contact and rest: the half of :class:`~bfsitl.physics.multirotor.Simulator` that
knows about the ground.

Spring-dampers at the eight corners of the Gazebo collision box (the four bottom ones are the
skids) with Coulomb friction, and the static-friction "rest" that freezes a vehicle sitting on
its skids (the module docstring of :mod:`bfsitl.physics.multirotor` says why each choice).
:class:`GroundContact` is a mixin: it reads the rigid body's state, which the simulator owns,
and sets the touching flags it reports.  Its methods are the simulator's own (no copies, no
extra calls in the 1 ms step), kept here so that the rigid body and the ground read apart.
"""

from __future__ import annotations

import math

from bfsitl.physics.params import Quat, Vec3

#: When a vehicle on all four skids counts as at rest (and is then frozen exactly).  The
#: motions the contact springs carry (vertical, roll, pitch) must have settled: slow *and*
#: unaccelerated, or a landing could freeze at the bottom of its compression, where the speed
#: passes through zero with the spring loaded.  These limits bound the offset from the static
#: sag a freeze can trap: acceleration / omega^2 (0.5 / 6900 ~ 70 um) plus speed / slow pole
#: of the overdamped contact (~27 /s: 40 um).  Tilt needs no acceleration limit: the roll and
#: pitch modes ring at ~230 rad/s, so a rate below 0.002 rad/s at a step leaves < 1e-5 rad
#: (tilted drops with the contact damping cut to 0.3 freeze level to 2e-4 deg).  The motions
#: only friction resists (sliding, yaw) store nothing: they merely have to be slow, and then
#: stop at once, as Coulomb friction does.  Loose enough to freeze under gusts and a flight
#: controller still fiddling with the motors.
REST_VERTICAL_SPEED_M_S = 0.001
REST_VERTICAL_ACCEL_M_S2 = 0.5
REST_TILT_RATE_RAD_S = 0.002
REST_SLIDE_SPEED_M_S = 0.02
REST_YAW_RATE_RAD_S = 0.02
#: To freeze, the centre of pressure must be this far inside the skid rectangle and the
#: friction needed this far below mu N; once frozen, only the true limits release it (the
#: hysteresis keeps it from flickering, and from creeping on the viscous stick in between).
REST_MARGIN = 0.95
_BOTTOM = ((1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0))


class GroundContact:
    """Contact forces, touching corners and the rest test of the rigid body it is mixed into."""

    # The rigid body's state and constants (set by the simulator).
    _p: Vec3
    _v: Vec3
    _w: Vec3
    _q: Quat
    _sf_world: Vec3
    _box: tuple[float, float, float, float]
    _reach: float
    _k: float
    _c: float
    _mu: float
    _stick: float
    _m: float
    _g: float
    _touching: int
    _on_skids: bool

    def _contact_possible(self, dt_s: float) -> bool:
        """Could a corner reach the ground within this step?  (Else: one plain step.)"""
        pz = self._p[2]
        if pz + self._reach <= 0.0:
            return False
        v, w = self._v, self._w
        rate = math.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
        reach = (abs(v[2]) + rate * self._reach) * dt_s + 1e-3
        return pz + self._lowest_corner_m(self._q) + reach > 0.0

    def _lowest_corner_m(self, q: Quat) -> float:
        """Largest world "down" offset of any contact corner from the CoM at attitude q."""
        w, x, y, z = q
        r20, r21, r22 = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)
        ax, ay, zb, zt = self._box
        return abs(ax * r20) + abs(ay * r21) + max(zb * r22, zt * r22)

    def _corners_touching(self) -> tuple[int, int]:
        w, x, y, z = self._q
        r20, r21, r22 = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)
        ax, ay, zb, zt = self._box
        pz = self._p[2]
        bottom = top = 0
        for sx, sy in _BOTTOM:
            lateral = pz + sx * ax * r20 + sy * ay * r21
            bottom += lateral + zb * r22 > 0.0
            top += lateral + zt * r22 > 0.0
        return bottom, top

    def _contact(
        self, r00: float, r01: float, r02: float, r10: float, r11: float, r12: float,
        r20: float, r21: float, r22: float,
    ) -> tuple[float, float, float, float, float, float]:
        """Ground force (world) and torque (body) of the box corners that are below z = 0.

        Per corner: normal n = k d + c d_dot (pushing only), friction -min(mu n, stick |v_t|)
        along the corner's sliding direction.  Also counts touching corners for rest checks.
        """
        bx, by, zb, zt = self._box
        # World offsets of the corner building blocks: R (bx, 0, 0), R (0, by, 0), R (0, 0, z).
        a0, a1, a2 = r00 * bx, r10 * bx, r20 * bx
        b0, b1, b2 = r01 * by, r11 * by, r21 * by
        px, py, pz = self._p
        vx, vy, vz = self._v
        p, q, r = self._w
        ox = r00 * p + r01 * q + r02 * r  # body rate in world axes
        oy = r10 * p + r11 * q + r12 * r
        oz = r20 * p + r21 * q + r22 * r
        k, c, mu, stick = self._k, self._c, self._mu, self._stick
        fx = fy = fz = tx = ty = tz = 0.0
        bottom = top = 0
        lateral = abs(a2) + abs(b2)
        for level, is_bottom in ((zb, True), (zt, False)):
            c0, c1, c2 = r02 * level, r12 * level, r22 * level
            if pz + lateral + c2 <= 0.0:
                continue  # no corner of this face reaches the ground (e.g. the top when upright)
            for sx, sy in _BOTTOM:
                rz = sx * a2 + sy * b2 + c2
                d = pz + rz
                if d <= 0.0:
                    continue
                if is_bottom:
                    bottom += 1
                else:
                    top += 1
                rx = sx * a0 + sy * b0 + c0
                ry = sx * a1 + sy * b1 + c1
                # Velocity of the corner: v + omega x r (world).
                cvx = vx + oy * rz - oz * ry
                cvy = vy + oz * rx - ox * rz
                cvz = vz + ox * ry - oy * rx
                n = k * d + c * cvz
                if n <= 0.0:
                    continue
                slide = math.sqrt(cvx * cvx + cvy * cvy)
                if slide > 0.0:
                    f = mu * n
                    viscous = stick * slide
                    if viscous < f:
                        f = viscous
                    f /= slide
                    gx, gy = -f * cvx, -f * cvy
                else:
                    gx = gy = 0.0
                gz = -n
                fx += gx
                fy += gy
                fz += gz
                tx += ry * gz - rz * gy
                ty += rz * gx - rx * gz
                tz += rx * gy - ry * gx
        self._touching = bottom + top
        self._on_skids = bottom == 4 and top == 0
        # Torque into body axes: R^T t.
        return (
            fx, fy, fz,
            r00 * tx + r10 * ty + r20 * tz,
            r01 * tx + r11 * ty + r21 * tz,
            r02 * tx + r12 * ty + r22 * tz,
        )

    # ---- rest (static friction) -------------------------------------------------------------

    def _rest_holds(self, fb: Vec3, mb: Vec3, margin: float) -> bool:
        """Can the four skids carry the applied force and torque with the body still?

        Quasi-static: normal load N > 0; centre of pressure (torque balance about the CoM,
        friction acting at skid depth) inside the skid rectangle; sideways force plus yaw
        torque over the corner radius within mu N.
        """
        w, x, y, z = self._q
        r20, r21, r22 = 2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)
        mg = self._m * self._g
        fx, fy = fb[0] + mg * r20, fb[1] + mg * r21
        normal = fb[2] + mg * r22
        if normal <= 0.0:
            return False
        bx, by, zb, _ = self._box
        limit = margin * normal
        if abs(zb * fy + mb[0]) > by * limit or abs(zb * fx - mb[1]) > bx * limit:
            return False
        corner = math.sqrt(bx * bx + by * by)
        return math.sqrt(fx * fx + fy * fy) + abs(mb[2]) / corner <= self._mu * limit

    def _at_rest_now(self, fb: Vec3, mb: Vec3) -> bool:
        """Settled on the springs, slow on the friction, and the skids can carry the load.

        Uses body rates as roll/pitch/yaw rates: the vehicle is level to within its sag here.
        """
        v, w, f = self._v, self._w, self._sf_world
        if abs(v[2]) >= REST_VERTICAL_SPEED_M_S:
            return False
        if abs(f[2] + self._g) >= REST_VERTICAL_ACCEL_M_S2:
            return False
        if v[0] * v[0] + v[1] * v[1] >= REST_SLIDE_SPEED_M_S * REST_SLIDE_SPEED_M_S:
            return False
        p, q, r = w
        if p * p + q * q >= REST_TILT_RATE_RAD_S * REST_TILT_RATE_RAD_S:
            return False
        if abs(r) >= REST_YAW_RATE_RAD_S:
            return False
        return self._rest_holds(fb, mb, REST_MARGIN)
