/*
 * fmi2_wrapper.c -- the one implementation of the FMI 2.0 co-simulation API shared by
 * every model of the twin (in the shape of the Modelica Reference-FMUs' cosimulation.c).
 *
 * Rules it enforces for every model:
 *  - a call-sequence state machine: a call in the wrong state returns fmi2Error and logs
 *    why; it never aborts or crashes the host;
 *  - value access checks: unknown value reference, causality/variability that forbids
 *    the set, NaN/Inf, values outside the declared [min, max] -> fmi2Error, nothing changed;
 *  - fmi2DoStep runs a fixed internal step (the model's INTERNAL_STEP_VR parameter) an
 *    integer number of times and keeps time as start + k*h from an integer counter, so
 *    doStep(2h) equals two doStep(h) bit for bit; at most TWIN_MAX_SUBSTEPS (model.h: one
 *    million) internal steps per doStep, a larger step is refused with fmi2Error at once;
 *  - the whole FMU state is one plain struct (ModelValues) behind a small header: get state
 *    is a copy, serialization is the same bytes. A state handed back (set, deserialize) is
 *    untrusted: its header, every parameter and input, the clock and the model's own
 *    invariants (model_check_state) are checked before it is accepted, so a crafted state is
 *    refused with fmi2Error and the instance stays unchanged and usable.
 */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the variable tables live in this translation unit only */
#define MODEL_VARS_TABLES
#include "model.h"

#define MSG_SIZE 1024
#define ALL_LIVE_STATES (ST_INSTANTIATED | ST_INIT_MODE | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define STATE_MAGIC "TWINSTA1"

/* ------------------------------------------------------------------ logging */

static void vlog(ModelInstance *comp, fmi2Status status, const char *category, const char *fmt, va_list ap) {
    char buf[MSG_SIZE];
    if (!comp || !comp->logger) return;
    vsnprintf(buf, sizeof buf, fmt, ap);
    /* the logger is printf-like: never hand it our text as a format */
    comp->logger(comp->env, comp->instance_name ? comp->instance_name : "?", status, category, "%s", buf);
}

void log_error(ModelInstance *comp, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlog(comp, fmi2Error, "logStatusError", fmt, ap);
    va_end(ap);
}

void log_info(ModelInstance *comp, const char *fmt, ...) {
    va_list ap;
    if (!comp || !comp->logging_on) return;
    va_start(ap, fmt);
    vlog(comp, fmi2OK, "logAll", fmt, ap);
    va_end(ap);
}

static const char *state_name(int s) {
    switch (s) {
        case ST_INSTANTIATED: return "instantiated";
        case ST_INIT_MODE: return "initialization mode";
        case ST_STEP_COMPLETE: return "step complete";
        case ST_STEP_FAILED: return "step failed";
        case ST_TERMINATED: return "terminated";
        case ST_ERROR: return "error";
        case ST_FATAL: return "fatal";
        default: return "unknown";
    }
}

/* Returns 1 if the call is allowed in the current state, else logs and returns 0. */
static int allowed(ModelInstance *comp, const char *fn, int states) {
    if (!comp) return 0;
    if (comp->state & states) return 1;
    log_error(comp, "%s is not allowed in state '%s'", fn, state_name(comp->state));
    return 0;
}

double model_time(const ModelInstance *comp) {
    return comp->v.start_time + (double)comp->v.steps_taken * comp->v.r[INTERNAL_STEP_VR];
}

static int outputs_finite(ModelInstance *comp);

/* outputs_stale: 0 the outputs are current; after a set of an input, or after a step of a
 * model that defers its outputs (MODEL_DEFERS_OUTPUTS), to be computed at the next read */
#define STALE_AFTER_SET 1
#define STALE_AFTER_STEP 2

/* The outputs as the current states and inputs give them: a set of an input in the state
 * 'step complete' only marks them stale, and whatever reads a value or the instance's state
 * (get, get FMU state) computes them first. model_outputs is a function of the states,
 * parameters and inputs alone, so computing it later gives the bits computing it at the set
 * gave; a step recomputes them after its last internal step, and no model_step reads an output
 * (each model's model_step reads its parameters, inputs and ModelState only). */
static int fresh_outputs(ModelInstance *comp) {
    const int after_step = comp->outputs_stale == STALE_AFTER_STEP;
    if (!comp->outputs_stale) return 1;
    comp->outputs_stale = 0;
    model_outputs(comp);
    /* a step's outputs, computed now instead of at its end: checked as fmi2DoStep checks them */
    if (after_step && !outputs_finite(comp)) {
        comp->state = ST_ERROR;
        return 0;
    }
    return 1;
}

/* Nothing pending: the outputs in the values are the current ones (after a reset, a state
 * handed back). */
static void nothing_pending(ModelInstance *comp) {
    comp->outputs_stale = 0;
    comp->init_done = 0;
#ifdef MODEL_DEFERS_OUTPUTS
    comp->deferred.pending = 0;
#endif
}

/* ------------------------------------------------------------------ start values */

