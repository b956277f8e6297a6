/* A blackbox log's frames decoded in one pass, by the plans bfsitl.blackbox.frame_plan makes.
 *
 * The Python face is bfsitl.blackbox.compiled_frames, which says what goes in and out.  This
 * reads what FramePlan reads, predicts as it predicts (and as orangebox 0.4.0 does, quirks
 * included: a slow or GPS frame's "previous" is the last *main* frame's field at its index),
 * and walks the frames as orangebox's Parser.frames does.  It gives up (BB_BAIL) at anything
 * a clean log does not hold: an unknown frame byte or event, a frame not followed by a frame
 * byte, a log that ends without LOG_END, an iteration that goes back, a number past 64 bits.
 * The caller then decodes the log in Python, which keeps orangebox's handling of damage; so
 * this is only ever a faster way to the same numbers (tests/unit/blackbox/test_compiled_frames.py
 * decodes every log at hand both ways).
 */
#include <stdint.h>
#include <string.h>

enum { BB_OK = 0, BB_FULL = 1, BB_BAIL = 2 };

/* What a step reads (frame_plan's _SIGNED_VB ... _NULL). */
enum { R_SIGNED_VB, R_UNSIGNED_VB, R_NEG_14BIT, R_TAG8_8SVB, R_TAG2_3S32, R_TAG8_4S16, R_NULL };

/* How a run is predicted (compiled_frames' HOW_* numbers). */
enum {
    P_NONE, P_PREVIOUS, P_STRAIGHT_LINE, P_AVERAGE_2, P_CONSTANT, P_INCREMENT,
    P_MOTOR_0, P_HOME_0, P_HOME_1, P_LAST_MAIN_TIME
};

/* Frame types, in the order of the plan table. */
enum { T_INTRA, T_INTER, T_SLOW, T_GPS, T_HOME, T_COUNT };

/* The settings array. */
enum {
    S_I_INTERVAL, S_P_NUM, S_P_DENOM, S_ITER_INDEX, S_MOTOR_0_INDEX, S_COUNT
};

/* The counts array the call fills. */
enum { C_MAIN, C_SLOW, C_GPS, C_EVENTS, C_WHERE, C_COUNT };

#define MAX_FIELDS 256
/* orangebox's Parser.frames: an iteration that does not advance, past this sum, is dropped. */
#define MAX_ITER_JUMP 5000
/* Below this a sum of two is exact in a double: orangebox's average is int((a + b) / 2). */
#define EXACT_IN_DOUBLE (INT64_C(1) << 53)

typedef struct {
    int present;
    int64_t fields;
    int64_t step_count;
    const int64_t *steps; /* (what, count) */
    int64_t run_count;
    const int64_t *runs; /* (how, first, end, constant) */
} plan_t;

typedef struct {
    const uint8_t *data;
    int64_t length;
    int64_t at;
    int failed; /* read past the end, or a number orangebox could not give */
} cursor_t;

typedef struct {
    int64_t past0[MAX_FIELDS], past1[MAX_FIELDS];
    int has0, has1; /* whether a main frame is there (orangebox's empty frame: not) */
    int64_t main_fields;
    int64_t home[MAX_FIELDS];
    int64_t home_fields; /* 0 before the first home frame */
    int64_t last_iter; /* orangebox's Context.last_iter */
    int64_t i_interval, p_num, p_denom, motor_0_index;
} state_t;

static inline int64_t next_byte(cursor_t *c)
{
    if (c->at >= c->length) {
        c->failed = 1;
        return 0;
    }
    return c->data[c->at++];
}

/* An unsigned varint: 7 bits a byte, low first, at most 5 bytes; 5 that never end read 0. */
static int64_t unsigned_vb(cursor_t *c)
{
    int64_t result = 0;
    for (int shift = 0; shift < 35; shift += 7) {
        int64_t byte = next_byte(c);
        result |= (byte & 0x7F) << shift;
        if (byte < 0x80)
            return result;
    }
    return 0;
}

static inline int64_t zig_zag(int64_t value)
{
    uint64_t low = (uint64_t)value & 0xFFFFFFFFu;
    return (int64_t)(low >> 1) ^ -(int64_t)(low & 1);
}

static inline int64_t sign_extend(int64_t value, int bits)
{
    return (value & (INT64_C(1) << (bits - 1))) ? value - (INT64_C(1) << bits) : value;
}

