/*
 * The embedded physics (see physics.h for how Python drives it).
 *
 * The model is Gazebo-IRIS parity (docs/firmware-facts.md#iris-model,
 * docs/firmware-facts.md#iris-motors) with these choices, each made for the 1 ms step
 * (docs/firmware-facts.md#model-choices):
 *
 * - Motors: first-order lag towards the speed the Gazebo joint P controller settles at,
 *   updated exactly (1 - exp(-h/tau), tau = 0.82 ms) and slew-limited by the +-2.5 N m motor
 *   torque clamp.  The rotor's spin-up reaction I_r dOmega/dt is applied to the frame (on IRIS
 *   it dominates transient yaw), as is the rotor gyroscopic torque.
 * - Rotors: T = k_T Omega^2, Q = k_Q Omega^2, with the LiftDrag elements' axial-inflow
 *   term linearised: climbing at v through the disc lowers the angle of attack by v / (Omega r),
 *   so T = k_T Omega (Omega - v / (r a0)), capped at stall.
 * - Integrator: one force evaluation per step.  Symplectic Euler for translation (v first,
 *   then p with the new v: no drift in a hover or on the contact springs); an explicit midpoint
 *   step for Euler's equations (plain Euler pumps energy into a free rotation); the exponential
 *   map of the step's mean body rate for the quaternion, renormalised.  RK4 would cost four
 *   force evaluations and buys nothing: the motors, the only fast states, are integrated
 *   exactly.  Measured: energy 2e-7 and angular momentum 1e-6 relative over a minute of
 *   tumbling, |q| - 1 below 1e-15.
 * - Ground contact: spring-dampers at the eight corners of the Gazebo collision box (the
 *   four bottom ones are the skids), with Coulomb friction.  The ground only pushes; the
 *   vertical mode is damped at 1.5 x critical so that no landing rebounds.  While a corner
 *   touches, the step is split into sub-steps (the contact's rotational modes are ~30x lighter
 *   than the vertical one).  Below the sliding limit friction is a stiff viscous "stick" sized
 *   to the sub-step, so it can neither chatter nor go unstable at impact.
 * - Rest: a spring-damper alone holds a resting quad only approximately, so when the vehicle
 *   sits on all four skids, slow and unaccelerated, and the ground can carry the applied force
 *   and torque, the body is frozen: velocities exactly zero, the accelerometer exactly
 *   R^T (0, 0, -g).  It is released the moment those conditions fail (static friction).
 * - Sensors: a constant bias plus white Gaussian noise per reading on the gyro, accelerometer
 *   and barometer; a drifting barometer; the GPS's slow wander (first-order Gauss-Markov),
 *   noise, velocity noise and offset.  Wind: a constant part plus first-order Gauss-Markov
 *   gusts per NED axis, discretised exactly.
 *
 * Rules that keep the flights repeatable across versions (tests/data/physics_golden.json holds
 * the flights this model flew when it was written in Python, and the tests replay them):
 *   - doubles only; no fused multiply-add (built with -ffp-contract=off), no fast-math;
 *     expressions keep their grouping (a + b + c is (a + b) + c);
 *   - the libm functions CPython's math module calls (exp, expm1, sqrt, log, sin, cos, pow);
 *     sin and cos go through pointers the compiler cannot see through, so it never fuses a sin
 *     and a cos of the same angle into one sincos call;
 *   - the random draws are CPython's random.random and random.gauss on its Mersenne Twister,
 *     started from the states Python seeds (so a seed gives the noise it always gave); every
 *     call that draws is its own statement (C leaves the order of calls in an expression open).
 */
#include "physics.h"

#include <math.h>
#include <string.h>

/* ---- the model's constants ---- */

/* Explicit contact sub-steps are sized so (damping rate x sub-step) stays below this, and the
   friction stick takes at most as much again: together under 1, so contact velocities decay
   without changing sign from one sub-step to the next (IRIS at 1 ms: 4 sub-steps). */
#define CONTACT_RATE_STEP 0.5
/* Longest step accepted (bfsitl.physics.multirotor.MAX_STEP_S says the same: tested). */
#define MAX_STEP_S 0.02
/* When a vehicle on all four skids counts as at rest (and is then frozen exactly).  The
   motions the contact springs carry (vertical, roll, pitch) must have settled: slow *and*
   unaccelerated, or a landing could freeze at the bottom of its compression.  These limits
   bound the offset from the static sag a freeze can trap: acceleration / omega^2 (0.5 / 6900
   ~ 70 um) plus speed / slow pole of the overdamped contact (~27 /s: 40 um).  Tilt needs no
   acceleration limit: the roll and pitch modes ring at ~230 rad/s.  The motions only friction
   resists (sliding, yaw) store nothing: they merely have to be slow.  Loose enough to freeze
   under gusts and a flight controller still fiddling with the motors. */