static void set_start_values(ModelInstance *comp) {
    size_t k;
    memset(&comp->v, 0, sizeof comp->v);
    for (k = 0; k < N_REALS; k++) comp->v.r[k] = VARS_REAL[k].start;
#if N_INTEGERS > 0
    for (k = 0; k < N_INTEGERS; k++) comp->v.i[k] = (int)VARS_INTEGER[k].start;
#endif
#if N_BOOLEANS > 0
    for (k = 0; k < N_BOOLEANS; k++) comp->v.b[k] = VARS_BOOLEAN[k].start != 0.0;
#endif
}

/* ------------------------------------------------------------------ common API */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories, const fmi2String categories[]) {
    ModelInstance *comp = (ModelInstance *)c;
    size_t k;
    if (!allowed(comp, "fmi2SetDebugLogging", ALL_LIVE_STATES)) return fmi2Error;
    if (nCategories > 0 && !categories) {
        log_error(comp, "fmi2SetDebugLogging: categories is NULL but nCategories = %zu", nCategories);
        return fmi2Error;
    }
    for (k = 0; k < nCategories; k++) {
        if (!categories[k] || (strcmp(categories[k], "logStatusError") && strcmp(categories[k], "logAll"))) {
            log_error(comp, "fmi2SetDebugLogging: unknown log category '%s'", categories[k] ? categories[k] : "(null)");
            return fmi2Error;
        }
    }
    comp->logging_on = loggingOn ? 1 : 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID, fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible, fmi2Boolean loggingOn) {
    ModelInstance tmp, *comp;
    (void)fmuResourceLocation;
    (void)visible;
    if (!functions || !functions->logger) return NULL; /* nobody to tell why */
    memset(&tmp, 0, sizeof tmp);
    tmp.logger = functions->logger;
    tmp.env = functions->componentEnvironment;
    tmp.instance_name = (char *)(instanceName ? instanceName : "?");
    if (!instanceName || !instanceName[0]) {
        log_error(&tmp, "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        log_error(&tmp, "fmi2Instantiate: this FMU supports co-simulation only");
        return NULL;
    }
    if (!fmuGUID || strcmp(fmuGUID, MODEL_GUID) != 0) {
        log_error(&tmp, "fmi2Instantiate: GUID '%s' does not match this binary's '%s'", fmuGUID ? fmuGUID : "(null)",
                  MODEL_GUID);
        return NULL;
    }
    /* own allocation: the FMU never depends on the host's allocator for its lifetime */
    comp = (ModelInstance *)calloc(1, sizeof *comp);
    if (!comp) {
        log_error(&tmp, "fmi2Instantiate: out of memory");
        return NULL;
    }
    comp->instance_name = (char *)malloc(strlen(instanceName) + 1);
    if (!comp->instance_name) {
        free(comp);
        log_error(&tmp, "fmi2Instantiate: out of memory");
        return NULL;
    }
    strcpy(comp->instance_name, instanceName);
    comp->logger = functions->logger;
    comp->env = functions->componentEnvironment;
    comp->logging_on = loggingOn ? 1 : 0;
    set_start_values(comp);
    comp->state = ST_INSTANTIATED;
    return comp;
}

void fmi2FreeInstance(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!comp) return;
    free(comp->instance_name);
    free(comp);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    ModelInstance *comp = (ModelInstance *)c;
    (void)toleranceDefined;
    (void)tolerance;
    if (!allowed(comp, "fmi2SetupExperiment", ST_INSTANTIATED)) return fmi2Error;
    if (!isfinite(startTime) || (stopTimeDefined && (!isfinite(stopTime) || stopTime < startTime))) {
        log_error(comp, "fmi2SetupExperiment: invalid start/stop time (%g, %g)", startTime, stopTime);
        return fmi2Error;
    }
    comp->v.start_time = startTime;
    comp->v.steps_taken = 0;
    /* with debug logging on (twin run --fmi-logging), the instance's life in a few lines */
    log_info(comp, "fmi2SetupExperiment: start time %.17g s", startTime);
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2EnterInitializationMode", ST_INSTANTIATED)) return fmi2Error;
    comp->state = ST_INIT_MODE;
    comp->init_done = 0;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    char msg[MSG_SIZE] = "";
    double h;
    if (!allowed(comp, "fmi2ExitInitializationMode", ST_INIT_MODE)) return fmi2Error;
    h = comp->v.r[INTERNAL_STEP_VR];
    if (comp->init_done) { /* checked and computed for a get, from what is set now */
        comp->init_done = 0;
        comp->state = ST_STEP_COMPLETE;
        log_info(comp, "fmi2ExitInitializationMode: initialized at %.17g s, internal step %.17g s", model_time(comp), h);
        return fmi2OK;
    }
    if (!(h > 0.0) || !isfinite(h)) {
        log_error(comp, "parameter %s = %g must be a positive finite step", VARS_REAL[INTERNAL_STEP_VR].name, h);
        return fmi2Error; /* stay in initialization mode: the host may correct the parameter */
    }
    if (model_check(comp, msg, sizeof msg) != 0) {
        log_error(comp, "invalid parameters: %s", msg);
        return fmi2Error;
    }
    /* what fails here comes from the parameters and inputs (model_initialize sets the states
     * from them alone): the instance stays in initialization mode, where they can be corrected */
    if (model_initialize(comp) != fmi2OK) return fmi2Error;
    model_outputs(comp);
    if (!outputs_finite(comp)) return fmi2Error;
    comp->state = ST_STEP_COMPLETE;
    log_info(comp, "fmi2ExitInitializationMode: initialized at %.17g s, internal step %.17g s", model_time(comp), h);
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2Terminate", ST_STEP_COMPLETE | ST_STEP_FAILED | ST_ERROR)) return fmi2Error;
    comp->state = ST_TERMINATED;
    log_info(comp, "fmi2Terminate: at %.17g s after %lld internal steps", model_time(comp),
             (long long)comp->v.steps_taken);
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2Reset", ALL_LIVE_STATES)) return fmi2Error;
    set_start_values(comp);
    nothing_pending(comp);
    comp->state = ST_INSTANTIATED;
    return fmi2OK;
}

