/*
 * bfsitl's compiled lockstep loop: the steps of bfsitl.sim.lockstep.LockstepBridge between two
 * of the mission's decisions, without returning to Python.
 *
 * One step is what the bridge's step in Python does, in the same order and with the same
 * bytes: read the sensors, encode the fdm packet for the firmware's generation (mirroring
 * bfsitl.protocol.fdm_encoding.FdmEncoder), append the RC packet the caller packed, hand the
 * datagram to the FC through the shared region (bfsitl.link.shm_exchange: the request word is
 * 0 while the datagram is written, then the new sequence number, then one FUTEX_WAKE unless
 * the FC says it is polling), wait for the reply (polling the reply word for spin_s, saying
 * so, then FUTEX_WAIT), check that it answers
 * this packet's timestamp, put the motors in Betaflight's order and integrate the physics.
 *
 * Anything unusual goes back to Python with a status, where the bridge's code handles it
 * the one way it always does: a reply that has not come within wait_s (resends, the check
 * that the SITL still runs), a reading or motors that are not finite (the errors that name
 * the field), a reply for another timestamp.
 */
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <string.h>
#include <time.h>

#include "physics.h"

#ifdef __linux__
#include <linux/futex.h>
#include <poll.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

enum {
    BK_LOCKSTEP_DONE = 0,        /* stepped up to the time or the count asked */
    BK_LOCKSTEP_PENDING = 1,     /* the datagram went out, no reply within wait_s */
    BK_LOCKSTEP_OUT_OF_STEP = 2, /* the reply answers another timestamp */
    BK_LOCKSTEP_BAD_READING = 3, /* a reading Python must name (not finite, pressure <= 0) */
    BK_LOCKSTEP_BAD_MOTORS = 4,  /* the reply's motors are not finite, or the step refused */
    BK_LOCKSTEP_TOO_BIG = 5,     /* the datagram does not fit the region */
    BK_LOCKSTEP_NO_FUTEX = 6,    /* not built for Linux */
};

/* The header's words (bfsitl.link.shm_exchange). */
#define REQUEST_WORD 2
#define REPLY_WORD 3
#define BYTES_WORD 4
#define FDM_BYTES 144
#define REPLY_BYTES 24
#define MAX_DATAGRAM 256

typedef struct bk_lockstep {
    /* the region, as ShmExchange found it */
    uint8_t *region;
    uint32_t datagram_offset;
    uint32_t reply_offset;
    uint32_t seq;               /* the last request number sent (ShmExchange._seq) */
    int32_t status;
    /* the encoder (FdmEncoder's fields for this profile) */
    double gyro_k[3];
    double acc_k[3];
    double rz_minus_90[4];
    double home_lon_deg;
    double home_lat_deg;
    double sea_level_pa;
    double lapse_per_m;
    double exponent;
    double lost_lon_deg;
    double lost_lat_deg;
    int32_t gazebo_quaternion;
    int32_t altitude_z_up;
    int32_t has_gps;
    int32_t send_gps_lost;
    int32_t mirrored;
    int32_t motor_slot[4];      /* profile.motor_slot_of_betaflight_motor */
    /* the stepping */
    double step_s;
    double spin_s;              /* poll the reply word this long before sleeping */
    double wait_s;              /* give up (PENDING) after this long without a reply */
    /* the RC link's frames (RcFrameClock of sim/rc_frames.py, the same arithmetic) */
    double rc_period_s;         /* a frame every rc_period_s of simulated time; 0: every datagram */
    double rc_next_s;           /* the next frame is due in the first datagram stamped at or after */
    double rc_sent_s;           /* the stamp of the last datagram that carried one */
    int64_t rc_frames;          /* frames sent so far (a resend not counted again) */
    /* what happened (totals over the object's life, and the last step's) */
    double exchange_s;
    double physics_s;
    int64_t steps;
    double motors[4];           /* the last reply's, Betaflight order */
    double stamp_s;             /* the timestamp of the last datagram sent */
    double began_s;             /* the wall time the last step began */
    double answered_s;          /* the timestamp an out-of-step reply answered */
    /* the region's words of each side's waiting (layout 3; 0: an older layout, where every
       hand-over wakes the other side) */
    int32_t fc_sleeping_word;   /* 1 while the FC sleeps on the request word */
    int32_t sim_polling_word;   /* 1 while this loop polls the reply word */
    int64_t wakes;              /* FUTEX_WAKE calls made (a total, as steps) */
} bk_lockstep;