#define REST_VERTICAL_SPEED_M_S 0.001
#define REST_VERTICAL_ACCEL_M_S2 0.5
#define REST_TILT_RATE_RAD_S 0.002
#define REST_SLIDE_SPEED_M_S 0.02
#define REST_YAW_RATE_RAD_S 0.02
/* To freeze, the centre of pressure must be this far inside the skid rectangle and the
   friction needed this far below mu N; once frozen, only the true limits release it (the
   hysteresis keeps it from flickering, and from creeping on the viscous stick in between). */
#define REST_MARGIN 0.95
/* The ISA troposphere (bfsitl.physics.atmosphere and constants say the same: tested). */
#define SEA_LEVEL_PRESSURE_PA 101325.0
#define LAPSE_OVER_T0_PER_M 2.25577e-5
#define PRESSURE_EXPONENT 5.25588
#define MIN_ALTITUDE_M -1000.0
#define MAX_ALTITUDE_M 20000.0
/* random.py: TWOPI = 2.0 * pi */
#define TWOPI (2.0 * 3.14159265358979323846)

static const double BOTTOM[4][2] = {{1.0, 1.0}, {1.0, -1.0}, {-1.0, 1.0}, {-1.0, -1.0}};

static double (*volatile bk_sin)(double) = sin;
static double (*volatile bk_cos)(double) = cos;

/* ---- random.Random: MT19937 and gauss ---- */

#define MT_N 624
#define MT_M 397

static uint32_t mt_next(bk_rng *rng)
{
    uint32_t *mt = rng->mt;
    if (rng->index >= MT_N) {
        /* Regenerate all 624 words (the recurrence of Matsumoto and Nishimura's MT19937). */
        for (int i = 0; i < MT_N; i++) {
            uint32_t y = (mt[i] & 0x80000000U) | (mt[(i + 1) % MT_N] & 0x7fffffffU);
            uint32_t next = mt[(i + MT_M) % MT_N] ^ (y >> 1);
            if (y & 1U)
                next ^= 0x9908b0dfU;
            mt[i] = next;
        }
        rng->index = 0;
    }
    uint32_t y = mt[rng->index++];
    y ^= y >> 11;
    y ^= (y << 7) & 0x9d2c5680U;
    y ^= (y << 15) & 0xefc60000U;
    y ^= y >> 18;
    return y;
}

/* random.random(): 53 bits from two words. */
static double rng_random(bk_rng *rng)
{
    uint32_t a = mt_next(rng) >> 5;
    uint32_t b = mt_next(rng) >> 6;
    return ((double)a * 67108864.0 + (double)b) * (1.0 / 9007199254740992.0);
}

/* random.gauss(mu, sigma), with its cached second deviate. */
static double rng_gauss(bk_rng *rng, double mu, double sigma)
{
    double z;
    if (rng->has_gauss_next) {
        z = rng->gauss_next;
        rng->has_gauss_next = 0;
    } else {
        double x2pi = rng_random(rng) * TWOPI;
        double u = rng_random(rng);
        double g2rad = sqrt(-2.0 * log(1.0 - u));
        z = bk_cos(x2pi) * g2rad;
        rng->gauss_next = bk_sin(x2pi) * g2rad;
        rng->has_gauss_next = 1;
    }
    return mu + z * sigma;
}

/* ---- quaternions and rotations (the conventions of bfsitl.physics.frames) ---- */

/* quat_integrate: q after turning at body rate om for dt, renormalised. */
static void quat_integrate(const double q[4], double wx, double wy, double wz, double dt,
                           double out[4])
{
    double half_dt = 0.5 * dt;
    double hx = wx * half_dt, hy = wy * half_dt, hz = wz * half_dt;
    double half2 = hx * hx + hy * hy + hz * hz;
    double c, s;
    if (half2 < 0.01) {
        c = 1.0 - half2 * (0.5 - half2 * (1.0 / 24.0));
        s = 1.0 - half2 * (1.0 / 6.0 - half2 * (1.0 / 120.0));
    } else {
        double half = sqrt(half2);
        c = bk_cos(half);
        s = bk_sin(half) / half;
    }
    double dw = c, dx = hx * s, dy = hy * s, dz = hz * s;
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double nw = w * dw - x * dx - y * dy - z * dz;
    double nx = w * dx + x * dw + y * dz - z * dy;
    double ny = w * dy - x * dz + y * dw + z * dx;
    double nz = w * dz + x * dy - y * dx + z * dw;
    double inv = 1.0 / sqrt(nw * nw + nx * nx + ny * ny + nz * nz);
    out[0] = nw * inv;
    out[1] = nx * inv;
    out[2] = ny * inv;
    out[3] = nz * inv;
}

