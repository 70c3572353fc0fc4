/*
 * model.h -- the contract between the one FMI 2.0 co-simulation wrapper (fmi2_wrapper.c)
 * and a model (fmus/<Model>/model.c).
 *
 * The wrapper owns the FMI API: instance life cycle, the call-sequence state machine,
 * value access with range/NaN checks, the fixed-step loop of fmi2DoStep and FMU state
 * (get/set/serialize). A model only supplies its variables (generated from its
 * modelDescription.xml into model_vars.h) and its equations:
 *
 *   model_check       parameters consistent? (called at exitInitializationMode)
 *   model_initialize  precompute from parameters, set initial states and outputs
 *   model_step        advance the states by exactly one internal step
 *   model_outputs     recompute outputs from states and inputs (after set of inputs)
 *   model_check_state are the model's own states (ModelState) consistent with its parameters?
 *                     (called on every FMU state handed back by the host, see below)
 *
 * All model data lives in ModelInstance.v (plain doubles/ints, no pointers), so an FMU
 * state is a byte copy of that struct and serialization is trivially portable between
 * instances of the same build.
 *
 * An FMU state handed back by the host (fmi2SetFMUstate, fmi2DeSerializeFMUstate) is untrusted:
 * the bytes may come from a file. The wrapper accepts it only after re-checking every invariant a
 * live instance keeps (header, instance state, clock, every parameter and input against its
 * declared range, and in the state 'step complete' model_check, model_check_state and the outputs
 * against model_outputs), so a crafted state is refused with fmi2Error and never reaches the
 * equations. In the other states ModelState is never read (initialization recomputes it; a
 * terminated or failed instance only hands out its last values), so only the wrapper's checks
 * apply there.
 */
#ifndef TWIN_MODEL_H
#define TWIN_MODEL_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "fmi2Functions.h"

/* Causality and variability as declared in modelDescription.xml. */
typedef enum { CAUS_PARAMETER, CAUS_CALCULATED_PARAMETER, CAUS_INPUT, CAUS_OUTPUT, CAUS_LOCAL, CAUS_INDEPENDENT } Causality;
typedef enum { VAR_CONSTANT, VAR_FIXED, VAR_TUNABLE, VAR_DISCRETE, VAR_CONTINUOUS } Variability;

typedef struct {
    const char *name;
    Causality causality;
    Variability variability;
    double start; /* for integers/booleans the start value as double */
    double min;   /* -HUGE_VAL if none declared */
    double max;   /* +HUGE_VAL if none declared */
} VarInfo;

/* Generated per model from its modelDescription.xml: N_REALS, N_INTEGERS, N_BOOLEANS,
 * VR_<name> (index into the value arrays), the VarInfo tables and MODEL_GUID. It also
 * includes the model's config.h, which declares ModelState (the model's own states and
 * precomputed data) and INTERNAL_STEP_VR (the parameter holding the fixed solver step). */
#include "model_vars.h"

/* At most this many internal steps per fmi2DoStep: a larger communication step returns fmi2Error
 * at once (the instance is unchanged) instead of blocking the host for minutes. The twin's
 * scenarios take at most a few hundred internal steps per doStep (the thermal network's 10 s
 * over a 1 s step, the others 0.5 s over 10 ms); a million internal steps take well under a
 * second for every model. */
#define TWIN_MAX_SUBSTEPS 1000000
/* The internal step counter never passes 2^53: time = start + k h stays exact in k, and the
 * counter can never overflow. */
#define TWIN_MAX_STEPS_TAKEN 9007199254740992LL

typedef enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT_MODE = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_FATAL = 1 << 6
} InstanceState;

/* Everything that makes up an FMU state: copied byte for byte by get/set/serialize. */
typedef struct {
    double r[N_REALS > 0 ? N_REALS : 1];
    int i[N_INTEGERS > 0 ? N_INTEGERS : 1];
    int b[N_BOOLEANS > 0 ? N_BOOLEANS : 1];
    double start_time;
    int64_t steps_taken; /* internal steps since start: time = start_time + steps_taken * h */
    int state;           /* InstanceState at the time of the snapshot */
    ModelState m;
} ModelValues;

/* The last arguments (their bits) and result of an expensive libm call whose arguments seldom
 * change (a temperature's factor, held for the thermal network's 10 s, asked for every 0.1 s):
 * the same bits in give the same bits out, so a hit returns exactly what the call would. A
 * model whose config.h defines MODEL_MEMOS keeps that many in its instance, outside its FMU
 * state (a memo is right for any state). */
typedef struct {
    uint64_t key[2];
    double value;
    int valid;
} Memo;

/* Whether m holds the result for the arguments (x, y); memo_keep stores it. */
static inline int memo_hit(const Memo *m, double x, double y) {
    uint64_t kx, ky;
    memcpy(&kx, &x, sizeof kx);
    memcpy(&ky, &y, sizeof ky);
    return m->valid && m->key[0] == kx && m->key[1] == ky;
}