size_t bk_lockstep_size(void) { return sizeof(bk_lockstep); }

static double wall_s(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)now.tv_sec + (double)now.tv_nsec * 1e-9;
}

static void put_doubles(uint8_t *out, const double *values, int count)
{
    memcpy(out, values, (size_t)count * sizeof(double)); /* x86-64: little-endian as "<d" */
}

/* FdmEncoder.pack: 18 doubles (timestamp, gyro, accel, quaternion, velocity, position,
   pressure); 0 when a value is one Python must report. */
static int encode(const bk_lockstep *ls, const bk_reading *r, double stamp_s, uint8_t *out)
{
    double v[18];
    const double *g = r->gyro_frd_rad_s, *a = r->specific_force_frd_m_s2;
    v[0] = stamp_s;
    v[1] = g[0] * ls->gyro_k[0];
    v[2] = g[1] * ls->gyro_k[1];
    v[3] = g[2] * ls->gyro_k[2];
    v[4] = a[0] * ls->acc_k[0];
    v[5] = a[1] * ls->acc_k[1];
    v[6] = a[2] * ls->acc_k[2];
    const double *q = r->quaternion_wxyz;
    if (ls->gazebo_quaternion) {
        /* gazebo_quaternion(): (pw, px, -py, -pz) of Rz(-90) * (w, x, -y, -z) */
        const double *m = ls->rz_minus_90;
        double bw = q[0], bx = q[1], by = -q[2], bz = -q[3];
        v[7] = m[0] * bw - m[1] * bx - m[2] * by - m[3] * bz;
        v[8] = m[0] * bx + m[1] * bw + m[2] * bz - m[3] * by;
        v[9] = -(m[0] * by - m[1] * bz + m[2] * bw + m[3] * bx);
        v[10] = -(m[0] * bz + m[1] * by - m[2] * bx + m[3] * bw);
    } else {
        v[7] = q[0];
        v[8] = q[1];
        v[9] = q[2];
        v[10] = q[3];
    }
    double altitude_m;
    if (ls->altitude_z_up) {
        /* altitude_for_pressure_m: Python's max(pressure, 1.0) keeps the first unless the
           second is larger. */
        double pressure = r->pressure_pa;
        double ratio = (1.0 > pressure ? 1.0 : pressure) / ls->sea_level_pa;
        altitude_m = (1.0 - pow(ratio, 1.0 / ls->exponent)) / ls->lapse_per_m;
    } else {
        altitude_m = r->geodetic[2];
    }
    const double *vel;
    if (!ls->has_gps) {
        v[14] = r->position_ned_m[0];
        v[15] = r->position_ned_m[1];
        v[16] = ls->altitude_z_up ? altitude_m : r->position_ned_m[2];
        vel = r->velocity_ned_m_s;
    } else {
        double lon = r->geodetic[0], lat = r->geodetic[1];
        if (ls->send_gps_lost) {
            lon = ls->lost_lon_deg;
            lat = ls->lost_lat_deg;
        } else if (ls->mirrored) {
            lon = 2.0 * ls->home_lon_deg - lon;
            lat = 2.0 * ls->home_lat_deg - lat;
        }
        v[14] = lon;
        v[15] = lat;
        v[16] = altitude_m;
        vel = r->velocity_enu_m_s;
    }
    v[11] = vel[0];
    v[12] = vel[1];
    v[13] = vel[2];
    v[17] = r->pressure_pa;
    for (int i = 0; i < 18; i++) {
        if (!isfinite(v[i]))
            return 0;
    }
    if (!(v[17] > 0.0))
        return 0;
    put_doubles(out, v, 18);
    return 1;
}

#ifdef __linux__
static void futex_wake(volatile uint32_t *word)
{
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAKE, 1, NULL, NULL, 0);
}