/* R(q) (v * scale): body FRD to world NED. */
static void rotate(const double q[4], const double v[3], double scale, double out[3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double a = v[0] * scale, b = v[1] * scale, c = v[2] * scale;
    out[0] = (1.0 - 2.0 * (y * y + z * z)) * a + 2.0 * (x * y - w * z) * b
             + 2.0 * (x * z + w * y) * c;
    out[1] = 2.0 * (x * y + w * z) * a + (1.0 - 2.0 * (x * x + z * z)) * b
             + 2.0 * (y * z - w * x) * c;
    out[2] = 2.0 * (x * z - w * y) * a + 2.0 * (y * z + w * x) * b
             + (1.0 - 2.0 * (x * x + y * y)) * c;
}

/* R(q)^T v: world NED to body FRD. */
static void rotate_inverse(const double q[4], const double v[3], double out[3])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double a = v[0], b = v[1], c = v[2];
    out[0] = (1.0 - 2.0 * (y * y + z * z)) * a + 2.0 * (x * y + w * z) * b
             + 2.0 * (x * z - w * y) * c;
    out[1] = 2.0 * (x * y - w * z) * a + (1.0 - 2.0 * (x * x + z * z)) * b
             + 2.0 * (y * z + w * x) * c;
    out[2] = 2.0 * (x * z + w * y) * a + 2.0 * (y * z - w * x) * b
             + (1.0 - 2.0 * (x * x + y * y)) * c;
}

/* max(a, b) as the model was first written (Python's): the first unless the second is
   larger. */
static double py_max(double a, double b)
{
    return b > a ? b : a;
}

/* ---- ground contact and rest ---- */

static double lowest_corner(const bk_sim *s, const double q[4])
{
    double w = q[0], x = q[1], y = q[2], z = q[3];
    double r20 = 2.0 * (x * z - w * y), r21 = 2.0 * (y * z + w * x);
    double r22 = 1.0 - 2.0 * (x * x + y * y);
    double ax = s->box[0], ay = s->box[1], zb = s->box[2], zt = s->box[3];
    return fabs(ax * r20) + fabs(ay * r21) + py_max(zb * r22, zt * r22);
}

static int contact_possible(const bk_sim *s, double dt)
{
    double pz = s->p[2];
    if (pz + s->reach <= 0.0)
        return 0;
    const double *v = s->v, *w = s->w;
    double rate = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    double reach = (fabs(v[2]) + rate * s->reach) * dt + 1e-3;
    return pz + lowest_corner(s, s->q) + reach > 0.0;
}

static void corners_touching(const bk_sim *s, int *bottom_out, int *top_out)
{
    double w = s->q[0], x = s->q[1], y = s->q[2], z = s->q[3];
    double r20 = 2.0 * (x * z - w * y), r21 = 2.0 * (y * z + w * x);
    double r22 = 1.0 - 2.0 * (x * x + y * y);
    double ax = s->box[0], ay = s->box[1], zb = s->box[2], zt = s->box[3];
    double pz = s->p[2];
    int bottom = 0, top = 0;
    for (int i = 0; i < 4; i++) {
        double sx = BOTTOM[i][0], sy = BOTTOM[i][1];
        double lateral = pz + sx * ax * r20 + sy * ay * r21;
        bottom += lateral + zb * r22 > 0.0;
        top += lateral + zt * r22 > 0.0;
    }
    *bottom_out = bottom;
    *top_out = top;
}

/* Ground force (world, out[0..2]) and torque (body, out[3..5]). */
static void contact(bk_sim *s, double r00, double r01, double r02, double r10, double r11,
                    double r12, double r20, double r21, double r22, double out[6])
{
    double bx = s->box[0], by = s->box[1], zb = s->box[2], zt = s->box[3];
    double a0 = r00 * bx, a1 = r10 * bx, a2 = r20 * bx;
    double b0 = r01 * by, b1 = r11 * by, b2 = r21 * by;
    double pz = s->p[2];
    double vx = s->v[0], vy = s->v[1], vz = s->v[2];
    double p = s->w[0], q = s->w[1], r = s->w[2];
    double ox = r00 * p + r01 * q + r02 * r;
    double oy = r10 * p + r11 * q + r12 * r;
    double oz = r20 * p + r21 * q + r22 * r;
    double k = s->k, c = s->c, mu = s->mu, stick = s->stick;
    double fx = 0.0, fy = 0.0, fz = 0.0, tx = 0.0, ty = 0.0, tz = 0.0;
    int bottom = 0, top = 0;
    double lateral = fabs(a2) + fabs(b2);
    for (int face = 0; face < 2; face++) {
        int is_bottom = face == 0;
        double level = is_bottom ? zb : zt;
        double c0 = r02 * level, c1 = r12 * level, c2 = r22 * level;
        if (pz + lateral + c2 <= 0.0)
            continue;
        for (int i = 0; i < 4; i++) {
            double sx = BOTTOM[i][0], sy = BOTTOM[i][1];
            double rz = sx * a2 + sy * b2 + c2;
            double d = pz + rz;
            if (d <= 0.0)
                continue;
            if (is_bottom)
                bottom += 1;
            else
                top += 1;
            double rx = sx * a0 + sy * b0 + c0;
            double ry = sx * a1 + sy * b1 + c1;
            double cvx = vx + oy * rz - oz * ry;
            double cvy = vy + oz * rx - ox * rz;
            double cvz = vz + ox * ry - oy * rx;
            double n = k * d + c * cvz;
            if (n <= 0.0)
                continue;
            double slide = sqrt(cvx * cvx + cvy * cvy);
            double gx, gy;
            if (slide > 0.0) {
                double f = mu * n;
                double viscous = stick * slide;
                if (viscous < f)
                    f = viscous;
                f /= slide;
                gx = -f * cvx;
                gy = -f * cvy;
            } else {
                gx = 0.0;
                gy = 0.0;
            }
            double gz = -n;
            fx += gx;
            fy += gy;
            fz += gz;
            tx += ry * gz - rz * gy;
            ty += rz * gx - rx * gz;
            tz += rx * gy - ry * gx;
        }
    }
    s->touching = bottom + top;
    s->on_skids = bottom == 4 && top == 0;
    out[0] = fx;
    out[1] = fy;
    out[2] = fz;
    out[3] = r00 * tx + r10 * ty + r20 * tz;
    out[4] = r01 * tx + r11 * ty + r21 * tz;
    out[5] = r02 * tx + r12 * ty + r22 * tz;
}

