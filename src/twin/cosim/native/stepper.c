/*
 * stepper.c -- the master's hot loop in C: runs whole batches of macro steps over a static
 * exchange plan, calling the FMUs' FMI functions directly.
 *
 * It does what the Python loop in twin/cosim/stepping.py does, tick by tick, with the same
 * values:
 *   (1) outputs that became valid at this tick are committed (pending -> raw, raw + bias -> cur),
 *   (2) the inputs of the FMUs due at this tick are gathered and set (connections read the
 *       visible outputs; a delayed connection gives the value of the previous exchange; a
 *       driven input takes its column of the precomputed profile matrix, whose rows are the
 *       ticks that read it: the multiples of driven_every, twin.cosim.state.driven_ticks);
 *       after an instance's first exchange in a call, only the inputs whose bits changed
 *       (set_inputs),
 *   (3) the row of an output tick is recorded,
 *   (4) the due FMUs step from t to t + period and their outputs become pending (fetched only
 *       where something can read them: fetch_needed).
 * Scenario events are applied by Python between batches. Time is t = k * step_ns / 1e9, from
 * integers, identical to Python's t_ns / 1_000_000_000.
 *
 * A tick where nothing happens (no instance due, no output committed, no row recorded) is
 * counted, not visited: the paper replay's FMUs exchange every tenth tick of its master, and a
 * Monte Carlo's batch steps sixty instances at once.
 */
#include <math.h>
#include <string.h>

/* the structures, the enumerations and this file's entry point: generated from
 * twin/cosim/layout.py at build time, so that C and the ctypes side cannot disagree */
#include "twin_layout.h"

/* fetched: whether the pending outputs were fetched since the last commit in this call (NULL:
 * not known, a system too large for the stepper's stack). Outputs whose fetch was skipped are
 * those committed last, with the same bias (Python changes it between calls only): committing
 * them again would copy the very values, so it is left out. */
static void commit(TwinSlot *s, int64_t k, unsigned char *fetched) {
    int32_t j;
    if (*s->pending_at != k) return;
    if (!fetched || *fetched) {
        for (j = 0; j < s->n_out; j++) {
            s->out_raw[j] = s->out_pending[j];
            s->out_cur[j] = s->out_raw[j] + s->bias[j];
        }
    }
    if (fetched) *fetched = 0;
    *s->pending_at = -1;
}

/* whether input j's connection transforms what it reads (a factor or an offset) */
static int transforms(const TwinSlot *s, int32_t j) { return s->in_factor[j] != 1.0 || s->in_offset[j] != 0.0; }

/* what a connection gives its input: factor * output + offset, the output itself (bit for bit,
 * a -0.0 included) when the connection transforms nothing */
static double transformed(const TwinSlot *s, int32_t j, double v) {
    return transforms(s, j) ? v * s->in_factor[j] + s->in_offset[j] : v;
}

/* The first tick >= k that is a multiple of p (p > 0; k may be negative). */
static int64_t first_multiple(int64_t k, int64_t p) {
    int64_t r = k % p;
    if (r < 0) r += p;
    return r ? k + (p - r) : k;
}

/* Must the outputs of the step at tick k be fetched (fmi2GetReal)? They are visible from
 * k + p until the next step's commit at k + 2p. Nothing else reads the outputs of an instance
 * no connection reads (read_always 0) but a recorded row in that window, and Python between
 * two batches (events, checkpoints, the last row): the last two steps before the batch's end
 * k1 are always fetched. Skipping a fetch nobody sees changes no value: an FMU computes its
 * outputs from its states and inputs whenever they are read (fmi2_wrapper.c, fresh_outputs). */
static int fetch_needed(const TwinSlot *s, int64_t k, int64_t k1, int64_t out_every) {
    const int64_t p = s->period_ticks, visible = k + p;
    if (s->read_always || visible + p >= k1) return 1;
    return first_multiple(visible, out_every) < visible + p;
}

/* The largest number of instances whose next tick the stepper keeps on its stack (a Monte
 * Carlo's batch of twenty copies of the five-instance tester holds a hundred); a larger system
 * falls back to the remainder of each tick and visits every tick. */
#define LOCAL_SLOTS 512

/* The largest number of inputs whose source the stepper finds once per call and keeps on its
 * stack (a Monte Carlo's batch of the paper replay has under six hundred); a system with more
 * finds each input's source at every tick it is set. */
#define LOCAL_INPUTS 4096

/* Where the stepper finds what the inputs of a call's instances are given: per input, the
 * address of the output a connection (or a delayed one) reads, and whether the connection
 * transforms it (transformed: a factor or an offset). Found once per call: the instances'
 * outputs stay where they are while it runs, and at every tick the gather then reads one
 * address instead of its source's slot, its outputs and the output's place among them (two
 * fifths of the stepper's own time in the MIL endurance run). */