/* ------------------------------------------------------------------ get / set */



#define GET_STATES (ST_INIT_MODE | ST_STEP_COMPLETE | ST_STEP_FAILED | ST_TERMINATED | ST_ERROR)
#define SET_STATES (ST_INSTANTIATED | ST_INIT_MODE | ST_STEP_COMPLETE)

/* The typed get/set functions differ only in their base type: one row each of this table,
 * and one get_values / set_values for all three (the Reference-FMUs share theirs the same way,
 * through GET_VARIABLES(T) and SET_VARIABLES(T) macros). Integer and Boolean values are both
 * int, in FMI 2 and in ModelValues. */
typedef enum { T_REAL, T_INTEGER, T_BOOLEAN } BaseType;

typedef struct {
    const char *get_fn;
    const char *set_fn;
    size_t n_vars;
    const VarInfo *vars;
} BaseTypeInfo;

static const BaseTypeInfo BASE_TYPES[] = {
    {"fmi2GetReal", "fmi2SetReal", N_REALS, VARS_REAL},
    {"fmi2GetInteger", "fmi2SetInteger", N_INTEGERS, VARS_INTEGER},
    {"fmi2GetBoolean", "fmi2SetBoolean", N_BOOLEANS, VARS_BOOLEAN},
};

/* The instance's array of the Integer or Boolean values. */
static int *int_values(ModelInstance *comp, BaseType type) { return type == T_INTEGER ? comp->v.i : comp->v.b; }

/* What every get and set checks first: the call is allowed in this state and its arrays are
 * there. Returns 1 or logs and returns 0. */
static int check_call(ModelInstance *comp, const char *fn, int states, const fmi2ValueReference vr[], size_t nvr,
                      const void *value) {
    if (!allowed(comp, fn, states)) return 0;
    if (nvr > 0 && (!vr || !value)) {
        log_error(comp, "%s: NULL argument", fn);
        return 0;
    }
    return 1;
}

/* Is vr one of the n_vars value references of its type?  Returns 1 or logs and returns 0. */
static int known_vr(ModelInstance *comp, const char *fn, fmi2ValueReference vr, size_t n_vars) {
    if (vr < n_vars) return 1;
    log_error(comp, "%s: unknown value reference %u", fn, vr);
    return 0;
}

static int check_get_args(ModelInstance *comp, const char *fn, const fmi2ValueReference vr[], size_t nvr,
                          const void *value, size_t n_vars) {
    size_t k;
    if (!check_call(comp, fn, GET_STATES, vr, nvr, value)) return 0;
    for (k = 0; k < nvr; k++)
        if (!known_vr(comp, fn, vr[k], n_vars)) return 0;
    return 1;
}

/* May variable `info` be set now?  Returns 1 or logs and returns 0. */
static int settable(ModelInstance *comp, const char *fn, const VarInfo *info, double value) {
    if (info->variability == VAR_CONSTANT || (info->causality != CAUS_PARAMETER && info->causality != CAUS_INPUT)) {
        log_error(comp, "%s: variable '%s' cannot be set (not a parameter or input)", fn, info->name);
        return 0;
    }
    if (comp->state == ST_STEP_COMPLETE && info->causality == CAUS_PARAMETER && info->variability != VAR_TUNABLE) {
        log_error(comp, "%s: parameter '%s' is fixed after initialization", fn, info->name);
        return 0;
    }
    if (!isfinite(value)) {
        log_error(comp, "%s: value of '%s' is not finite (%g)", fn, info->name, value);
        return 0;
    }
    if (value < info->min || value > info->max) {
        log_error(comp, "%s: value %g of '%s' is outside its range [%g, %g]", fn, value, info->name, info->min, info->max);
        return 0;
    }
    return 1;
}

/* Checks the whole request first, so a rejected call changes nothing. */
static int check_set_args(ModelInstance *comp, BaseType type, const fmi2ValueReference vr[], size_t nvr, const void *value) {
    const BaseTypeInfo *t = &BASE_TYPES[type];
    const char *fn = t->set_fn;
    size_t k;
    if (!check_call(comp, fn, SET_STATES, vr, nvr, value)) return 0;
    for (k = 0; k < nvr; k++) {
        double x;
        if (!known_vr(comp, fn, vr[k], t->n_vars)) return 0;
        if (type == T_REAL) x = ((const fmi2Real *)value)[k];
        else x = (double)((const int *)value)[k];
        if (type == T_BOOLEAN && x != fmi2True && x != fmi2False) {
            log_error(comp, "%s: value %d of '%s' is not a Boolean", fn, ((const int *)value)[k], t->vars[vr[k]].name);
            return 0;
        }
        if (!settable(comp, fn, &t->vars[vr[k]], x)) return 0;
    }
    return 1;
}