static int rest_holds(const bk_sim *s, const double fb[3], const double mb[3], double margin)
{
    double w = s->q[0], x = s->q[1], y = s->q[2], z = s->q[3];
    double r20 = 2.0 * (x * z - w * y), r21 = 2.0 * (y * z + w * x);
    double r22 = 1.0 - 2.0 * (x * x + y * y);
    double mg = s->m * s->g;
    double fx = fb[0] + mg * r20, fy = fb[1] + mg * r21;
    double normal = fb[2] + mg * r22;
    if (normal <= 0.0)
        return 0;
    double bx = s->box[0], by = s->box[1], zb = s->box[2];
    double limit = margin * normal;
    if (fabs(zb * fy + mb[0]) > by * limit || fabs(zb * fx - mb[1]) > bx * limit)
        return 0;
    double corner = sqrt(bx * bx + by * by);
    return sqrt(fx * fx + fy * fy) + fabs(mb[2]) / corner <= s->mu * limit;
}

static int at_rest_now(const bk_sim *s, const double fb[3], const double mb[3])
{
    const double *v = s->v, *w = s->w, *f = s->sf_world;
    if (!s->freeze_at_rest)
        return 0;
    if (fabs(v[2]) >= REST_VERTICAL_SPEED_M_S)
        return 0;
    if (fabs(f[2] + s->g) >= REST_VERTICAL_ACCEL_M_S2)
        return 0;
    if (v[0] * v[0] + v[1] * v[1] >= REST_SLIDE_SPEED_M_S * REST_SLIDE_SPEED_M_S)
        return 0;
    double p = w[0], q = w[1], r = w[2];
    if (p * p + q * q >= REST_TILT_RATE_RAD_S * REST_TILT_RATE_RAD_S)
        return 0;
    if (fabs(r) >= REST_YAW_RATE_RAD_S)
        return 0;
    return rest_holds(s, fb, mb, REST_MARGIN);
}

/* ---- the rigid body, motors and rotors ---- */

static void set_step(bk_sim *s, double dt)
{
    s->dt = dt;
    s->alpha = -expm1(-dt / s->motor_time_constant_s);
    double n = ceil(dt * s->rate / CONTACT_RATE_STEP);
    s->n_sub = n > 1.0 ? (int32_t)n : 1;
    double h_sub = dt / (double)s->n_sub;
    s->stick = CONTACT_RATE_STEP / (4.0 * s->w_t * h_sub);
}

static void update_motors(bk_sim *s, const double commands[4], double h)
{
    double drive = s->drive, b = s->b_motor, kq = s->kq;
    double damp = s->damp, tau_max = s->tau_max;
    double alpha = s->alpha, inv_ir_h = h / s->ir, inv_h = 1.0 / h;
    double four_kq = 4.0 * kq;
    for (int i = 0; i < 4; i++) {
        double u = commands[i];
        u = u < 0.0 ? 0.0 : (u > 1.0 ? 1.0 : u);
        double d = drive * u;
        double target = d > 0.0 ? 2.0 * d / (b + sqrt(b * b + four_kq * d)) : 0.0;
        double o = s->om[i];
        double delta = (target - o) * alpha;
        double load = damp * o + kq * o * o;
        double up = (tau_max - load) * inv_ir_h;
        if (delta > up) {
            delta = up;
        } else {
            double down = (-tau_max - load) * inv_ir_h;
            if (delta < down)
                delta = down;
        }
        if (o + delta < 0.0)
            delta = -o;
        s->om[i] = o + delta;
        s->om_dot[i] = delta * inv_h;
    }
}

