/*
 * bfsitl's compiled physics: bfsitl.physics.Simulator (multirotor.py, contact.py, sensors.py,
 * wind.py and the parts of frames.py and atmosphere.py it uses) ported to C with bit-identical
 * results.  Every expression keeps the Python's operation order and parenthesisation, in
 * doubles, with the same libm functions; the random draws are CPython's Mersenne Twister and
 * random.gauss, started from the Python generators' own states.
 *
 * The Python face is bfsitl.kernel.simulator.KernelSimulator: it validates every input with
 * the reference's own code, mirrors struct bk_sim field for field in ctypes (keep the two in
 * step: it checks the size and the offsets below when it loads), and writes the constants the
 * reference computes (_cache_constants) so they are the same doubles.
 */
#ifndef BFSITL_KERNEL_PHYSICS_H
#define BFSITL_KERNEL_PHYSICS_H

#include <stddef.h>
#include <stdint.h>

/* What Simulator.read_sensors() returns, in SensorReading's order. */
typedef struct bk_reading {
    double time_s;
    double gyro_frd_rad_s[3];
    double specific_force_frd_m_s2[3];
    double quaternion_wxyz[4];
    double pressure_pa;
    double position_ned_m[3];
    double velocity_ned_m_s[3];
    double geodetic[3];             /* lon deg, lat deg, alt m MSL */
    double velocity_enu_m_s[3];
} bk_reading;

/* random.Random: MT19937's 624 words and position (getstate()[1]) and the cached second
   normal deviate of gauss() (getstate()[2]; has_gauss_next 0 for None). */
typedef struct bk_rng {
    uint32_t mt[624];
    int32_t index;
    int32_t has_gauss_next;
    double gauss_next;
} bk_rng;

typedef struct bk_sim {
    /* ---- the vehicle's state (Python reads t .. om_dot as one block of 25 doubles) ---- */
    double t;
    double p[3];
    double v[3];
    double q[4];
    double w[3];
    double om[4];
    double sf_world[3];
    double om_dot[4];
    double t_err;
    double thrust_scale[4];
    int32_t resting;
    int32_t held;
    int32_t touching;
    int32_t on_skids;
    int32_t n_sub;
    int32_t reading_valid;          /* the reading below is the one for now */
    uint64_t reading_gen;           /* +1 each time a reading is computed */
    /* ---- Simulator._set_step's cache (bk_step refreshes it when dt changes) ---- */
    double dt;
    double alpha;
    double stick;
    /* ---- Simulator._cache_constants, copied from the reference ---- */
    double m;
    double inv_m;
    double j[3];
    double g;
    double rotors[4][3];            /* x, y, spin sign */
    double kf;
    double kq;
    double ir;
    double inflow_inv_m;
    double stall_ratio;
    double drive;
    double b_motor;
    double damp;
    double tau_max;
    double lin[3];
    double quad[3];
    double box[4];                  /* half x, half y, bottom z, top z */
    double k;
    double c;
    double mu;
    double reach;
    double rate;
    double w_t;
    double motor_tau;               /* QuadParams.motor_time_constant_s */
    int32_t inflow;
    int32_t wind_on;                /* 0: no WindField (still air) */
    /* ---- GeodeticProjection and home ---- */
    double home_lon;
    double home_lat;
    double home_alt;
    double deg_per_east;
    double deg_per_north;
    /* ---- WindField ---- */
    double wind_base[3];
    double wind_std;
    double wind_tau;
    double gust[3];
    double wind_dt;
    double wind_decay;
    double wind_kick;
    /* ---- SensorModel: the configuration ---- */
    int32_t ideal;
    int32_t gps_errors;
    int32_t has_gps_time;           /* SensorModel._gps_time_s is not None */
    int32_t has_drift_origin;       /* SensorModel._drift_origin_s is not None */
    double gyro_std;
    double gyro_bias[3];
    double accel_std;
    double accel_bias[3];
    double baro_std;
    double baro_bias;
    double baro_drift;
    double gps_drift_std;
    double gps_drift_time;
    double gps_noise_std;
    double gps_vel_std;
    double gps_offset[2];
    /* ---- SensorModel: the state ---- */
    double gps_drift[2];
    double gps_time;
    double drift_origin;
    bk_rng wind_rng;
    bk_rng rng;
    bk_rng gps_rng;
    bk_reading reading;
} bk_sim;

size_t bk_sim_size(void);

/* Offsets of some fields, for the ctypes mirror's check: index 0.. until it returns
   (size_t)-1. */
size_t bk_sim_offset(int index);

/* Advance dt_s with the 4 motor commands (Betaflight order M1..M4) held.  Returns 0 when it
   stepped; nonzero when the input is invalid (a non-finite motor, dt outside (0, 0.02]) and
   then nothing changed (Python re-runs its checks to raise the same SimInputError text). */
int bk_step(bk_sim *sim, const double motors[4], double dt_s);

/* bk_step with the motors as four arguments (what the Python face calls). */
int bk_step4(bk_sim *sim, double m1, double m2, double m3, double m4, double dt_s);

/* The reading now: the same pointer and values until the next step, reset, hold or sensor
   change (the Python caches it the same way).  NULL, with nothing changed and no random draw,
   when the altitude is outside the ISA model's -1000..20000 m MSL: there the Python raises
   SimInputError (isa_pressure_pa). */
const bk_reading *bk_read_sensors(bk_sim *sim);

double bk_time_s(const bk_sim *sim);

/* Simulator.reset after its checks: the pose, velocities and rotor speeds are given (q
   normalised), everything derived (touching corners, rest, specific force) is worked out. */
void bk_reset(bk_sim *sim, const double q[4], const double p[3], const double v[3],
              const double w[3], const double om[4]);

/* Simulator.hold. */
void bk_hold(bk_sim *sim, int enabled);


#endif