static void futex_wait(volatile uint32_t *word, uint32_t expected, double timeout_s)
{
    struct timespec timeout;
    timeout.tv_sec = (time_t)timeout_s;
    timeout.tv_nsec = (long)((timeout_s - (double)timeout.tv_sec) * 1e9);
    syscall(SYS_futex, (uint32_t *)word, FUTEX_WAIT, expected, &timeout, NULL, 0);
}

static void send_datagram(bk_lockstep *ls, const uint8_t *datagram, uint32_t length)
{
    volatile uint32_t *words = (volatile uint32_t *)ls->region;
    __atomic_store_n(&words[REQUEST_WORD], 0u, __ATOMIC_RELEASE);
    memcpy(ls->region + ls->datagram_offset, datagram, length);
    __atomic_store_n(&words[BYTES_WORD], length, __ATOMIC_RELEASE);
    ls->seq += 1u;
    if (ls->seq == 0u)
        ls->seq = 1u; /* 0 means "being written": never a request */
    /* Sequentially consistent, against the FC's store of its sleeping word and its load of
       this one: either it sees the new request and does not sleep, or this sees it asleep. */
    __atomic_store_n(&words[REQUEST_WORD], ls->seq, __ATOMIC_SEQ_CST);
    if (ls->fc_sleeping_word == 0 ||
        __atomic_load_n(&words[ls->fc_sleeping_word], __ATOMIC_SEQ_CST) != 0) {
        futex_wake(&words[REQUEST_WORD]);
        ls->wakes += 1;
    }
}

/* 1 when the reply to request ls->seq is in the region within wait_s.  polling (NULL: the
   layout has no such word) is the word that says this loop polls: 1 for the whole run, so
   the FC makes no wake-up a poller would not need, and 0 only while it sleeps. */
static int wait_reply(bk_lockstep *ls, volatile uint32_t *polling)
{
    volatile uint32_t *words = (volatile uint32_t *)ls->region;
    uint32_t want = ls->seq;
    double start = wall_s();
    double spin_until = start + ls->spin_s;
    for (;;) {
        if (__atomic_load_n(&words[REPLY_WORD], __ATOMIC_ACQUIRE) == want)
            return 1;
        if (wall_s() >= spin_until)
            break;
    }
    /* About to sleep: sequentially consistent against the FC's store of its reply and its
       load of this word, so that one of the two sees the other (no lost wake-up). */
    if (polling != NULL)
        __atomic_store_n(polling, 0u, __ATOMIC_SEQ_CST);
    int answered = 0;
    for (;;) {
        uint32_t now = __atomic_load_n(&words[REPLY_WORD], __ATOMIC_SEQ_CST);
        if (now == want) {
            answered = 1;
            break;
        }
        double left = start + ls->wait_s - wall_s();
        if (left <= 0.0)
            break;
        futex_wait(&words[REPLY_WORD], now, left);
    }
    if (polling != NULL && answered)
        __atomic_store_n(polling, 1u, __ATOMIC_RELAXED);
    return answered;
}

/* 1 when fd has something to read (or was closed): an MSP reply has come. */
static int readable(int fd)
{
    struct pollfd watched = {.fd = fd, .events = POLLIN, .revents = 0};
    return poll(&watched, 1, 0) > 0;
}
#endif

/* Frame times are compared with this slack: the simulated time is a sum of steps. */
#define RC_FRAME_SLACK_S 1e-9
/* A stamp this fraction of a period below a grid point counts as at it. */
#define RC_FRAME_GRID_EPS 1e-6

/* Whether the datagram stamped `stamp` carries the RC trailer: every one without a period;
   else the first at or after each frame time (and a repeat of that stamp), which moves the
   next frame time to the grid point after it. */
static int rc_frame_due(bk_lockstep *ls, double stamp)
{
    double period = ls->rc_period_s;
    if (period <= 0.0 || stamp == ls->rc_sent_s)
        return 1;
    if (stamp < ls->rc_next_s - RC_FRAME_SLACK_S)
        return 0;
    ls->rc_sent_s = stamp;
    ls->rc_frames += 1;
    ls->rc_next_s = (floor(stamp / period + RC_FRAME_GRID_EPS) + 1.0) * period;
    return 1;
}