static void applied_wrench(const bk_sim *s, const double wind[3], double fb[3], double mb[3])
{
    double w = s->q[0], x = s->q[1], y = s->q[2], z = s->q[3];
    double xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z;
    double wx = w * x, wy = w * y, wz = w * z;
    double vx = s->v[0] - wind[0], vy = s->v[1] - wind[1], vz = s->v[2] - wind[2];
    double bx = (1.0 - 2.0 * (yy + zz)) * vx + 2.0 * (xy + wz) * vy + 2.0 * (xz - wy) * vz;
    double by = 2.0 * (xy - wz) * vx + (1.0 - 2.0 * (xx + zz)) * vy + 2.0 * (yz + wx) * vz;
    double bz = 2.0 * (xz + wy) * vx + 2.0 * (yz - wx) * vy + (1.0 - 2.0 * (xx + yy)) * vz;
    double p = s->w[0], q = s->w[1];
    double kf = s->kf, kq = s->kq, ir = s->ir;
    double thrust = 0.0, mx = 0.0, my = 0.0, mz = 0.0;
    double inflow_inv_m = s->inflow_inv_m, stall = s->stall_ratio;
    for (int i = 0; i < 4; i++) {
        double rx = s->rotors[i][0], ry = s->rotors[i][1], sgn = s->rotors[i][2];
        double o = s->om[i];
        double t;
        if (s->inflow) {
            double v_axial = -(bz + p * ry - q * rx);
            t = kf * o * (o - v_axial * inflow_inv_m);
            double cap = kf * o * o * stall;
            t = t < 0.0 ? 0.0 : (t > cap ? cap : t);
        } else {
            t = kf * o * o;
        }
        double k = s->thrust_scale[i];
        t *= k;
        thrust += t;
        mx -= ry * t;
        my += rx * t;
        mz += sgn * (k * kq * o * o + ir * s->om_dot[i]);
    }
    const double *lin = s->lin, *quad = s->quad;
    double speed = sqrt(bx * bx + by * by + bz * bz);
    fb[0] = -(lin[0] + quad[0] * speed) * bx;
    fb[1] = -(lin[1] + quad[1] * speed) * by;
    fb[2] = -(lin[2] + quad[2] * speed) * bz - thrust;
    mb[0] = mx;
    mb[1] = my;
    mb[2] = mz;
}

/* Integrates the rigid body over h; the world specific force applied goes to acc. */
static void substep(bk_sim *s, double h, const double fb[3], const double mb[3], int with_contact,
                    double acc[3])
{
    double w = s->q[0], x = s->q[1], y = s->q[2], z = s->q[3];
    double xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z;
    double qwx = w * x, qwy = w * y, qwz = w * z;
    double r00 = 1.0 - 2.0 * (yy + zz), r01 = 2.0 * (xy - qwz), r02 = 2.0 * (xz + qwy);
    double r10 = 2.0 * (xy + qwz), r11 = 1.0 - 2.0 * (xx + zz), r12 = 2.0 * (yz - qwx);
    double r20 = 2.0 * (xz - qwy), r21 = 2.0 * (yz + qwx), r22 = 1.0 - 2.0 * (xx + yy);
    double fx = fb[0], fy = fb[1], fz = fb[2];
    double mx = mb[0], my = mb[1], mz = mb[2];
    double inv_m = s->inv_m;
    double ax = (r00 * fx + r01 * fy + r02 * fz) * inv_m;
    double ay = (r10 * fx + r11 * fy + r12 * fz) * inv_m;
    double az = (r20 * fx + r21 * fy + r22 * fz) * inv_m;
    if (with_contact) {
        double cf[6];
        contact(s, r00, r01, r02, r10, r11, r12, r20, r21, r22, cf);
        ax += cf[0] * inv_m;
        ay += cf[1] * inv_m;
        az += cf[2] * inv_m;
        mx += cf[3];
        my += cf[4];
        mz += cf[5];
    }
    double px = s->p[0], py = s->p[1], pz = s->p[2];
    double vx = s->v[0], vy = s->v[1], vz = s->v[2];
    vx += ax * h;
    vy += ay * h;
    vz += (az + s->g) * h;
    s->v[0] = vx;
    s->v[1] = vy;
    s->v[2] = vz;
    s->p[0] = px + vx * h;
    s->p[1] = py + vy * h;
    s->p[2] = pz + vz * h;
    double jx = s->j[0], jy = s->j[1], jz = s->j[2];
    double hr = -s->ir * (s->om[0] * s->rotors[0][2] + s->om[1] * s->rotors[1][2]
                          + s->om[2] * s->rotors[2][2] + s->om[3] * s->rotors[3][2]);
    double p = s->w[0], q = s->w[1], r = s->w[2];
    double p0 = p, q0 = q, r0 = r;
    double lx = jx * p, ly = jy * q, lz = jz * r + hr;
    double half = 0.5 * h;
    double pm = p + half * (mx - (q * lz - r * ly)) / jx;
    double qm = q + half * (my - (r * lx - p * lz)) / jy;
    double rm = r + half * (mz - (p * ly - q * lx)) / jz;
    lx = jx * pm;
    ly = jy * qm;
    lz = jz * rm + hr;
    p += h * (mx - (qm * lz - rm * ly)) / jx;
    q += h * (my - (rm * lx - pm * lz)) / jy;
    r += h * (mz - (pm * ly - qm * lx)) / jz;
    s->w[0] = p;
    s->w[1] = q;
    s->w[2] = r;
    double q_old[4] = {w, x, y, z};
    quat_integrate(q_old, 0.5 * (p0 + p), 0.5 * (q0 + q), 0.5 * (r0 + r), h, s->q);
    acc[0] = ax;
    acc[1] = ay;
    acc[2] = az;
}