static int64_t tag8_4s16(cursor_t *c, int64_t *out)
{
    int64_t selector = next_byte(c);
    int nibble = 0;
    int64_t buffer = 0;
    for (int i = 0; i < 4; i++) {
        switch (selector & 3) {
        case 0:
            out[i] = 0;
            break;
        case 1:
            if (nibble) {
                out[i] = sign_extend(buffer & 0x0F, 4);
            } else {
                buffer = next_byte(c);
                out[i] = sign_extend(buffer >> 4, 4);
            }
            nibble = !nibble;
            break;
        case 2:
            if (nibble) {
                int64_t high = (buffer & 0x0F) << 4;
                buffer = next_byte(c);
                out[i] = sign_extend(high | (buffer >> 4), 8);
            } else {
                out[i] = sign_extend(next_byte(c), 8);
            }
            break;
        default: {
            int64_t first = next_byte(c);
            int64_t second = next_byte(c);
            if (nibble) {
                out[i] = sign_extend(((buffer & 0x0F) << 12) | (first << 4) | (second >> 4), 16);
                buffer = second;
            } else {
                out[i] = sign_extend((first << 8) | second, 16);
            }
        }
        }
        selector >>= 2;
    }
    return 4;
}

static int64_t tag2_3s32(cursor_t *c, int64_t *out)
{
    int64_t lead = next_byte(c);
    switch (lead >> 6) {
    case 0:
        out[0] = sign_extend((lead >> 4) & 3, 2);
        out[1] = sign_extend((lead >> 2) & 3, 2);
        out[2] = sign_extend(lead & 3, 2);
        break;
    case 1: {
        int64_t second = next_byte(c);
        out[0] = sign_extend(lead & 0x0F, 4);
        out[1] = sign_extend(second >> 4, 4);
        out[2] = sign_extend(second & 0x0F, 4);
        break;
    }
    case 2: {
        int64_t second = next_byte(c);
        int64_t third = next_byte(c);
        out[0] = sign_extend(lead & 0x3F, 6);
        out[1] = sign_extend(second & 0x3F, 6);
        out[2] = sign_extend(third & 0x3F, 6);
        break;
    }
    default:
        for (int i = 0; i < 3; i++) {
            switch (lead & 3) {
            case 0:
                out[i] = sign_extend(next_byte(c), 8);
                break;
            case 1: {
                int64_t b0 = next_byte(c), b1 = next_byte(c);
                out[i] = sign_extend(b0 | (b1 << 8), 16);
                break;
            }
            case 2: {
                int64_t b0 = next_byte(c), b1 = next_byte(c), b2 = next_byte(c);
                out[i] = sign_extend(b0 | (b1 << 8) | (b2 << 16), 24);
                break;
            }
            default: { /* 32 bits as they are: orangebox does not sign-extend these */
                int64_t b0 = next_byte(c), b1 = next_byte(c), b2 = next_byte(c);
                int64_t b3 = next_byte(c);
                out[i] = b0 | (b1 << 8) | (b2 << 16) | (b3 << 24);
            }
            }
            lead >>= 2;
        }
    }
    return 3;
}

/* The raw values of a frame's fields into raw[0..plan->fields). */
static void read_raw(const plan_t *plan, cursor_t *c, int64_t *raw)
{
    int64_t n = 0;
    for (int64_t s = 0; s < plan->step_count && !c->failed; s++) {
        int64_t what = plan->steps[2 * s], count = plan->steps[2 * s + 1];
        switch (what) {
        case R_SIGNED_VB:
            for (int64_t i = 0; i < count; i++)
                raw[n++] = zig_zag(unsigned_vb(c));
            break;
        case R_TAG8_8SVB: {
            int64_t header = next_byte(c);
            for (int64_t i = 0; i < count; i++) {
                raw[n++] = (header & 1) ? zig_zag(unsigned_vb(c)) : 0;
                header >>= 1;
            }
            break;
        }
        case R_UNSIGNED_VB:
            raw[n++] = unsigned_vb(c);
            break;
        case R_TAG8_4S16:
            n += tag8_4s16(c, raw + n);
            break;
        case R_TAG2_3S32:
            n += tag2_3s32(c, raw + n);
            break;
        case R_NEG_14BIT: {
            int64_t word = unsigned_vb(c);
            if (word & 0x2000) {
                if (word > INT64_C(0xFFFFFFFF)) {
                    c->failed = 1; /* orangebox's 32-bit packing raises on it */
                    return;
                }
                word = (int64_t)(int32_t)(uint32_t)(word | 0xFFFFC000u);
            }
            raw[n++] = -word;
            break;
        }
        default: /* R_NULL: nothing written */
            raw[n++] = 0;
        }
    }
}