typedef struct {
    const double *source[LOCAL_INPUTS];
    unsigned char plain[LOCAL_INPUTS];
    int32_t first[LOCAL_SLOTS]; /* each instance's first input in the arrays above */
} Sources;

/* Fills `to` for the instances; 0 (the arrays unused) where they have too many inputs. */
static int find_sources(const TwinSlot *slots, int32_t n_slots, Sources *to) {
    int32_t i, j, n = 0;
    if (n_slots > LOCAL_SLOTS) return 0;
    for (i = 0; i < n_slots; i++) {
        const TwinSlot *s = &slots[i];
        if (s->n_in > LOCAL_INPUTS - n) return 0;
        to->first[i] = n;
        for (j = 0; j < s->n_in; j++, n++) {
            const int linked = s->in_kind[j] == IN_CONNECTION || s->in_kind[j] == IN_DELAYED;
            to->source[n] = linked ? &slots[s->in_src[j]].out_cur[s->in_idx[j]] : NULL;
            to->plain[n] = !transforms(s, j);
        }
    }
    return 1;
}

/* What input j of instance i (s) is given now: its source's visible output, transformed; read
 * at the address found for it (found: the call's Sources), or else through its source's slot. */
static inline double linked_value(const TwinSlot *slots, const TwinSlot *s, int32_t i, int32_t j, const Sources *found) {
    if (found) {
        const int32_t n = found->first[i] + j;
        const double v = *found->source[n];
        return found->plain[n] ? v : v * s->in_factor[j] + s->in_offset[j];
    }
    return transformed(s, j, slots[s->in_src[j]].out_cur[s->in_idx[j]]);
}

/* The largest number of inputs of one instance whose changes the stepper sets alone (the
 * tester's mechanics has twenty); one with more is given all its inputs at every exchange. */
#define LOCAL_SET 1024

/* The inputs an instance is given whose bits changed since they were last set (an instance's
 * scratch: its references and values, in the order of its inputs). */
typedef struct {
    unsigned int vr[LOCAL_SET];
    double val[LOCAL_SET];
} Changed;

/* Gathers the inputs of instance i (s) at this exchange into in_val and sets them (fmi2SetReal;
 * its status). At its first exchange in the call (*synced 0, or synced NULL: a system too large
 * for the stepper's stack) every input is set, so that the instance then holds what in_val
 * says; after that only those whose bits changed: an input keeps its value until it is set
 * again (FMI 2.0), so setting the same value again changes nothing the instance computes. In
 * the MIL endurance run 68 % of the values given were those last set (the thermal network's
 * temperatures, new every hundredth exchange; the load held), and fmi2SetReal's checks of
 * them took more than the mechanics' own step (`perf`). */
static int set_inputs(const TwinSlot *slots, TwinSlot *s, int32_t i, const double *drow, const Sources *found,
                      unsigned char *synced, Changed *given) {
    const int whole = !synced || !*synced || s->n_in > LOCAL_SET;
    int32_t j, n = 0;
    for (j = 0; j < s->n_in; j++) {
        double v;
        switch (s->in_kind[j]) {
            case IN_CONNECTION: v = linked_value(slots, s, i, j, found); break;
            case IN_DELAYED:
                v = s->delay_buf[j];
                s->delay_buf[j] = linked_value(slots, s, i, j, found);
                break;
            default: v = drow[s->in_src[j]]; break;
        }
        if (!whole) {
            if (memcmp(&v, &s->in_val[j], sizeof v) == 0) continue; /* bit for bit: -0.0 is not 0.0 */
            given->vr[n] = s->in_vr[j];
            given->val[n++] = v;
        }
        s->in_val[j] = v;
    }
    if (synced) *synced = 1;
    if (whole) return s->n_in ? s->set_real(s->comp, s->in_vr, (size_t)s->n_in, s->in_val) : 0;
    return n ? s->set_real(s->comp, given->vr, (size_t)n, given->val) : 0;
}

/* The row of tick k's driven values: the matrix holds the multiples of every from the first
 * at or after k0; a tick that reads none gets the row before it (nothing reads it), and the
 * index never leaves the matrix the caller sized (twin.cosim.state.driven_row). */
static const double *driven_row(const double *driven, int32_t n_driven, int64_t k, int64_t k0, int64_t every) {
    int64_t r;
    if (every <= 0) return driven;
    r = (k - first_multiple(k0, every)) / every;
    return driven + (r > 0 ? r : 0) * (int64_t)n_driven;
}