/* The gusts over dt: exact discretisation of dg = -g/tau dt + sigma sqrt(2/tau) dW. */
static void wind_advance(bk_sim *s, double dt)
{
    if (s->wind_std == 0.0)
        return;
    if (dt != s->wind_dt) {
        s->wind_dt = dt;
        s->wind_decay = exp(-dt / s->wind_tau);
        s->wind_kick = s->wind_std * sqrt(1.0 - s->wind_decay * s->wind_decay);
    }
    double a = s->wind_decay, k = s->wind_kick;
    double g0 = s->gust[0], g1 = s->gust[1], g2 = s->gust[2];
    double n0 = rng_gauss(&s->wind_rng, 0.0, 1.0);
    double x0 = a * g0 + k * n0;
    double n1 = rng_gauss(&s->wind_rng, 0.0, 1.0);
    double x1 = a * g1 + k * n1;
    double n2 = rng_gauss(&s->wind_rng, 0.0, 1.0);
    double x2 = a * g2 + k * n2;
    s->gust[0] = x0;
    s->gust[1] = x1;
    s->gust[2] = x2;
}

size_t bk_sim_size(void)
{
    return sizeof(bk_sim);
}

void bk_init(bk_sim *s)
{
    double mass = s->mass_kg;
    s->m = mass;
    s->inv_m = 1.0 / mass;
    memcpy(s->j, s->inertia_kg_m2, sizeof s->j);
    s->g = s->gravity_m_s2;
    /* Per rotor: x, y, spin sign (+1 CCW).  The hub height does not enter the model (thrust
       is along body z, and no in-plane rotor force is modelled). */
    for (int i = 0; i < 4; i++) {
        s->rotors[i][0] = s->rotor_xy_frd_m[i][0];
        s->rotors[i][1] = s->rotor_xy_frd_m[i][1];
        s->rotors[i][2] = s->rotor_spin_ccw[i] ? 1.0 : -1.0;
    }
    s->kf = s->thrust_coefficient;
    s->kq = s->torque_coefficient;
    s->ir = s->rotor_inertia_kg_m2;
    s->inflow = s->axial_inflow != 0;
    s->inflow_inv_m = 1.0 / (s->blade_radius_m * s->blade_pitch_rad);
    s->stall_ratio = s->blade_stall_rad / s->blade_pitch_rad;
    s->drive = s->motor_p_gain_nm_s_per_rad * s->motor_command_speed_rad_s;
    s->b_motor = s->motor_p_gain_nm_s_per_rad + s->rotor_damping_nm_s_per_rad;
    s->damp = s->rotor_damping_nm_s_per_rad;
    s->tau_max = s->motor_torque_limit_nm;
    memcpy(s->lin, s->drag_linear_n_s_per_m, sizeof s->lin);
    memcpy(s->quad, s->drag_quadratic_n_s2_per_m2, sizeof s->quad);
    memcpy(s->box, s->contact_box_m, sizeof s->box);
    double ax = s->box[0], ay = s->box[1], zb = s->box[2], zt = s->box[3];
    s->k = s->contact_stiffness_n_per_m;
    s->c = s->contact_damping_n_s_per_m;
    s->mu = s->friction_coefficient;
    s->reach = sqrt(ax * ax + ay * ay + pow(py_max(zb, -zt), 2.0));
    double jx = s->j[0], jy = s->j[1], jz = s->j[2];
    /* Fastest contact damping rate (1/s): vertical, roll and pitch modes on four corners. */
    double c4 = 4.0 * s->c;
    s->rate = py_max(py_max(c4 / mass, c4 * ay * ay / jx), c4 * ax * ax / jy);
    /* Largest inverse effective mass of a corner pushed sideways (1/kg): sets the stick. */
    s->w_t = 1.0 / mass + py_max(zb * zb / jy + ay * ay / jz, zb * zb / jx + ax * ax / jz);
    s->dt = -1.0;
    s->n_sub = 1;
    s->freeze_at_rest = 1;
}

void bk_start_wind(bk_sim *s)
{
    double std = s->wind_std;
    if (std != 0.0) {
        double g0 = rng_gauss(&s->wind_rng, 0.0, std);
        double g1 = rng_gauss(&s->wind_rng, 0.0, std);
        double g2 = rng_gauss(&s->wind_rng, 0.0, std);
        s->gust[0] = g0;
        s->gust[1] = g1;
        s->gust[2] = g2;
    } else {
        s->gust[0] = s->gust[1] = s->gust[2] = 0.0;
    }
    s->wind_dt = -1.0;
    s->wind_decay = 0.0;
    s->wind_kick = 0.0;
    s->wind_on = 1;
}

