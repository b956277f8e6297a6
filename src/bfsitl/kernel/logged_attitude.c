/* A blackbox log's attitude: tilt, roll and pitch in degrees from each frame's logged
 * quaternion x, y, z (scaled by 0x7FFF, w >= 0 implied).
 *
 * The Python face is bfsitl.analysis.track, which made these one frame at a time with math's
 * functions (a fifth of a log's track).  The same operations in the same order, with the
 * libm functions CPython's math calls and its own rule for atan2 at y = 0, so the same
 * doubles (tests/unit/analysis/test_track.py compares both on every log at hand).
 */
#include <math.h>
#include <stdint.h>

/* CPython's math.degrees multiplies by this. */
static const double RAD_TO_DEG = 180.0 / 3.14159265358979323846;

static inline double at_least(double low, double value) { return value > low ? value : low; }
static inline double at_most(double high, double value) { return value < high ? value : high; }

/* CPython's math.atan2 for finite arguments: y = 0 answered without libm. */
static double python_atan2(double y, double x)
{
    if (y == 0.0)
        return copysign(1.0, x) == 1.0 ? copysign(0.0, y) : copysign(3.14159265358979323846, y);
    return atan2(y, x);
}

void bb_logged_attitudes(const int64_t *xyz, int64_t count, double *out)
{
    for (int64_t i = 0; i < count; i++) {
        double x = (double)xyz[3 * i] / 32767.0;
        double y = (double)xyz[3 * i + 1] / 32767.0;
        double z = (double)xyz[3 * i + 2] / 32767.0;
        double w = sqrt(at_least(0.0, 1.0 - x * x - y * y - z * z));
        double level = 1.0 - 2.0 * (x * x + y * y); /* cos(tilt): body z against the vertical */
        out[3 * i] = acos(at_least(-1.0, at_most(1.0, level))) * RAD_TO_DEG;
        out[3 * i + 1] = python_atan2(2.0 * (w * x + y * z), level) * RAD_TO_DEG;
        out[3 * i + 2] = asin(at_least(-1.0, at_most(1.0, 2.0 * (w * y - z * x)))) * RAD_TO_DEG;
    }
}