/* Step while the simulated time plus slack_s is below until_s (the bridge's tests: half a
   step of slack for run_until, none for an MSP wait) and fewer than max_steps have been
   taken, and, when watch_fd >= 0, until that descriptor is readable after a step (the FC
   wrote an MSP reply during its passes); the number taken.  rc (rc_len bytes) rides in the
   datagrams rc_frame_due picks.  ls->status says why it stopped. */
#ifdef __linux__
static long run_steps(bk_sim *sim, bk_lockstep *ls, const uint8_t *rc, uint32_t rc_len,
                      double until_s, double slack_s, long max_steps, int watch_fd,
                      volatile uint32_t *polling)
{
    long taken = 0;
    uint8_t datagram[MAX_DATAGRAM];
    uint32_t length = FDM_BYTES + rc_len;
    if (length > MAX_DATAGRAM || ls->datagram_offset + length > ls->reply_offset) {
        ls->status = BK_LOCKSTEP_TOO_BIG;
        return 0;
    }
    if (rc_len)
        memcpy(datagram + FDM_BYTES, rc, rc_len);
    while (taken < max_steps && bk_time_s(sim) + slack_s < until_s) {
        double began = wall_s();
        ls->began_s = began;
        double stamp = bk_time_s(sim);
        const bk_reading *reading = bk_read_sensors(sim); /* NULL: outside the ISA model */
        if (reading == NULL || !encode(ls, reading, stamp, datagram)) {
            ls->status = BK_LOCKSTEP_BAD_READING;
            return taken;
        }
        send_datagram(ls, datagram, rc_len && rc_frame_due(ls, stamp) ? length : FDM_BYTES);
        ls->stamp_s = stamp;
        if (!wait_reply(ls, polling)) {
            ls->status = BK_LOCKSTEP_PENDING;
            return taken;
        }
        const uint8_t *reply = ls->region + ls->reply_offset;
        float speeds[4];
        double answered;
        memcpy(speeds, reply, sizeof speeds);
        memcpy(&answered, reply + 16, sizeof answered);
        if (answered != stamp) {
            ls->answered_s = answered;
            ls->status = BK_LOCKSTEP_OUT_OF_STEP;
            return taken;
        }
        for (int i = 0; i < 4; i++)
            ls->motors[i] = (double)speeds[ls->motor_slot[i]];
        double stepped = wall_s();
        if (bk_step(sim, ls->motors, ls->step_s) != 0) {
            ls->status = BK_LOCKSTEP_BAD_MOTORS;
            return taken;
        }
        double done = wall_s();
        ls->exchange_s += stepped - began;
        ls->physics_s += done - stepped;
        ls->steps += 1;
        taken += 1;
        if (watch_fd >= 0 && readable(watch_fd))
            break;
    }
    return taken;
}
#endif

/* run_steps, saying in the region (layout 3) that this loop polls while it runs and spins. */
long bk_lockstep_run(bk_sim *sim, bk_lockstep *ls, const uint8_t *rc, uint32_t rc_len,
                     double until_s, double slack_s, long max_steps, int watch_fd)
{
    ls->status = BK_LOCKSTEP_DONE;
#ifndef __linux__
    (void)sim; (void)rc; (void)rc_len; (void)until_s; (void)slack_s; (void)max_steps;
    (void)watch_fd;
    ls->status = BK_LOCKSTEP_NO_FUTEX;
    return 0;
#else
    volatile uint32_t *polling = NULL;
    if (ls->sim_polling_word != 0 && ls->spin_s > 0.0) {
        polling = (volatile uint32_t *)ls->region + ls->sim_polling_word;
        __atomic_store_n(polling, 1u, __ATOMIC_RELAXED);
    }
    long taken = run_steps(sim, ls, rc, rc_len, until_s, slack_s, max_steps, watch_fd, polling);
    /* Python's own waits come next: the FC wakes them. */
    if (polling != NULL)
        __atomic_store_n(polling, 0u, __ATOMIC_SEQ_CST);
    return taken;
#endif
}