double bk_lowest_corner_m(const bk_sim *sim, const double q[4])
{
    return lowest_corner(sim, q);
}

double bk_time_s(const bk_sim *sim)
{
    return sim->t;
}

void bk_hold(bk_sim *sim, int enabled)
{
    sim->held = enabled != 0;
    if (sim->held) {
        sim->sf_world[0] = 0.0;
        sim->sf_world[1] = 0.0;
        sim->sf_world[2] = -sim->g;
    }
    sim->reading_valid = 0;
}

void bk_reset(bk_sim *s, const double q[4], const double p[3], const double v[3],
              const double w[3], const double om[4])
{
    memcpy(s->q, q, sizeof s->q);
    memcpy(s->p, p, sizeof s->p);
    memcpy(s->v, v, sizeof s->v);
    memcpy(s->w, w, sizeof s->w);
    memcpy(s->om, om, sizeof s->om);
    for (int i = 0; i < 4; i++)
        s->om_dot[i] = 0.0;
    int bottom, top;
    corners_touching(s, &bottom, &top);
    s->touching = bottom + top;
    s->on_skids = bottom == 4 && top == 0;
    /* not any(v) and not any(w): every component zero (-0.0 counts as zero, NaN does not) */
    s->resting = s->on_skids && !(s->v[0] != 0.0 || s->v[1] != 0.0 || s->v[2] != 0.0)
                 && !(s->w[0] != 0.0 || s->w[1] != 0.0 || s->w[2] != 0.0);
    if (s->resting || s->held) {
        s->sf_world[0] = 0.0;
        s->sf_world[1] = 0.0;
        s->sf_world[2] = -s->g;
    } else {
        static const double still[3] = {0.0, 0.0, 0.0};
        double fb[3], mb[3];
        applied_wrench(s, still, fb, mb);
        rotate(s->q, fb, s->inv_m, s->sf_world);
    }
    s->reading_valid = 0;
}

int bk_step(bk_sim *s, const double motors[4], double dt)
{
    for (int i = 0; i < 4; i++) {
        if (!isfinite(motors[i]))
            return 1;
    }
    if (!(0.0 < dt && dt <= MAX_STEP_S))
        return 2;
    if (dt != s->dt)
        set_step(s, dt);
    update_motors(s, motors, dt);
    /* Kahan-compensated clock */
    double y = dt - s->t_err;
    double t = s->t + y;
    s->t_err = (t - s->t) - y;
    s->t = t;
    s->reading_valid = 0;
    if (s->wind_on)
        wind_advance(s, dt);
    if (s->held)
        return 0;
    double wind[3] = {0.0, 0.0, 0.0};
    if (s->wind_on) {
        wind[0] = s->wind_base[0] + s->gust[0];
        wind[1] = s->wind_base[1] + s->gust[1];
        wind[2] = s->wind_base[2] + s->gust[2];
    }
    double fb[3], mb[3];
    applied_wrench(s, wind, fb, mb);
    if (s->resting) {
        if (rest_holds(s, fb, mb, 1.0))
            return 0;
        s->resting = 0;
    }
    if (contact_possible(s, dt)) {
        int n_sub = s->n_sub;
        double h = dt / (double)n_sub;
        double sx = 0.0, sy = 0.0, sz = 0.0;
        for (int i = 0; i < n_sub; i++) {
            double a[3];
            substep(s, h, fb, mb, 1, a);
            sx += a[0];
            sy += a[1];
            sz += a[2];
        }
        double inv = 1.0 / (double)n_sub;
        s->sf_world[0] = sx * inv;
        s->sf_world[1] = sy * inv;
        s->sf_world[2] = sz * inv;
        if (s->on_skids && at_rest_now(s, fb, mb)) {
            s->resting = 1;
            for (int i = 0; i < 3; i++) {
                s->v[i] = 0.0;
                s->w[i] = 0.0;
            }
            s->sf_world[0] = 0.0;
            s->sf_world[1] = 0.0;
            s->sf_world[2] = -s->g;
        }
    } else {
        s->touching = 0;
        s->on_skids = 0;
        substep(s, dt, fb, mb, 0, s->sf_world);
    }
    return 0;
}

int bk_step4(bk_sim *sim, double m1, double m2, double m3, double m4, double dt_s)
{
    double motors[4] = {m1, m2, m3, m4};
    return bk_step(sim, motors, dt_s);
}

/* ---- sensors ---- */