/* The first tick after k where something happens: an instance due, an output committed, a row
 * recorded, or the batch's end. */
static int64_t next_event(const TwinSlot *slots, int32_t n_slots, const int64_t *next_due, int64_t k, int64_t next_out,
                          int64_t k1) {
    int64_t next = next_out < k1 ? next_out : k1;
    int32_t i;
    for (i = 0; i < n_slots; i++) {
        const int64_t p = *slots[i].pending_at;
        if (next_due[i] < next) next = next_due[i];
        if (p > k && p < next) next = p;
    }
    return next > k ? next : k + 1;
}

int twin_run_ticks(TwinSlot *slots, int32_t n_slots, int64_t k0, int64_t k1, int64_t step_ns, int64_t out_every,
                   const double *driven, int32_t n_driven, int64_t driven_every, double *rec, int64_t rec_capacity,
                   const TwinColumn *cols, int32_t n_cols, TwinCounters *c) {
    int64_t k, next, next_out = first_multiple(k0, out_every);
    /* each instance's next tick: its period's multiples, counted instead of divided for */
    int64_t next_due[LOCAL_SLOTS];
    const int counted = n_slots <= LOCAL_SLOTS;
    Sources sources;
    const Sources *found = find_sources(slots, n_slots, &sources) ? &sources : NULL;
    unsigned char synced[LOCAL_SLOTS]; /* whether an instance's inputs were set in this call */
    unsigned char fetched[LOCAL_SLOTS]; /* commit: the first of a call copies what it finds */
    Changed given;
    int32_t i, j;
    memset(synced, 0, sizeof synced);
    memset(fetched, 1, sizeof fetched);
    for (i = 0; counted && i < n_slots; i++) next_due[i] = first_multiple(k0, slots[i].period_ticks);
    for (k = k0; k < k1; k = next) {
        const int64_t t_ns = k * step_ns;
        const double t = (double)t_ns / 1e9;
        const double *drow = driven_row(driven, n_driven, k, k0, driven_every);
        for (i = 0; i < n_slots; i++) commit(&slots[i], k, counted ? &fetched[i] : NULL);
        for (i = 0; i < n_slots; i++) {
            TwinSlot *s = &slots[i];
            int status;
            if (counted ? k != next_due[i] : k % s->period_ticks != 0) continue;
            if ((status = set_inputs(slots, s, i, drow, found, counted ? &synced[i] : NULL, &given)) > 1) {
                c->fail_slot = i, c->fail_call = CALL_SET_REAL, c->fail_tick = k, c->fail_status = status;
                return STEP_FAILED;
            }
        }
        if (k == next_out) {
            double *row;
            next_out += out_every;
            if (c->rows >= rec_capacity) return STEP_OVERFLOW; /* the caller sized the buffer: cannot happen */
            row = rec + c->rows * (int64_t)n_cols;
            for (j = 0; j < n_cols; j++) {
                const TwinSlot *s = &slots[cols[j].slot];
                row[j] = cols[j].kind == COL_OUTPUT ? s->out_cur[cols[j].idx] : s->in_val[cols[j].idx];
            }
            c->rows++;
        }
        for (i = 0; i < n_slots; i++) {
            TwinSlot *s = &slots[i];
            int status;
            if (counted ? k != next_due[i] : k % s->period_ticks != 0) continue;
            if (counted) next_due[i] += s->period_ticks;
            status = s->do_step(s->comp, t, (double)s->period_ns / 1e9, 1);
            if (status > 1) {
                c->fail_slot = i, c->fail_call = CALL_DO_STEP, c->fail_tick = k, c->fail_status = status;
                return STEP_FAILED;
            }
            if (s->n_out && fetch_needed(s, k, k1, out_every)) {
                if ((status = s->get_real(s->comp, s->out_vr, (size_t)s->n_out, s->out_pending)) > 1) {
                    c->fail_slot = i, c->fail_call = CALL_GET_REAL, c->fail_tick = k, c->fail_status = status;
                    return STEP_FAILED;
                }
                if (counted) fetched[i] = 1;
                /* an FMU that reports success with NaN/Inf must not poison the others */
                for (j = 0; j < s->n_out; j++) {
                    if (!isfinite(s->out_pending[j])) {
                        c->fail_slot = i, c->fail_call = CALL_NON_FINITE, c->fail_tick = k, c->fail_status = j;
                        return STEP_FAILED;
                    }
                }
            }
            *s->pending_at = k + s->period_ticks;
            c->fmu_steps++;
        }
        next = counted ? next_event(slots, n_slots, next_due, k, next_out, k1) : k + 1;
        c->macro_steps += next - k; /* this tick and those where nothing happens */
    }
    return STEP_OK;
}