/* One frame's raw fields by ``steps`` (step_count (what, count) pairs) from data[at..length),
 * into raw; returns where the frame ends, or -1 where the data ends inside it or orangebox
 * could not give the number.  What the tests compare with FramePlan's reader. */
int64_t bb_read_raw(const uint8_t *data, int64_t length, int64_t at, const int64_t *steps,
                    int64_t step_count, int64_t *raw)
{
    plan_t plan = { 1, 0, step_count, steps, 0, 0 };
    cursor_t c = { data, length, at, 0 };
    read_raw(&plan, &c, raw);
    return c.failed ? -1 : c.at;
}

/* orangebox's Context.count_skipped_frames: iterations not logged after the last one. */
static int skipped_after(const state_t *st, int64_t *skipped)
{
    if (st->last_iter == -1) {
        *skipped = 0;
        return 1;
    }
    if (st->last_iter < 0)
        return 0; /* Python's modulo of a negative number is not C's */
    int64_t index = st->last_iter + 1;
    for (int64_t tries = 0; tries <= st->i_interval + st->p_denom; tries++, index++) {
        if ((index % st->i_interval + st->p_num - 1) % st->p_denom < st->p_num) {
            *skipped = index - st->last_iter - 1;
            return 1;
        }
    }
    return 0;
}

/* The past main frame's field at ``index`` (orangebox: 0 without one; the one before that:
 * the last's value without one). */
static inline int past_values(const state_t *st, int64_t index, int64_t *last, int64_t *before)
{
    if ((st->has0 || st->has1) && index >= st->main_fields)
        return 0; /* past the main fields: orangebox would read a slow or GPS value there */
    *last = st->has0 ? st->past0[index] : 0;
    *before = st->has1 ? st->past1[index] : *last;
    return 1;
}

#define ADD(a, b, to)                           \
    do {                                        \
        if (__builtin_add_overflow(a, b, to))   \
            return 0;                           \
    } while (0)

/* raw -> out by the plan's runs; 0 where orangebox's numbers would differ or it would fail. */
static int predict(const plan_t *plan, const state_t *st, const int64_t *raw, int64_t *out)
{
    for (int64_t r = 0; r < plan->run_count; r++) {
        const int64_t *run = plan->runs + 4 * r;
        int64_t how = run[0], first = run[1], end = run[2], constant = run[3];
        for (int64_t i = first; i < end; i++) {
            int64_t last, before, sum, twice;
            switch (how) {
            case P_NONE:
                out[i] = raw[i];
                break;
            case P_PREVIOUS:
                if (!past_values(st, i, &last, &before))
                    return 0;
                ADD(raw[i], last, &out[i]);
                break;
            case P_STRAIGHT_LINE:
                if (!past_values(st, i, &last, &before))
                    return 0;
                if (__builtin_mul_overflow(last, 2, &twice) ||
                    __builtin_sub_overflow(twice, before, &sum))
                    return 0;
                ADD(raw[i], sum, &out[i]);
                break;
            case P_AVERAGE_2:
                if (!past_values(st, i, &last, &before))
                    return 0;
                ADD(last, before, &sum);
                if (sum >= EXACT_IN_DOUBLE || sum <= -EXACT_IN_DOUBLE)
                    return 0;
                ADD(raw[i], sum / 2, &out[i]); /* C truncates toward zero, as int() does */
                break;
            case P_CONSTANT:
                ADD(raw[i], constant, &out[i]);
                break;
            case P_INCREMENT: {
                int64_t skipped;
                if (!past_values(st, i, &last, &before) || !skipped_after(st, &skipped))
                    return 0;
                ADD(last, skipped, &sum);
                ADD(sum, 1, &out[i]);
                break;
            }
            case P_MOTOR_0: /* the current frame's motor[0], when decoded before this field */
                ADD(raw[i], (st->motor_0_index >= 0 && st->motor_0_index < i)
                                ? out[st->motor_0_index] : 0, &out[i]);
                break;
            case P_HOME_0:
            case P_HOME_1: {
                int64_t which = how == P_HOME_0 ? 0 : 1;
                if (st->home_fields == 0) {
                    out[i] = 0; /* orangebox: no home yet reads 0, whatever was written */
                } else if (which >= st->home_fields) {
                    return 0;
                } else {
                    ADD(raw[i], st->home[which], &out[i]);
                }
                break;
            }
            case P_LAST_MAIN_TIME: /* the main frame before the last's field, 0 without one */
                if (st->has1 && i >= st->main_fields)
                    return 0;
                ADD(raw[i], st->has1 ? st->past1[i] : 0, &out[i]);
                break;
            default:
                return 0;
            }
        }
    }
    return 1;
}