/* Measured gyro, specific force and pressure from true ones (in place). */
static void corrupt(bk_sim *s, double gyro[3], double f[3], double *pressure, double time_s)
{
    if (s->ideal)
        return;
    if (s->baro_drift != 0.0) {
        if (!s->has_drift_origin) {
            s->drift_origin = time_s;
            s->has_drift_origin = 1;
        }
        *pressure += s->baro_drift * (time_s - s->drift_origin);
    }
    bk_rng *rng = &s->rng;
    double gs = s->gyro_std, acs = s->accel_std, ps = s->baro_std;
    const double *gb = s->gyro_bias, *ab = s->accel_bias;
    if (gs > 0.0) {
        for (int i = 0; i < 3; i++) {
            double n = rng_gauss(rng, 0.0, gs);
            gyro[i] = gyro[i] + gb[i] + n;
        }
    } else {
        for (int i = 0; i < 3; i++)
            gyro[i] = gyro[i] + gb[i];
    }
    if (acs > 0.0) {
        for (int i = 0; i < 3; i++) {
            double n = rng_gauss(rng, 0.0, acs);
            f[i] = f[i] + ab[i] + n;
        }
    } else {
        for (int i = 0; i < 3; i++)
            f[i] = f[i] + ab[i];
    }
    double noise = ps > 0.0 ? rng_gauss(rng, 0.0, ps) : 0.0;
    *pressure = *pressure + s->baro_bias + noise;
}

/* What the GPS adds at time_s: (north m, east m, north m/s, east m/s).  The wander starts
   anywhere in its spread, as a receiver that has been on a while. */
static void gps_error(bk_sim *s, double time_s, double out[4])
{
    if (!s->gps_errors) {
        out[0] = out[1] = out[2] = out[3] = 0.0;
        return;
    }
    bk_rng *rng = &s->gps_rng;
    double std = s->gps_drift_std;
    if (std == 0.0) {
        s->gps_drift[0] = 0.0;
        s->gps_drift[1] = 0.0;
    } else if (!s->has_gps_time) {
        double d0 = rng_gauss(rng, 0.0, std);
        double d1 = rng_gauss(rng, 0.0, std);
        s->gps_drift[0] = d0;
        s->gps_drift[1] = d1;
    } else if (time_s > s->gps_time) {
        double keep = exp(-(time_s - s->gps_time) / s->gps_drift_time);
        double kick = std * sqrt(1.0 - keep * keep);
        double n0 = rng_gauss(rng, 0.0, 1.0);
        double d0 = keep * s->gps_drift[0] + kick * n0;
        double n1 = rng_gauss(rng, 0.0, 1.0);
        double d1 = keep * s->gps_drift[1] + kick * n1;
        s->gps_drift[0] = d0;
        s->gps_drift[1] = d1;
    }
    s->gps_time = time_s;
    s->has_gps_time = 1;
    double pn = s->gps_noise_std, vn = s->gps_vel_std;
    double on = s->gps_offset[0], oe = s->gps_offset[1];
    double e0 = pn != 0.0 ? rng_gauss(rng, 0.0, pn) : 0.0;
    out[0] = s->gps_drift[0] + on + e0;
    double e1 = pn != 0.0 ? rng_gauss(rng, 0.0, pn) : 0.0;
    out[1] = s->gps_drift[1] + oe + e1;
    out[2] = vn != 0.0 ? rng_gauss(rng, 0.0, vn) : 0.0;
    out[3] = vn != 0.0 ? rng_gauss(rng, 0.0, vn) : 0.0;
}

const bk_reading *bk_read_sensors(bk_sim *s)
{
    if (s->reading_valid)
        return &s->reading;
    const double *q = s->q, *p = s->p, *v = s->v;
    double altitude = s->home_alt - p[2];
    if (!(MIN_ALTITUDE_M <= altitude && altitude <= MAX_ALTITUDE_M))
        return NULL;
    double f[3];
    rotate_inverse(q, s->sf_world, f);
    double base = 1.0 - LAPSE_OVER_T0_PER_M * altitude;
    double pressure = SEA_LEVEL_PRESSURE_PA * pow(base, PRESSURE_EXPONENT);
    double gyro[3] = {s->w[0], s->w[1], s->w[2]};
    corrupt(s, gyro, f, &pressure, s->t);
    double e[4];
    gps_error(s, s->t, e);
    bk_reading *r = &s->reading;
    r->time_s = s->t;
    memcpy(r->gyro_frd_rad_s, gyro, sizeof gyro);
    memcpy(r->specific_force_frd_m_s2, f, sizeof f);
    memcpy(r->quaternion_wxyz, q, sizeof r->quaternion_wxyz);
    r->pressure_pa = pressure;
    memcpy(r->position_ned_m, p, sizeof r->position_ned_m);
    memcpy(r->velocity_ned_m_s, v, sizeof r->velocity_ned_m_s);
    /* The flat-earth projection of bfsitl.physics.frames.GeodeticProjection: the GPS's error
       moves only its own fields (the truth, position_ned_m, stays true). */
    double north = p[0] + e[0], east = p[1] + e[1];
    r->geodetic[0] = s->home_lon + east * s->deg_per_east;
    r->geodetic[1] = s->home_lat + north * s->deg_per_north;
    r->geodetic[2] = s->home_alt - p[2];
    r->velocity_enu_m_s[0] = v[1] + e[3];
    r->velocity_enu_m_s[1] = v[0] + e[2];
    r->velocity_enu_m_s[2] = -v[2];
    s->reading_valid = 1;
    s->reading_gen += 1;
    return r;
}