static inline double memo_keep(Memo *m, double x, double y, double value) {
    memcpy(&m->key[0], &x, sizeof x);
    memcpy(&m->key[1], &y, sizeof y);
    m->value = value;
    m->valid = 1;
    return value;
}

/* f(x) for a libm function f of one argument: from m when it holds x, else computed and kept */
static inline double memo_call(Memo *m, double (*f)(double), double x) {
    return memo_hit(m, x, 0.0) ? m->value : memo_keep(m, x, 0.0, f(x));
}

typedef struct ModelInstance {
    char *instance_name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    int state; /* InstanceState */
    /* set by fmi2DoStep before each model_step: 1 for the last internal step of the
     * communication step, whose values the host reads; a model may skip computing what only
     * an earlier step's outputs would show (not part of the FMU state) */
    int last_substep;
    /* 1 after a set in the state 'step complete' until the outputs are computed again: the
     * wrapper defers model_outputs to the next read of a value or of the state (not part of the
     * FMU state; see fmi2_wrapper.c, fresh_outputs) */
    int outputs_stale;
    /* 1 while the states and outputs initialization mode computed for a get (the wrapper's
     * outputs_in_init_mode) are those of the current parameters and inputs: nothing was set
     * since, so neither the next get nor fmi2ExitInitializationMode computes them again */
    int init_done;
#ifdef MODEL_MEMOS
    Memo memo[MODEL_MEMOS];
#endif
#ifdef MODEL_DEFERS_OUTPUTS
    /* a model whose config.h defines MODEL_DEFERS_OUTPUTS leaves the end of a step's outputs to
     * model_outputs, from what it kept here (not part of the FMU state: a state is taken with
     * the outputs computed, and a state handed back has none pending) */
    ModelDeferred deferred;
#endif
    ModelValues v;
} ModelInstance;

/* Logging helpers (implemented in the wrapper); errors are always logged. */
void log_error(ModelInstance *comp, const char *fmt, ...);
void log_info(ModelInstance *comp, const char *fmt, ...);

/* Current time of the instance from the integer step counter (never summed floats). */
double model_time(const ModelInstance *comp);

/* Why a state was refused: model_check_state writes one line into it (through the helpers
 * below) and returns -1. */
typedef struct {
    char *msg;
    size_t size;
} StateCheck;

/* Helpers for model_check_state. Each returns 0 if the value passes, else writes why (naming
 * `what`) into c and returns 1, so checks chain with ||. */
int state_fail(StateCheck *c, const char *fmt, ...);
/* x is not NaN and lies in [lo, hi] (pass -HUGE_VAL/HUGE_VAL for an open side; both infinite
 * still refuses +-Inf) */
int state_bad_real(StateCheck *c, const char *what, double x, double lo, double hi);
/* the same for each of x[0..n-1] */
int state_bad_reals(StateCheck *c, const char *what, const double *x, size_t n, double lo, double hi);
/* an integer count or index lies in [lo, hi] */
int state_bad_int(StateCheck *c, const char *what, int64_t x, int64_t lo, int64_t hi);
/* got[0..n-1] agree with want[0..n-1] (recomputed from the parameters) to 1e-9 of the largest
 * |want|: precomputed data must be what the parameters give (not bit for bit, so a state saved
 * by a build with other rounding is still accepted) */
int state_bad_match(StateCheck *c, const char *what, const double *got, const double *want, size_t n);
/* a state that follows Real variable vr (a sensor's lag of its input, a reference taken from
 * it) is finite and within vr's declared range, widened by 1e-9 of the range for rounding */
int state_bad_follower(StateCheck *c, const char *what, double x, int vr);
/* the declared range and name of Real variable vr (the tables live in the wrapper only) */
const VarInfo *real_var(int vr);

/* ---- to be implemented by every model ---- */

/* Return 0 if the parameters are consistent, else write a one-line reason into msg. */
int model_check(ModelInstance *comp, char *msg, size_t msg_size);
/* Precompute, set the initial states and outputs. Return fmi2OK or fmi2Error (logged). */
fmi2Status model_initialize(ModelInstance *comp);
/* Advance the states by one internal step of length h. Return fmi2OK or fmi2Error. */
fmi2Status model_step(ModelInstance *comp, double h);
/* Recompute the outputs from the states and the current inputs. */
void model_outputs(ModelInstance *comp);
/* Is ModelState consistent with the parameters, as after initialization and any number of
 * steps?  comp holds a candidate FMU state in 'step complete' whose parameters and inputs already
 * passed their ranges and model_check. Return 0, or -1 with the reason in c (state_* helpers):
 * counts and indices in range, values finite and within their physical bounds, precomputed data
 * equal to what the parameters give. Must not change anything but local copies. */
int model_check_state(const ModelInstance *comp, StateCheck *c);

#endif
