/*
 * bfsitl's embedded physics: the quadrotor's rigid body, motors, rotors, drag, ground contact
 * and rest, wind and gusts, and its sensors' errors (physics.c; the model's choices are in its
 * opening comment).  This is the only implementation of the model: a change to it is made here.
 *
 * The Python face is bfsitl.physics.Simulator (physics/multirotor.py): it checks every input,
 * writes the vehicle's parameters (QuadParams) and the sensor configuration into the structure
 * below, seeds the random generators (CPython's Mersenne Twister states, so a seed gives the
 * noise and gusts it always gave) and reads the state back.  Its ctypes mirror of these
 * structures is bfsitl.kernel.layout; tests/unit/kernel/test_layout.py fails when the two
 * differ in a field's name, type, length or order.
 */
#ifndef BFSITL_KERNEL_PHYSICS_H
#define BFSITL_KERNEL_PHYSICS_H

#include <stddef.h>
#include <stdint.h>

/* What the sensors report (bfsitl.physics.SensorReading's fields, in its order). */
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
    int32_t freeze_at_rest;         /* 1: settle into the static-friction rest (tests: 0) */
    int32_t padding;
    /* ---- the vehicle (QuadParams), written by Python before bk_init ---- */
    double mass_kg;
    double inertia_kg_m2[3];
    double rotor_xy_frd_m[4][2];
    int32_t rotor_spin_ccw[4];
    double thrust_coefficient;      /* N per (rad/s)^2 */
    double torque_coefficient;      /* N m per (rad/s)^2 */
    double rotor_inertia_kg_m2;
    double motor_command_speed_rad_s;
    double motor_p_gain_nm_s_per_rad;
    double motor_torque_limit_nm;
    double rotor_damping_nm_s_per_rad;
    double motor_time_constant_s;
    double blade_radius_m;
    double blade_pitch_rad;
    double blade_stall_rad;
    int32_t axial_inflow;
    int32_t padding2;
    double drag_linear_n_s_per_m[3];
    double drag_quadratic_n_s2_per_m2[3];
    double contact_box_m[4];        /* half x, half y, bottom z, top z */
    double contact_stiffness_n_per_m;
    double contact_damping_n_s_per_m;
    double friction_coefficient;
    double gravity_m_s2;
    /* ---- the step's cache (bk_step refreshes it when dt changes) ---- */
    double dt;
    double alpha;
    double stick;
    /* ---- derived from the vehicle by bk_init ---- */
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
    int32_t inflow;
    int32_t wind_on;                /* 0: still air (no wind given) */
    /* ---- home and its flat-earth projection (bfsitl.physics.frames) ---- */
    double home_lon;
    double home_lat;
    double home_alt;
    double deg_per_east;
    double deg_per_north;
    /* ---- wind: base, gusts and their state ---- */
    double wind_base[3];
    double wind_std;
    double wind_tau;
    double gust[3];
    double wind_dt;
    double wind_decay;
    double wind_kick;
    /* ---- sensor errors: the configuration (bfsitl.physics.SensorConfig) ---- */
    int32_t ideal;
    int32_t gps_errors;
    int32_t has_gps_time;           /* the GPS error was drawn before */
    int32_t has_drift_origin;       /* the barometer's drift has started */
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
    /* ---- sensor errors: the state ---- */
    double gps_drift[2];
    double gps_time;
    double drift_origin;
    bk_rng wind_rng;
    bk_rng rng;
    bk_rng gps_rng;
    bk_reading reading;
} bk_sim;

size_t bk_sim_size(void);

/* Work out everything the step needs from the vehicle's fields (after Python wrote them). */
void bk_init(bk_sim *sim);

/* Start the wind: the base, gust_std and gust_tau fields and the wind generator are set; this
   draws the first gust from the gusts' stationary spread (so their statistics hold from the
   start) and switches the wind on. */
void bk_start_wind(bk_sim *sim);

/* The largest world "down" offset of a contact-box corner from the centre of mass at the
   attitude q (where a reset parks the vehicle, and how deep it may put it). */
double bk_lowest_corner_m(const bk_sim *sim, const double q[4]);

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

/* A reset after Python's checks: the pose, velocities and rotor speeds are given (q
   normalised), everything derived (touching corners, rest, specific force) is worked out. */
void bk_reset(bk_sim *sim, const double q[4], const double p[3], const double v[3],
              const double w[3], const double om[4]);

/* Freeze the pose (a test stand) or let it go. */
void bk_hold(bk_sim *sim, int enabled);


#endif