/* Skip an event's payload as bfsitl.blackbox.events.read_event reads it; 0 for a code the
 * firmware does not write or a payload cut short.  LOG_END sets *ended. */
static int skip_event(cursor_t *c, int64_t code, int *ended)
{
    static const char log_end_text[] = "End of log"; /* and its NUL */
    switch (code) {
    case 0:  /* SYNC_BEEP */
    case 15: /* DISARM */
        unsigned_vb(c);
        break;
    case 14: /* LOGGING_RESUME */
    case 30: /* FLIGHTMODE */
        unsigned_vb(c);
        unsigned_vb(c);
        break;
    case 13: { /* INFLIGHT_ADJUSTMENT */
        int64_t function = next_byte(c);
        if (function & 0x80) {
            for (int i = 0; i < 4; i++)
                next_byte(c);
        } else {
            unsigned_vb(c);
        }
        break;
    }
    case 255:
        for (size_t i = 0; i < sizeof log_end_text; i++)
            if (next_byte(c) != (uint8_t)log_end_text[i])
                return 0;
        *ended = 1;
        break;
    default:
        return 0;
    }
    return !c->failed;
}

/* The same five bytes make a varint end in read_event as here; one that never ends within 5
 * bytes is an error there (a payload cut short), so the log is left to Python. */
static int varints_end(const uint8_t *data, int64_t from, int64_t to)
{
    int run = 0;
    for (int64_t i = from; i < to; i++) {
        run = data[i] >= 0x80 ? run + 1 : 0;
        if (run >= 5)
            return 0;
    }
    return 1;
}

static inline int is_frame_byte(uint8_t b)
{
    return b == 'I' || b == 'P' || b == 'S' || b == 'G' || b == 'H' || b == 'E';
}

static int64_t frame_type(uint8_t b)
{
    switch (b) {
    case 'I': return T_INTRA;
    case 'P': return T_INTER;
    case 'S': return T_SLOW;
    case 'G': return T_GPS;
    case 'H': return T_HOME;
    default: return -1;
    }
}

/* The plan table: table[t] is where frame type t's description starts (-1: the log has no
 * such frame): fields, steps, runs, then the steps' pairs and the runs' quads. */
static int load_plans(const int64_t *table, plan_t *plans)
{
    for (int t = 0; t < T_COUNT; t++) {
        int64_t at = table[t];
        plans[t].present = at >= 0;
        if (at < 0)
            continue;
        plans[t].fields = table[at];
        plans[t].step_count = table[at + 1];
        plans[t].run_count = table[at + 2];
        plans[t].steps = table + at + 3;
        plans[t].runs = table + at + 3 + 2 * plans[t].step_count;
        if (plans[t].fields < 0 || plans[t].fields > MAX_FIELDS)
            return 0;
    }
    return 1;
}

/* Decode data[start..length).  Main frames' values go to main (main_capacity rows of the
 * intra frame's field count), with the slow and GPS row in force for each (-1: none yet);
 * slow and GPS frames to their own rows; events as (position after the code, code, main
 * frames before).  An output given as NULL is only counted: a first pass with all of them
 * NULL says how much room the second needs.  counts gets how many of each and where
 * decoding stopped.  Returns BB_OK at LOG_END, BB_FULL when a capacity ran out, BB_BAIL
 * otherwise. */