/* In initialization mode the outputs are the initial unknowns: compute them from the current
 * parameters and inputs (importers such as libcosim exchange them before the first step).
 * model_initialize only sets states from parameters and inputs, so repeating it is harmless. */
static fmi2Status outputs_in_init_mode(ModelInstance *comp) {
    char msg[MSG_SIZE];
    double h = comp->v.r[INTERNAL_STEP_VR];
    if (comp->state != ST_INIT_MODE || comp->init_done) return fmi2OK; /* before any work */
    msg[0] = '\0';
    if (!(h > 0.0) || !isfinite(h) || model_check(comp, msg, sizeof msg) != 0) {
        log_error(comp, "outputs cannot be computed in initialization mode: invalid parameters%s%s", msg[0] ? ": " : "",
                  msg);
        return fmi2Error;
    }
    if (model_initialize(comp) != fmi2OK) return fmi2Error;
    model_outputs(comp);
    /* parameters in their ranges can still combine into an overflow (a spring of 1e-307 N/m) */
    if (!outputs_finite(comp)) return fmi2Error;
    comp->init_done = 1;
    return fmi2OK;
}

static fmi2Status get_values(fmi2Component c, BaseType type, const fmi2ValueReference vr[], size_t nvr, void *value) {
    ModelInstance *comp = (ModelInstance *)c;
    size_t k;
    if (!check_get_args(comp, BASE_TYPES[type].get_fn, vr, nvr, value, BASE_TYPES[type].n_vars)) return fmi2Error;
    if (!fresh_outputs(comp)) return fmi2Error;
    if (type == T_REAL) {
        /* the outputs are Reals: only they need computing in initialization mode */
        if (outputs_in_init_mode(comp) != fmi2OK) return fmi2Error;
        for (k = 0; k < nvr; k++) ((fmi2Real *)value)[k] = comp->v.r[vr[k]];
    } else {
        const int *array = int_values(comp, type);
        for (k = 0; k < nvr; k++) ((int *)value)[k] = array[vr[k]];
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    return get_values(c, T_REAL, vr, nvr, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    return get_values(c, T_INTEGER, vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    return get_values(c, T_BOOLEAN, vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    ModelInstance *comp = (ModelInstance *)c;
    /* the twin's models have no String variables: any reference is unknown */
    if (!check_get_args(comp, "fmi2GetString", vr, nvr, value, 0)) return fmi2Error;
    return fmi2OK;
}

static fmi2Status set_values(fmi2Component c, BaseType type, const fmi2ValueReference vr[], size_t nvr, const void *value) {
    ModelInstance *comp = (ModelInstance *)c;
    size_t k;
    if (!check_set_args(comp, type, vr, nvr, value)) return fmi2Error;
    if (nvr) comp->init_done = 0; /* initialization mode computes again from the new values */
    if (type == T_REAL) {
        for (k = 0; k < nvr; k++) comp->v.r[vr[k]] = ((const fmi2Real *)value)[k];
    } else {
        int *array = int_values(comp, type);
        /* Booleans were checked to be fmi2True (1) or fmi2False (0) */
        for (k = 0; k < nvr; k++) array[vr[k]] = ((const int *)value)[k];
    }
    /* outputs with direct feedthrough follow their inputs: computed when they are next read
     * (fresh_outputs), not here, since a master sets the inputs and then steps, and the step
     * computes them anyway (no model_step reads an output) */
    if (nvr && comp->state == ST_STEP_COMPLETE && !comp->outputs_stale) comp->outputs_stale = STALE_AFTER_SET;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    return set_values(c, T_REAL, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    return set_values(c, T_INTEGER, vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    return set_values(c, T_BOOLEAN, vr, nvr, value);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2SetString", SET_STATES)) return fmi2Error;
    if (nvr > 0) {
        log_error(comp, "fmi2SetString: unknown value reference %u", vr ? vr[0] : 0u);
        return fmi2Error;
    }
    (void)value;
    return fmi2OK;
}

/* ------------------------------------------------------------------ FMU state */

/* An FMU state, in memory (what fmi2FMUstate points to) and serialized alike: a header naming
 * the format (the magic carries its version) and the model, then the values. Both the pointers
 * and the bytes come back from the host untrusted and are checked before anything is read
 * beyond the header (see model.h). */
typedef struct {
    char magic[8];
    char guid[64]; /* MODEL_GUID, padded with zeros */
    uint64_t size; /* sizeof(ModelValues) */
} StateHeader;

typedef struct {
    StateHeader header;
    ModelValues v;
} SavedState;

/* ---- checks of a state handed back: the state_* helpers of model.h */

int state_fail(StateCheck *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(c->msg, c->size, fmt, ap);
    va_end(ap);
    return 1;
}

int state_bad_real(StateCheck *c, const char *what, double x, double lo, double hi) {
    if (isfinite(x) && x >= lo && x <= hi) return 0;
    return state_fail(c, "%s = %.17g is not a finite value within [%.10g, %.10g]", what, x, lo, hi);
}

int state_bad_reals(StateCheck *c, const char *what, const double *x, size_t n, double lo, double hi) {
    size_t k;
    for (k = 0; k < n; k++) {
        if (!(isfinite(x[k]) && x[k] >= lo && x[k] <= hi))
            return state_fail(c, "%s[%zu] = %.17g is not a finite value within [%.10g, %.10g]", what, k, x[k], lo, hi);
    }
    return 0;
}

int state_bad_int(StateCheck *c, const char *what, int64_t x, int64_t lo, int64_t hi) {
    if (x >= lo && x <= hi) return 0;
    return state_fail(c, "%s = %lld is not in [%lld, %lld]", what, (long long)x, (long long)lo, (long long)hi);
}

int state_bad_match(StateCheck *c, const char *what, const double *got, const double *want, size_t n) {
    double scale = 0.0;
    size_t k;
    for (k = 0; k < n; k++)
        if (fabs(want[k]) > scale || !isfinite(want[k])) scale = fabs(want[k]);
    if (!isfinite(scale)) return state_fail(c, "%s cannot be recomputed from the parameters", what);
    for (k = 0; k < n; k++) {
        if (!(fabs(got[k] - want[k]) <= 1e-9 * scale))
            return state_fail(c, "%s[%zu] = %.17g is not what the parameters give (%.17g)", what, k, got[k], want[k]);
    }
    return 0;
}

int state_bad_follower(StateCheck *c, const char *what, double x, int vr) {
    const VarInfo *info = &VARS_REAL[vr];
    double slack = 1e-9 * (info->max - info->min); /* rounding of x + a (u - x); infinite if a side is open */
    if (isfinite(x) && x >= info->min - slack && x <= info->max + slack) return 0;
    return state_fail(c, "%s = %.17g is outside the range [%g, %g] of '%s' it follows", what, x, info->min, info->max,
                      info->name);
}

const VarInfo *real_var(int vr) { return &VARS_REAL[vr]; }

/* exactly one of the states a live instance can be in */
static int bad_instance_state(StateCheck *c, int s) {
    switch (s) {
        case ST_INSTANTIATED:
        case ST_INIT_MODE:
        case ST_STEP_COMPLETE:
        case ST_STEP_FAILED:
        case ST_TERMINATED:
        case ST_ERROR: return 0;
        default: return state_fail(c, "instance state %d is not one a live instance can be in", s);
    }
}

/* What a set would have accepted: every parameter and input finite and in its declared range,
 * every Boolean 0 or 1. The outputs are the model's business (bad_model). */
static int bad_variable(StateCheck *c, const VarInfo *info, double x, int is_boolean) {
    if (info->causality != CAUS_PARAMETER && info->causality != CAUS_INPUT) return 0;
    if (is_boolean && x != 0.0 && x != 1.0) return state_fail(c, "Boolean '%s' = %.17g is neither 0 nor 1", info->name, x);
    return state_bad_real(c, info->name, x, info->min, info->max);
}

static int bad_variables(StateCheck *c, const ModelValues *v) {
    size_t k;
    for (k = 0; k < N_REALS; k++)
        if (bad_variable(c, &VARS_REAL[k], v->r[k], 0)) return 1;
#if N_INTEGERS > 0
    for (k = 0; k < N_INTEGERS; k++)
        if (bad_variable(c, &VARS_INTEGER[k], (double)v->i[k], 0)) return 1;
#endif
#if N_BOOLEANS > 0
    for (k = 0; k < N_BOOLEANS; k++)
        if (bad_variable(c, &VARS_BOOLEAN[k], (double)v->b[k], 1)) return 1;
#endif
    return 0;
}

/* The clock: a finite start, 0 <= k <= 2^53 internal steps (none before initialization is
 * over), a finite time. Checked after the variables, so the internal step is valid. */
static int bad_clock(StateCheck *c, const ModelValues *v) {
    int64_t k_max = (v->state & (ST_INSTANTIATED | ST_INIT_MODE)) ? 0 : TWIN_MAX_STEPS_TAKEN;
    return state_bad_real(c, "start time", v->start_time, -HUGE_VAL, HUGE_VAL) ||
           state_bad_int(c, "internal steps taken", v->steps_taken, 0, k_max) ||
           state_bad_real(c, "time", v->start_time + (double)v->steps_taken * v->r[INTERNAL_STEP_VR], -HUGE_VAL, HUGE_VAL);
}

/* Two output values agree: the same bits, or (a state saved by a build with other rounding)
 * both finite within 1e-9 of each other. */
static int same_output(double a, double b) {
    if (memcmp(&a, &b, sizeof a) == 0 || (isnan(a) && isnan(b))) return 1;
    return isfinite(a) && isfinite(b) && fabs(a - b) <= 1e-9 * fmax(fabs(a), fabs(b));
}

/* The output fault_inject = 3 made NaN after a step (fmi2DoStep): the first output. A state saved
 * then holds that NaN, and restoring it must give it back (the fault is the model's, on purpose). */
static int injected_nan(const ModelValues *v, size_t k) {
#ifdef VR_fault_inject
    size_t j = 0;
    if (!(v->r[VR_fault_inject] >= 2.5) || !isnan(v->r[k])) return 0;
    while (j < N_REALS && VARS_REAL[j].causality != CAUS_OUTPUT) j++;
    return j == k;
#else
    (void)v, (void)k;
    return 0;
#endif
}

/* 'Step complete' is the one state in which the model computes with its states: its parameters
 * pass model_check, its states model_check_state, and its outputs are model_outputs of them
 * (every step and every set of an input recompute them). */
static int bad_model(StateCheck *c, const ModelInstance *comp, const ModelValues *v) {
    ModelInstance scratch = *comp; /* the logger and name, for a message of model_check_state */
    size_t k;
    if (v->state != ST_STEP_COMPLETE) return 0;
    scratch.v = *v;
    nothing_pending(&scratch); /* the outputs of v's states, not of what comp has pending */
    if (model_check(&scratch, c->msg, c->size) != 0 || model_check_state(&scratch, c) != 0) return 1;
    model_outputs(&scratch);
    for (k = 0; k < N_REALS; k++) {
        if (VARS_REAL[k].causality == CAUS_OUTPUT && !same_output(v->r[k], scratch.v.r[k]) && !injected_nan(v, k))
            return state_fail(c, "output '%s' = %.17g is not what the states give (%.17g)", VARS_REAL[k].name, v->r[k],
                              scratch.v.r[k]);
    }
    return 0;
}

/* The header every state of this FMU starts with: this format, this model, this size. */
static void make_header(StateHeader *h) {
    memset(h, 0, sizeof *h);
    memcpy(h->magic, STATE_MAGIC, 8);
    strncpy(h->guid, MODEL_GUID, sizeof h->guid - 1);
    h->size = sizeof(ModelValues);
}

/* Is s one of ours: its header byte for byte the one make_header writes? Reads the header only,
 * so a (larger or smaller) state of another model is told apart safely. */
static int ours(const SavedState *s) {
    StateHeader h;
    make_header(&h);
    return memcmp(&s->header, &h, sizeof h) == 0;
}

/* Every invariant of a state handed back. Returns 1 or logs why and returns 0. */
static int state_accepted(ModelInstance *comp, const char *fn, const SavedState *s) {
    char msg[MSG_SIZE] = "";
    StateCheck c = {msg, sizeof msg};
    if (!ours(s)) {
        log_error(comp, "%s: not a state of this FMU (format %s, model %s)", fn, STATE_MAGIC, MODEL_GUID);
        return 0;
    }
    if (bad_instance_state(&c, s->v.state) || bad_variables(&c, &s->v) || bad_clock(&c, &s->v) ||
        bad_model(&c, comp, &s->v)) {
        log_error(comp, "%s: state refused, the instance is unchanged: %s", fn, msg);
        return 0;
    }
    return 1;
}

/* Where a state goes: the host's *FMUstate if it hands back one of ours, else a new allocation.
 * NULL (logged) when out of memory or when *FMUstate is something else. */
static SavedState *state_slot(ModelInstance *comp, const char *fn, fmi2FMUstate *FMUstate) {
    SavedState *s = (SavedState *)*FMUstate;
    if (s) {
        if (ours(s)) return s;
        log_error(comp, "%s: *FMUstate is not a state of this FMU (pass NULL for a new one)", fn);
        return NULL;
    }
    s = (SavedState *)malloc(sizeof *s);
    if (!s) {
        log_error(comp, "%s: out of memory", fn);
        return NULL;
    }
    *FMUstate = s;
    return s;
}

/* The state the host passes to a function: non-NULL and one of ours. Logs and returns NULL otherwise. */
static const SavedState *given_state(ModelInstance *comp, const char *fn, fmi2FMUstate FMUstate) {
    const SavedState *s = (const SavedState *)FMUstate;
    if (!s) log_error(comp, "%s: NULL state", fn);
    else if (!ours(s)) log_error(comp, "%s: not a state of this FMU (format %s, model %s)", fn, STATE_MAGIC, MODEL_GUID);
    else return s;
    return NULL;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    ModelInstance *comp = (ModelInstance *)c;
    SavedState *s;
    if (!allowed(comp, "fmi2GetFMUstate", ALL_LIVE_STATES)) return fmi2Error;
    if (!FMUstate) {
        log_error(comp, "fmi2GetFMUstate: NULL argument");
        return fmi2Error;
    }
    if (!(s = state_slot(comp, "fmi2GetFMUstate", FMUstate))) return fmi2Error;
    /* a state's outputs are what its states give (bad_model checks it) */
    if (!fresh_outputs(comp)) return fmi2Error;
    make_header(&s->header);
    memcpy(&s->v, &comp->v, sizeof s->v);
    s->v.state = comp->state;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    ModelInstance *comp = (ModelInstance *)c;
    const SavedState *s;
    if (!allowed(comp, "fmi2SetFMUstate", ALL_LIVE_STATES)) return fmi2Error;
    if (!(s = given_state(comp, "fmi2SetFMUstate", FMUstate))) return fmi2Error;
    /* checked again: the host may have changed the memory, or hand over a state of another instance */
    if (!state_accepted(comp, "fmi2SetFMUstate", s)) return fmi2Error;
    memcpy(&comp->v, &s->v, sizeof comp->v);
    comp->state = s->v.state;
    nothing_pending(comp); /* the state's outputs were checked against its states */
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2FreeFMUstate", ALL_LIVE_STATES)) return fmi2Error;
    if (FMUstate) {
        free(*FMUstate);
        *FMUstate = NULL;
    }
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    ModelInstance *comp = (ModelInstance *)c;
    if (!allowed(comp, "fmi2SerializedFMUstateSize", ALL_LIVE_STATES)) return fmi2Error;
    if (!size) {
        log_error(comp, "fmi2SerializedFMUstateSize: NULL argument");
        return fmi2Error;
    }
    if (!given_state(comp, "fmi2SerializedFMUstateSize", FMUstate)) return fmi2Error;
    *size = sizeof(SavedState);
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte serializedState[], size_t size) {
    ModelInstance *comp = (ModelInstance *)c;
    const SavedState *s;
    if (!allowed(comp, "fmi2SerializeFMUstate", ALL_LIVE_STATES)) return fmi2Error;
    if (!serializedState) {
        log_error(comp, "fmi2SerializeFMUstate: NULL argument");
        return fmi2Error;
    }
    if (!(s = given_state(comp, "fmi2SerializeFMUstate", FMUstate))) return fmi2Error;
    if (size < sizeof *s) {
        log_error(comp, "fmi2SerializeFMUstate: buffer of %zu bytes is smaller than the state (%zu)", size, sizeof *s);
        return fmi2Error;
    }
    memcpy(serializedState, s, sizeof *s);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[], size_t size, fmi2FMUstate *FMUstate) {
    ModelInstance *comp = (ModelInstance *)c;
    SavedState in, *s;
    if (!allowed(comp, "fmi2DeSerializeFMUstate", ALL_LIVE_STATES)) return fmi2Error;
    if (!serializedState || !FMUstate) {
        log_error(comp, "fmi2DeSerializeFMUstate: NULL argument");
        return fmi2Error;
    }
    if (size != sizeof in) {
        log_error(comp, "fmi2DeSerializeFMUstate: %zu bytes given, a state of this FMU has %zu", size, sizeof in);
        return fmi2Error;
    }
    memcpy(&in, serializedState, sizeof in); /* aligned, and the host's bytes are read once */
    if (!state_accepted(comp, "fmi2DeSerializeFMUstate", &in)) return fmi2Error;
    if (!(s = state_slot(comp, "fmi2DeSerializeFMUstate", FMUstate))) return fmi2Error;
    memcpy(s, &in, sizeof in);
    return fmi2OK;
}

/* A function the capability flags of modelDescription.xml say this FMU does not provide:
 * fmi2Error with the reason (a NULL instance has nobody to tell). */
static fmi2Status unsupported(fmi2Component c, const char *why) {
    if (c) log_error((ModelInstance *)c, "%s", why);
    return fmi2Error;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative: not provided (providesDirectionalDerivative=false)");
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

/* Scans the outputs for NaN/Inf after a step: a model must never hand one to the host. */
static int outputs_finite(ModelInstance *comp) {
    size_t j, k;
    for (j = 0; j < N_OUTPUT_REALS; j++) {
        k = (size_t)OUTPUT_REALS[j];
        if (!isfinite(comp->v.r[k])) {
            if (comp->state == ST_INIT_MODE)
                log_error(comp, "output '%s' is not finite in initialization mode: the parameters give %g",
                          VARS_REAL[k].name, comp->v.r[k]);
            else
                log_error(comp, "output '%s' is not finite at t = %.9g s", VARS_REAL[k].name, model_time(comp));
            return 0;
        }
    }
    return 1;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    ModelInstance *comp = (ModelInstance *)c;
    double h_int, t, tol, n_real;
    int64_t n, k;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (!allowed(comp, "fmi2DoStep", ST_STEP_COMPLETE)) return fmi2Error;
    if (!isfinite(communicationStepSize) || communicationStepSize < 0.0 || !isfinite(currentCommunicationPoint)) {
        log_error(comp, "fmi2DoStep: invalid step size %g at %g (must be finite and >= 0)", communicationStepSize,
                  currentCommunicationPoint);
        return fmi2Error;
    }
    h_int = comp->v.r[INTERNAL_STEP_VR];
    t = model_time(comp);
    /* The FMU keeps its own time exactly (a count of internal steps); the host's clock only has to
     * name the same step. A host that sums its steps in floating point (tc += h, as the FMI 2.0
     * standard's example master does) drifts from it by rounding: 2e-8 s after 10^5 steps of
     * 0.1 s. Less than half an internal step off is that; half a step or more is a step skipped or
     * repeated. */
    tol = 0.5 * h_int;
    if (!(fabs(currentCommunicationPoint - t) < tol)) {
        log_error(comp,
                  "fmi2DoStep: currentCommunicationPoint %.17g s does not match the FMU's time %.17g s (off by %.3g s, "
                  "half an internal step or more: a step skipped or repeated)",
                  currentCommunicationPoint, t, currentCommunicationPoint - t);
        return fmi2Error;
    }
    n_real = communicationStepSize / h_int;
    if (n_real > TWIN_MAX_SUBSTEPS + 0.5) {
        /* refused before any work: the host is told at once instead of waiting for hours */
        log_error(comp,
                  "fmi2DoStep: step %.12g s needs %.0f internal steps of %s = %.12g s, more than the %d one doStep "
                  "may take: split it into smaller communication steps",
                  communicationStepSize, n_real, VARS_REAL[INTERNAL_STEP_VR].name, h_int, TWIN_MAX_SUBSTEPS);
        return fmi2Error;
    }
    n = (int64_t)llround(n_real);
    if (fabs((double)n * h_int - communicationStepSize) > 1e-9 * (communicationStepSize > h_int ? communicationStepSize : h_int)) {
        log_error(comp, "fmi2DoStep: step %.12g s is not a multiple of the fixed internal step %s = %.12g s",
                  communicationStepSize, VARS_REAL[INTERNAL_STEP_VR].name, h_int);
        return fmi2Error;
    }
    if (n > TWIN_MAX_STEPS_TAKEN - comp->v.steps_taken) {
        log_error(comp, "fmi2DoStep: the internal step counter would pass 2^53 (time no longer exact)");
        return fmi2Error;
    }
#ifdef VR_fault_inject
    /* fault injection (reliability tests of masters): fail the way a broken model would */
    if (comp->v.r[VR_fault_inject] >= 0.5 && comp->v.r[VR_fault_inject] < 1.5) {
        log_error(comp, "injected fault: fmi2DoStep fails at t = %.9g s (fault_inject = 1)", t);
        comp->state = ST_ERROR;
        return fmi2Error;
    }
    if (comp->v.r[VR_fault_inject] >= 1.5 && comp->v.r[VR_fault_inject] < 2.5) {
        log_error(comp, "injected fault: fmi2DoStep discards the step at t = %.9g s (fault_inject = 2)", t);
        comp->state = ST_STEP_FAILED;
        return fmi2Discard;
    }
#endif
    for (k = 0; k < n; k++) {
        comp->last_substep = k + 1 == n;
        if (model_step(comp, h_int) != fmi2OK) {
            comp->state = ST_ERROR;
            return fmi2Error;
        }
        comp->v.steps_taken++;
    }
#ifdef MODEL_DEFERS_OUTPUTS
    /* computed (and checked) when they are read: a master that reads them after every step
     * sees what it saw, one that does not (twin's compiled stepper, for an FMU no connection
     * reads) saves their cost; an injected NaN output is made at once, below */
#ifdef VR_fault_inject
    if (!(comp->v.r[VR_fault_inject] >= 2.5))
#endif
    {
        comp->outputs_stale = STALE_AFTER_STEP;
        return fmi2OK;
    }
#endif
    model_outputs(comp);
    comp->outputs_stale = 0;
    if (!outputs_finite(comp)) {
        comp->state = ST_ERROR;
        return fmi2Error;
    }
#ifdef VR_fault_inject
    if (comp->v.r[VR_fault_inject] >= 2.5) { /* a model that reports success with a NaN output */
        size_t j;
        for (j = 0; j < N_REALS; j++) {
            if (VARS_REAL[j].causality == CAUS_OUTPUT) {
                comp->v.r[j] = NAN;
                break;
            }
        }
    }
#endif
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    return unsupported(c, "fmi2CancelStep: fmi2DoStep always completes synchronously, there is nothing to cancel");
}

/* The status queries: fmi2DoStep always completes, so nothing is ever pending. Only the last
 * successful time and "terminated" have an answer: status_query returns fmi2OK when s is the
 * kind the caller can answer (it then fills in the value), fmi2Discard for any other kind and
 * fmi2Error for a query in the wrong state or without a place for the value. */
#define NO_ANSWER (-1)

static fmi2Status status_query(fmi2Component c, const char *fn, const void *value, fmi2StatusKind s, int answered) {
    if (!allowed((ModelInstance *)c, fn, GET_STATES) || !value) return fmi2Error;
    return (int)s == answered ? fmi2OK : fmi2Discard;
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    fmi2Status status = status_query(c, "fmi2GetStatus", value, s, NO_ANSWER);
    if (status == fmi2Discard) log_error((ModelInstance *)c, "fmi2GetStatus: no asynchronous step is ever pending");
    return status;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    fmi2Status status = status_query(c, "fmi2GetRealStatus", value, s, fmi2LastSuccessfulTime);
    if (status == fmi2OK) *value = model_time((ModelInstance *)c);
    return status;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    return status_query(c, "fmi2GetIntegerStatus", value, s, NO_ANSWER);
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    fmi2Status status = status_query(c, "fmi2GetBooleanStatus", value, s, fmi2Terminated);
    if (status == fmi2OK) *value = fmi2False;
    return status;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    return status_query(c, "fmi2GetStringStatus", value, s, NO_ANSWER);
}