int bb_decode_frames(const uint8_t *data, int64_t length, int64_t start,
                     const int64_t *plan_table, const int64_t *settings,
                     int64_t *main, int64_t *main_slow, int64_t *main_gps, int64_t main_capacity,
                     int64_t *slow, int64_t slow_capacity,
                     int64_t *gps, int64_t gps_capacity,
                     int64_t *events, int64_t event_capacity,
                     int64_t *counts)
{
    state_t st; /* each call its own: ctypes lets other threads run meanwhile */
    plan_t plans[T_COUNT];
    int64_t raw[MAX_FIELDS], values[MAX_FIELDS];
    cursor_t c = { data, length, start, 0 };
    int64_t n_main = 0, n_slow = 0, n_gps = 0, n_events = 0;
    int64_t current_slow = -1, current_gps = -1, local_last_iter = 0;
    int status = BB_BAIL;

    memset(counts, 0, C_COUNT * sizeof *counts);
    if (!load_plans(plan_table, plans) || !plans[T_INTRA].present)
        return BB_BAIL;
    memset(&st, 0, sizeof st);
    st.main_fields = plans[T_INTRA].fields;
    st.last_iter = -1;
    st.i_interval = settings[S_I_INTERVAL];
    st.p_num = settings[S_P_NUM];
    st.p_denom = settings[S_P_DENOM];
    st.motor_0_index = settings[S_MOTOR_0_INDEX];
    int64_t iter_index = settings[S_ITER_INDEX];
    if (st.i_interval < 1 || st.p_num < 1 || st.p_denom < 1)
        return BB_BAIL;
    if (plans[T_INTER].present && plans[T_INTER].fields != st.main_fields)
        return BB_BAIL;

    while (1) {
        if (c.at >= length)
            break; /* no LOG_END: a log cut short */
        uint8_t byte = data[c.at++];
        if (byte == 'E') {
            if (c.at >= length)
                break;
            int64_t code = data[c.at++];
            int64_t payload = c.at;
            int ended = 0;
            if (!skip_event(&c, code, &ended) || !varints_end(data, payload, c.at))
                break;
            if (events != NULL) {
                if (n_events >= event_capacity) {
                    status = BB_FULL;
                    break;
                }
                events[3 * n_events] = payload;
                events[3 * n_events + 1] = code;
                events[3 * n_events + 2] = n_main;
            }
            n_events++;
            if (ended) {
                status = BB_OK;
                break;
            }
            continue;
        }
        int64_t t = frame_type(byte);
        if (t < 0 || !plans[t].present)
            break;
        const plan_t *plan = &plans[t];
        read_raw(plan, &c, raw);
        if (c.failed || !predict(plan, &st, raw, values))
            break;
        if (t == T_SLOW || t == T_GPS) {
            int64_t *rows = t == T_SLOW ? slow : gps;
            int64_t *count = t == T_SLOW ? &n_slow : &n_gps;
            if (rows != NULL) {
                if (*count >= (t == T_SLOW ? slow_capacity : gps_capacity)) {
                    status = BB_FULL;
                    break;
                }
                memcpy(rows + *count * plan->fields, values, plan->fields * sizeof *values);
            }
            if (t == T_SLOW)
                current_slow = (*count)++;
            else
                current_gps = (*count)++;
            continue;
        }
        if (t == T_HOME) {
            memcpy(st.home, values, plan->fields * sizeof *values);
            st.home_fields = plan->fields;
            continue;
        }
        /* A main frame: orangebox checks its iteration, then that a frame byte follows. */
        int64_t iteration = iter_index >= 0 && iter_index < plan->fields ? values[iter_index] : 0;
        st.last_iter = iteration;
        if (local_last_iter >= iteration && MAX_ITER_JUMP < iteration + local_last_iter)
            break;
        local_last_iter = iteration;
        if (c.at >= length || !is_frame_byte(data[c.at]))
            break;
        if (main != NULL) {
            if (n_main >= main_capacity) {
                status = BB_FULL;
                break;
            }
            memcpy(main + n_main * st.main_fields, values, st.main_fields * sizeof *values);
            main_slow[n_main] = current_slow;
            main_gps[n_main] = current_gps;
        }
        n_main++;
        if (t == T_INTRA) {
            memcpy(st.past0, values, st.main_fields * sizeof *values);
            memcpy(st.past1, values, st.main_fields * sizeof *values);
            st.has0 = st.has1 = 1;
        } else {
            memcpy(st.past1, st.past0, st.main_fields * sizeof *values);
            memcpy(st.past0, values, st.main_fields * sizeof *values);
            st.has1 = st.has0;
            st.has0 = 1;
        }
    }
    counts[C_MAIN] = n_main;
    counts[C_SLOW] = n_slow;
    counts[C_GPS] = n_gps;
    counts[C_EVENTS] = n_events;
    counts[C_WHERE] = c.at;
    return status;
}
