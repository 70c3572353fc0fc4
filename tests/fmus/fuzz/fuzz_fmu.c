/*
 * fuzz_fmu.c -- a deterministic fuzzer for one of the twin's FMUs, meant to be built with
 * AddressSanitizer and UBSan together with the model's sources and the FMI wrapper
 * (tests/fmus/sanitized.py does the build; tests/fmus/test_fuzz_sanitized.py runs it in CI,
 * tools/fuzz_fmus.py for long runs).
 *
 *   usage: fuzz_fmu SEED ITERATIONS [-v] [-r]
 *          -v logs every FMU message, -r skips the crafted cases (random fuzzing only)
 *
 * First every crafted case (crafted_cases: one violation of each invariant the wrapper and the
 * model check) must be refused with a message naming it.
 * Each iteration does one thing a hostile or careless host could do, chosen at random:
 *   blob       hand back a serialized state mutated by one of the MUTATIONS below
 *   set        set Reals, Integers, Booleans, Strings: NaN, Inf, huge, out of range, unknown
 *              value references, NULL arrays, in any instance state
 *   get        get values and status, with unknown references and NULL arrays
 *   step       fmi2DoStep with NaN, Inf, negative, huge, non-multiple steps, wrong times
 *   lifecycle  the calls of the FMI life cycle in any order, with odd arguments
 *   state api  get/set/free/size/serialize FMU states with NULL and foreign states
 *   run        a legitimate stretch: valid inputs and steps, snapshots into the blob pool
 *
 * What must hold (anything else ends the run with "FUZZ FAILURE" and exit code 3; the
 * sanitizers end it on any memory error or undefined behaviour):
 *   - a call that is refused returns fmi2Error and leaves the instance's bytes unchanged;
 *   - a state handed back with a wrong header, size or length is always refused;
 *   - a deserialized state is accepted by fmi2SetFMUstate too, and becomes the instance's;
 *   - every state a legitimate sequence of calls reaches is accepted when handed back (no
 *     false refusal), and restoring it continues bit for bit like the original;
 *   - a set that succeeds stored finite values within their ranges;
 *   - fmi2DoStep refuses more than TWIN_MAX_SUBSTEPS internal steps without stepping.
 * At the end it prints one line of counts (accepted and refused mutated states per kind, ...)
 * and frees everything, so LeakSanitizer sees no leak.
 */
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MODEL_VARS_TABLES /* this file's own copy of the variable tables (they are static) */
#include "model.h"

/* the layout of a serialized state (the wrapper's SavedState); checked against its size below */
typedef struct {
    char magic[8];
    char guid[64];
    uint64_t header_size;
    ModelValues v;
} Blob;

#define N_SLOTS 3
#define POOL 24
#define MAX_NVR 5

/* ------------------------------------------------------------------ random numbers */

static uint64_t fz_x;

static uint64_t fz_next(void) { /* splitmix64 */
    uint64_t z = (fz_x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static size_t below(size_t n) { return (size_t)(fz_next() % n); }
static double unit(void) { return (double)(fz_next() >> 11) * (1.0 / 9007199254740992.0); }
static int chance(double p) { return unit() < p; }

static double special_real(void) {
    static const double v[] = {NAN,  -NAN,    INFINITY, -INFINITY, 0.0,   -0.0, DBL_MAX, -DBL_MAX, DBL_MIN, 4.9e-324,
                               1e300, -1e300, 1e-300,   1.0,       -1.0,  0.5,  2.0,     8.0,      1e10,    -1e10,
                               9007199254740993.0};
    return v[below(sizeof v / sizeof v[0])];
}

static int special_int(void) {
    static const int v[] = {0, 1, -1, 2, 3, 4, 7, 8, 9, 100, -1000, 1 << 16, INT_MAX, INT_MIN, INT_MIN + 1, 32, 64};
    return v[below(sizeof v / sizeof v[0])];
}

static int64_t special_int64(void) {
    static const int64_t v[] = {0, 1, -1, 2, INT64_MAX, INT64_MIN, 9007199254740992LL, 9007199254740993LL,
                                2147483648LL, -2147483649LL, 1000000LL};
    return v[below(sizeof v / sizeof v[0])];
}

/* ------------------------------------------------------------------ reporting */

static uint64_t seed_given;
static long iteration;
static char last_message[2048];
static unsigned long n_messages;
static int verbose, random_only;

static void fail(const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "FUZZ FAILURE (model %s, seed %llu, iteration %ld): ", MODEL_GUID, (unsigned long long)seed_given,
            iteration);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\n  last FMU message: %s\n", last_message);
    exit(3);
}

static void logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    va_list ap;
    (void)env;
    va_start(ap, message);
    vsnprintf(last_message, sizeof last_message, message, ap);
    va_end(ap);
    n_messages++;
    if (verbose) fprintf(stderr, "[%s %d %s] %s\n", name, (int)status, category, last_message);
}

static const fmi2CallbackFunctions CALLBACKS = {logger, calloc, free, NULL, NULL};

/* ------------------------------------------------------------------ counts */

enum {
    MUT_BITFLIP,
    MUT_SLOT,
    MUT_MODEL_FIELD,
    MUT_VALUE_FIELD,
    MUT_SPLICE,
    MUT_RANDOM_BODY,
    MUT_HEADER,
    MUT_TRUNCATE,
    MUT_EXTEND,
    MUT_RANDOM,
    N_MUT
};
static const char *MUT_NAMES[N_MUT] = {"bitflip", "slot",   "model_field", "value_field", "splice",
                                       "random_body", "header", "truncate",  "extend",      "random"};
static unsigned long accepted[N_MUT], refused[N_MUT];
static unsigned long n_crafted, n_legit, n_restored, n_set_ok, n_set_refused, n_step_ok, n_step_refused, n_too_long;

/* ------------------------------------------------------------------ instances */

typedef struct {
    fmi2Component c;
    int tainted; /* it took a mutated state: what it reaches is no longer a legitimate state */
} Slot;

static Slot slots[N_SLOTS];
static fmi2Byte *pool[POOL];
static size_t pool_n, blob_size;

static ModelInstance *mi(const Slot *s) { return (ModelInstance *)s->c; }
static double step_of(const Slot *s) { return mi(s)->v.r[INTERNAL_STEP_VR]; }

static fmi2Component instantiate(const char *name) {
    fmi2Component c = fmi2Instantiate(name, fmi2CoSimulation, MODEL_GUID, "", &CALLBACKS, fmi2False, fmi2False);
    if (!c) fail("fmi2Instantiate refused a valid call");
    return c;
}

/* The instance's bytes (state and values), to tell that a refused call changed nothing. */
typedef struct {
    int state;
    ModelValues v;
} Snapshot;

static void snap(const Slot *s, Snapshot *out) {
    memset(out, 0, sizeof *out);
    out->state = mi(s)->state;
    memcpy(&out->v, &mi(s)->v, sizeof out->v);
}

static void expect_unchanged(const Slot *s, const Snapshot *before, const char *what) {
    Snapshot now;
    snap(s, &now);
    if (memcmp(&now, before, sizeof now) != 0) fail("%s was refused but changed the instance", what);
}

/* a value variable `info` may take: mostly within its range, now and then a special one */
static double value_for(const VarInfo *info) {
    double lo = info->min, hi = info->max;
    if (chance(0.15)) return special_real();
    if (chance(0.1)) return chance(0.5) ? lo : hi;
    if (!isfinite(lo) || !isfinite(hi)) return info->start + (unit() - 0.5) * 20.0;
    return lo + (hi - lo) * unit();
}

static int valid_value(const VarInfo *info, double x) { return isfinite(x) && x >= info->min && x <= info->max; }

/* A valid value for one parameter of any type (the model may still find the set inconsistent). */
static void set_some_parameter(Slot *s) {
    /* one time in three an Integer or Boolean (profiles, counts, seeds, switches: few, and each
     * changes a lot) */
    size_t n_other = N_INTEGERS + N_BOOLEANS;
    size_t k = n_other && chance(1.0 / 3.0) ? N_REALS + below(n_other) : below(N_REALS);
    fmi2ValueReference vr;
    if (k < N_REALS) {
        double x = value_for(&VARS_REAL[k]);
        vr = (fmi2ValueReference)k;
        if (VARS_REAL[k].causality == CAUS_PARAMETER && valid_value(&VARS_REAL[k], x)) fmi2SetReal(s->c, &vr, 1, &x);
    } else if (k < N_REALS + N_INTEGERS) {
        const VarInfo *info = &VARS_INTEGER[k - N_REALS];
        double lo = fmax(info->min, -1e6), hi = fmin(info->max, 1e6);
        fmi2Integer x = (fmi2Integer)(lo + floor((hi - lo + 1.0) * unit()));
        vr = (fmi2ValueReference)(k - N_REALS);
        if (info->causality == CAUS_PARAMETER) fmi2SetInteger(s->c, &vr, 1, &x);
    } else {
        fmi2Boolean x = (fmi2Boolean)below(2);
        vr = (fmi2ValueReference)(k - N_REALS - N_INTEGERS);
        if (VARS_BOOLEAN[vr].causality == CAUS_PARAMETER) fmi2SetBoolean(s->c, &vr, 1, &x);
    }
}

/* Reset (or create) the slot and take it through initialization, with a few parameters moved
 * within their ranges; back to the start values if the model refuses them. */
static void start_slot(Slot *s) {
    size_t k, n = below(6);
    fmi2Status st;
    if (!s->c) s->c = instantiate("fuzz");
    else if (fmi2Reset(s->c) != fmi2OK) fail("fmi2Reset of a live instance failed");
    s->tainted = 0;
    if (fmi2SetupExperiment(s->c, fmi2False, 0.0, chance(0.7) ? 0.0 : 1000.0 * unit(), fmi2False, 0.0) != fmi2OK)
        fail("fmi2SetupExperiment failed");
    if (fmi2EnterInitializationMode(s->c) != fmi2OK) fail("fmi2EnterInitializationMode failed");
    for (k = 0; k < n; k++) set_some_parameter(s);
    st = fmi2ExitInitializationMode(s->c);
    if (st == fmi2OK) return;
    if (fmi2Reset(s->c) != fmi2OK || fmi2SetupExperiment(s->c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
        fmi2EnterInitializationMode(s->c) != fmi2OK || fmi2ExitInitializationMode(s->c) != fmi2OK)
        fail("the start values do not initialize");
}

/* ------------------------------------------------------------------ saving and restoring */

/* The instance's state, serialized into a new exact-size buffer (a live instance can always be saved). */
static fmi2Byte *save(const Slot *s) {
    fmi2FMUstate st = NULL;
    size_t size = 0;
    fmi2Byte *buf;
    if (fmi2GetFMUstate(s->c, &st) != fmi2OK || fmi2SerializedFMUstateSize(s->c, st, &size) != fmi2OK)
        fail("a live instance's state cannot be saved");
    if (size != blob_size) fail("serialized size %zu, expected %zu", size, blob_size);
    buf = (fmi2Byte *)malloc(size);
    if (!buf) fail("out of memory");
    if (fmi2SerializeFMUstate(s->c, st, buf, size) != fmi2OK) fail("fmi2SerializeFMUstate failed");
    fmi2FreeFMUstate(s->c, &st);
    return buf;
}

static double fault_inject_of(const ModelValues *v) {
#ifdef VR_fault_inject
    return v->r[VR_fault_inject];
#else
    (void)v;
    return 0.0;
#endif
}

/* The oracle against false refusals: the state this untainted instance has reached through
 * legitimate calls is accepted when handed back, and comes back byte for byte. (A model told to
 * fail with fault_inject >= 2.5 reports a NaN output it did not compute: not a state to accept.) */
static void check_legit(Slot *s) {
    fmi2Byte *buf, *again;
    fmi2FMUstate st = NULL;
    Slot *other = &slots[below(N_SLOTS)];
    if (s->tainted || !other->c || fault_inject_of(&mi(s)->v) >= 2.5) return;
    buf = save(s);
    if (fmi2DeSerializeFMUstate(other->c, buf, blob_size, &st) != fmi2OK)
        fail("a legitimately reached state (instance state %d) was refused", mi(s)->state);
    if (fmi2SetFMUstate(other->c, st) != fmi2OK) fail("fmi2SetFMUstate refused what it deserialized");
    other->tainted = 0;
    again = save(other);
    if (memcmp(buf, again, blob_size) != 0) fail("a restored state does not serialize to the same bytes");
    fmi2FreeFMUstate(other->c, &st);
    free(again);
    n_legit++;
    if (pool_n < POOL) pool[pool_n++] = buf;
    else {
        size_t k = below(POOL);
        free(pool[k]);
        pool[k] = buf;
    }
}

/* ------------------------------------------------------------------ legitimate runs */

/* Valid values for some inputs: accepted in every state that allows a set. */
static void set_valid_inputs(Slot *s) {
    const int settable = mi(s)->state & (ST_INSTANTIATED | ST_INIT_MODE | ST_STEP_COMPLETE);
    size_t k;
    for (k = 0; k < N_REALS; k++) {
        if (VARS_REAL[k].causality == CAUS_INPUT && chance(0.3)) {
            fmi2ValueReference vr = (fmi2ValueReference)k;
            double x = value_for(&VARS_REAL[k]);
#ifdef VR_fault_inject
            if (k == VR_fault_inject) x = chance(0.9) ? 0.0 : x; /* mostly healthy */
#endif
            if (valid_value(&VARS_REAL[k], x) && fmi2SetReal(s->c, &vr, 1, &x) != fmi2OK && settable)
                fail("a valid input '%s' = %.17g was refused in state %d", VARS_REAL[k].name, x, mi(s)->state);
        }
    }
}

/* One valid doStep of 0..8 internal steps; checks the clock moved by exactly that. */
static void valid_step(Slot *s) {
    int64_t k = (int64_t)below(9), before = mi(s)->v.steps_taken;
    fmi2Status st = fmi2DoStep(s->c, model_time(mi(s)), (double)k * step_of(s), fmi2True);
    if (st == fmi2OK) {
        n_step_ok++;
        if (mi(s)->v.steps_taken != before + k) fail("doStep of %lld internal steps took %lld", (long long)k,
                                                     (long long)(mi(s)->v.steps_taken - before));
    } else if (mi(s)->state == ST_STEP_COMPLETE && fault_inject_of(&mi(s)->v) < 0.5 && !s->tainted) {
        fail("a valid doStep failed (status %d) and left the instance in 'step complete'", (int)st);
    }
}

/* Two instances in the same state, stepped alike, stay bit for bit alike. */
static void check_restore_continues(Slot *s) {
    Slot *t = &slots[(size_t)(s - slots + 1) % N_SLOTS];
    fmi2Byte *buf;
    fmi2FMUstate st = NULL;
    int k;
    if (s->tainted || mi(s)->state != ST_STEP_COMPLETE || !t->c || fault_inject_of(&mi(s)->v) >= 0.5) return;
    buf = save(s);
    if (fmi2DeSerializeFMUstate(t->c, buf, blob_size, &st) != fmi2OK || fmi2SetFMUstate(t->c, st) != fmi2OK)
        fail("a legitimately reached state was refused");
    fmi2FreeFMUstate(t->c, &st);
    free(buf);
    t->tainted = 0;
    for (k = 0; k < 3; k++) {
        double h = (double)(1 + k) * step_of(s);
        if (fmi2DoStep(s->c, model_time(mi(s)), h, fmi2True) != fmi2OK ||
            fmi2DoStep(t->c, model_time(mi(t)), h, fmi2True) != fmi2OK)
            return; /* e.g. an output went non-finite: both fail alike or the next check says so */
        if (memcmp(mi(s)->v.r, mi(t)->v.r, sizeof mi(s)->v.r) != 0 || memcmp(&mi(s)->v.m, &mi(t)->v.m, sizeof mi(s)->v.m) != 0)
            fail("a restored instance does not continue bit for bit like the original");
    }
    n_restored++;
}

static void op_run(Slot *s) {
    int k, n = 1 + (int)below(4);
    if (mi(s)->state != ST_STEP_COMPLETE || s->tainted) start_slot(s);
    for (k = 0; k < n && mi(s)->state == ST_STEP_COMPLETE; k++) {
        set_valid_inputs(s);
        valid_step(s);
    }
    check_legit(s);
    if (chance(0.2)) check_restore_continues(s);
}

/* ------------------------------------------------------------------ mutated states */

static void put_special(fmi2Byte *buf, size_t offset, size_t end) {
    /* an 8-aligned double or int64, or a 4-aligned int, within [offset, end) */
    size_t span = end - offset, at;
    if (span < 8 || chance(0.4)) {
        int x = special_int();
        if (span < 4) return;
        at = offset + 4 * below(span / 4);
        memcpy(buf + at, &x, sizeof x);
    } else if (chance(0.6)) {
        double x = special_real();
        at = offset + 8 * below(span / 8);
        memcpy(buf + at, &x, sizeof x);
    } else {
        int64_t x = special_int64();
        at = offset + 8 * below(span / 8);
        memcpy(buf + at, &x, sizeof x);
    }
}

/* a parameter, input, Integer, Boolean or clock field set to a value out of range or special */
static void put_value_field(Blob *b) {
    switch (below(10)) {
        case 0:
        case 1:
        case 2: b->v.r[below(N_REALS)] = chance(0.5) ? special_real() : value_for(&VARS_REAL[below(N_REALS)]); break;
#if N_INTEGERS > 0
        case 3:
        case 4:
        case 5: b->v.i[below(N_INTEGERS)] = special_int(); break;
#endif
#if N_BOOLEANS > 0
        case 6: b->v.b[below(N_BOOLEANS)] = special_int(); break;
#endif
        case 7: /* a special count, or one a few steps off (wrapping, as the bytes would) */
            b->v.steps_taken = chance(0.5) ? special_int64() : (int64_t)((uint64_t)b->v.steps_taken + below(5) - 2u);
            break;
        case 8: b->v.start_time = special_real(); break;
        default: b->v.state = chance(0.5) ? special_int() : 1 << below(8); break;
    }
}

/* Mutate a pool state into buf (allocated by the caller with room for extension); returns its length. */
static size_t mutate(int kind, fmi2Byte *buf, size_t room) {
    Blob b;
    size_t k, n, len = blob_size;
    memcpy(buf, pool[below(pool_n)], blob_size);
    switch (kind) {
        case MUT_BITFLIP:
            for (k = 0, n = 1 + below(8); k < n; k++) buf[below(blob_size)] ^= (fmi2Byte)(1u << below(8));
            break;
        case MUT_SLOT: put_special(buf, 0, blob_size); break;
        case MUT_MODEL_FIELD:
            for (k = 0, n = 1 + below(2); k < n; k++)
                put_special(buf, offsetof(Blob, v.m), offsetof(Blob, v.m) + sizeof(ModelState));
            break;
        case MUT_VALUE_FIELD:
            memcpy(&b, buf, sizeof b);
            for (k = 0, n = 1 + below(3); k < n; k++) put_value_field(&b);
            memcpy(buf, &b, sizeof b);
            break;
        case MUT_SPLICE: /* the model's states of another moment (or another parameter set) */
            memcpy(buf + offsetof(Blob, v.m), pool[below(pool_n)] + offsetof(Blob, v.m), sizeof(ModelState));
            break;
        case MUT_RANDOM_BODY:
            for (k = offsetof(Blob, v); k < blob_size; k++) buf[k] = (fmi2Byte)fz_next();
            break;
        case MUT_HEADER: buf[below(offsetof(Blob, v))] ^= (fmi2Byte)(1u + below(255)); break;
        case MUT_TRUNCATE: len = below(blob_size); break;
        case MUT_EXTEND:
            len = blob_size + 1 + below(room - blob_size);
            for (k = blob_size; k < len; k++) buf[k] = (fmi2Byte)fz_next();
            break;
        default:
            len = chance(0.5) ? blob_size : below(room);
            for (k = 0; k < len; k++) buf[k] = (fmi2Byte)fz_next();
            break;
    }
    return len;
}

/* What an accepted (possibly crafted) state must survive: reading, stepping, setting, saving. */
static void exercise(Slot *s) {
    fmi2ValueReference vrs[N_REALS];
    fmi2Real values[N_REALS];
    size_t k;
    int j;
    for (k = 0; k < N_REALS; k++) vrs[k] = (fmi2ValueReference)k;
    fmi2GetReal(s->c, vrs, N_REALS, values);
    for (j = 0; j < 3; j++) {
        if (chance(0.5)) set_valid_inputs(s);
        fmi2DoStep(s->c, model_time(mi(s)), (double)(1 + below(5)) * step_of(s), fmi2True);
        fmi2GetReal(s->c, vrs, N_REALS, values);
    }
    free(save(s));
}

static void op_blob(Slot *s) {
    const size_t room = blob_size + 64;
    int kind = (int)below(N_MUT);
    fmi2Byte *buf = (fmi2Byte *)malloc(room), *exact;
    size_t len;
    fmi2FMUstate st = NULL;
    Snapshot before;
    fmi2Status status;
    if (!buf) fail("out of memory");
    if (!pool_n) {
        free(buf);
        op_run(s);
        return;
    }
    len = mutate(kind, buf, room);
    exact = (fmi2Byte *)malloc(len ? len : 1); /* exactly len bytes: any read beyond is an ASan report */
    if (!exact) fail("out of memory");
    memcpy(exact, buf, len);
    free(buf);
    snap(s, &before);
    status = fmi2DeSerializeFMUstate(s->c, exact, len, &st);
    expect_unchanged(s, &before, "fmi2DeSerializeFMUstate"); /* deserializing never touches the instance */
    free(exact);
    if (status != fmi2OK) {
        if (st) fail("a refused state was handed out");
        refused[kind]++;
        if (mi(s)->state == ST_STEP_COMPLETE) valid_step(s); /* still usable */
        return;
    }
    if (kind == MUT_HEADER || kind == MUT_TRUNCATE || kind == MUT_EXTEND)
        fail("a state with a broken %s was accepted", MUT_NAMES[kind]);
    accepted[kind]++;
    if (fmi2SetFMUstate(s->c, st) != fmi2OK) fail("fmi2SetFMUstate refused what fmi2DeSerializeFMUstate accepted");
    if (memcmp(&mi(s)->v, &((const Blob *)st)->v, sizeof mi(s)->v) != 0) fail("the accepted state is not the instance's");
    fmi2FreeFMUstate(s->c, &st);
    s->tainted = 1;
    exercise(s);
}

/* ------------------------------------------------------------------ misuse of the API */

/* A set call with random references (some unknown), values (some special) and arrays (some
 * NULL): a refusal changes nothing, a success stored valid values. */
static void op_set(Slot *s) {
    fmi2ValueReference vr[MAX_NVR];
    fmi2Real rv[MAX_NVR];
    fmi2Integer iv[MAX_NVR];
    fmi2String sv[MAX_NVR] = {"x", "", NULL, "y", "z"};
    size_t k, nvr = below(MAX_NVR + 1), type = below(4);
    size_t n_vars = type == 0 ? N_REALS : (type == 1 ? N_INTEGERS : (type == 2 ? N_BOOLEANS : 0));
    const VarInfo *table = type == 0 ? VARS_REAL : (type == 1 ? VARS_INTEGER : VARS_BOOLEAN);
    int null_args = chance(0.05);
    Snapshot before;
    fmi2Status st;
    for (k = 0; k < nvr; k++) {
        if (chance(0.9) && n_vars) vr[k] = (fmi2ValueReference)below(n_vars);
        else vr[k] = chance(0.3) ? UINT_MAX - (fmi2ValueReference)below(3) : (fmi2ValueReference)(n_vars + below(3));
        rv[k] = vr[k] < n_vars ? value_for(&table[vr[k]]) : special_real();
        iv[k] = chance(0.7) && vr[k] < n_vars ? (int)fmax(-1e9, fmin(1e9, value_for(&table[vr[k]]))) : special_int();
    }
    snap(s, &before);
    if (type == 0) st = fmi2SetReal(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : rv);
    else if (type == 1) st = fmi2SetInteger(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : iv);
    else if (type == 2) st = fmi2SetBoolean(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : iv);
    else st = fmi2SetString(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : sv);
    if (st != fmi2OK) {
        n_set_refused++;
        expect_unchanged(s, &before, "a set");
        return;
    }
    n_set_ok++;
    for (k = 0; k < nvr; k++) {
        double x = type == 0 ? mi(s)->v.r[vr[k]] : (double)(type == 1 ? mi(s)->v.i[vr[k]] : mi(s)->v.b[vr[k]]);
        if (type == 3 || !valid_value(&table[vr[k]], x)) fail("a set stored an invalid value %.17g for vr %u", x, vr[k]);
    }
}

static void op_get(Slot *s) {
    fmi2ValueReference vr[MAX_NVR];
    fmi2Real rv[MAX_NVR];
    fmi2Integer iv[MAX_NVR];
    fmi2String sv[MAX_NVR];
    fmi2Status status;
    fmi2Real t;
    fmi2Boolean b;
    size_t k, nvr = below(MAX_NVR + 1);
    int null_args = chance(0.05);
    for (k = 0; k < nvr; k++) vr[k] = chance(0.9) ? (fmi2ValueReference)below(N_REALS) : (fmi2ValueReference)(N_REALS + below(1000));
    switch (below(7)) {
        case 0: fmi2GetReal(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : rv); break;
        case 1: fmi2GetInteger(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : iv); break;
        case 2: fmi2GetBoolean(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : iv); break;
        case 3: fmi2GetString(s->c, null_args ? NULL : vr, nvr, null_args ? NULL : sv); break;
        case 4: fmi2GetStatus(s->c, (fmi2StatusKind)below(4), null_args ? NULL : &status); break;
        case 5: fmi2GetRealStatus(s->c, (fmi2StatusKind)below(4), null_args ? NULL : &t); break;
        default: fmi2GetBooleanStatus(s->c, (fmi2StatusKind)below(4), null_args ? NULL : &b); break;
    }
}

/* doStep with a random step: a refusal changes nothing; beyond TWIN_MAX_SUBSTEPS always a refusal. */
static void op_step(Slot *s) {
    double h = step_of(s), t = model_time(mi(s)), dt;
    int too_long = 0;
    Snapshot before;
    fmi2Status st;
    switch (below(8)) {
        case 0: dt = special_real(); break;
        case 1: dt = -(double)(1 + below(5)) * h; break;
        case 2: dt = ((double)below(5) + 0.37) * h; break;
        case 3: t += (double)(1 + below(3)) * h; dt = h; break;
        case 4: t = special_real(); dt = h; break;
        case 5:
            dt = (double)(TWIN_MAX_SUBSTEPS + 1 + (int64_t)below(1000)) * h;
            too_long = 1;
            break;
        case 6:
            dt = (1e6 + 1e6 * unit()) * (double)TWIN_MAX_SUBSTEPS * h;
            too_long = 1;
            break;
        default: dt = (double)below(9) * h; break;
    }
    snap(s, &before);
    st = fmi2DoStep(s->c, t, dt, chance(0.5) ? fmi2True : fmi2False);
    if (st == fmi2OK && too_long) fail("doStep of %.17g s (more than %d internal steps) was accepted", dt, TWIN_MAX_SUBSTEPS);
    if (too_long) n_too_long++;
    if (st == fmi2OK) {
        n_step_ok++;
    } else {
        n_step_refused++;
        /* a refused argument changes nothing; only a model failure mid-step moves the instance to 'error' */
        if (mi(s)->state != ST_ERROR && mi(s)->state != ST_STEP_FAILED) expect_unchanged(s, &before, "a doStep");
    }
}

static void op_lifecycle(Slot *s) {
    static const fmi2String categories[] = {"logAll", "logStatusError", "nonsense", NULL};
    fmi2ValueReference vr = 0;
    fmi2Real x = 1.0;
    fmi2Integer order = 1;
    switch (below(12)) {
        case 0: fmi2SetupExperiment(s->c, fmi2True, special_real(), chance(0.5) ? 0.0 : special_real(), (fmi2Boolean)below(2), special_real()); break;
        case 1: fmi2EnterInitializationMode(s->c); break;
        case 2: fmi2ExitInitializationMode(s->c); break;
        case 3: fmi2Terminate(s->c); break;
        case 4: fmi2Reset(s->c); s->tainted = 0; break;
        case 5:
            fmi2FreeInstance(s->c);
            s->c = instantiate(chance(0.5) ? "fuzz" : "a much longer instance name, to be copied");
            s->tainted = 0;
            break;
        case 6:
            if (fmi2Instantiate(chance(0.5) ? NULL : "", fmi2CoSimulation, MODEL_GUID, "", &CALLBACKS, 0, 0) ||
                fmi2Instantiate("x", fmi2ModelExchange, MODEL_GUID, "", &CALLBACKS, 0, 0) ||
                fmi2Instantiate("x", fmi2CoSimulation, chance(0.5) ? NULL : "{not-this-guid}", "", &CALLBACKS, 0, 0))
                fail("fmi2Instantiate accepted a wrong name, type or GUID");
            break;
        case 7: fmi2SetDebugLogging(s->c, (fmi2Boolean)below(2), below(3), chance(0.1) ? NULL : categories + below(2)); break;
        case 8: fmi2SetRealInputDerivatives(s->c, &vr, 1, &order, &x); break;
        case 9: fmi2GetRealOutputDerivatives(s->c, &vr, 1, &order, &x); break;
        case 10: fmi2CancelStep(s->c); break;
        default: start_slot(s); break;
    }
}

/* FMU-state calls with NULL, foreign and short arguments. */
static void op_state_api(Slot *s) {
    /* a state of another model: the same header layout, another GUID, and smaller than ours */
    size_t foreign_size = offsetof(Blob, v) + 8 * (1 + below(4));
    fmi2Byte *foreign = (fmi2Byte *)calloc(1, foreign_size), small[16];
    fmi2FMUstate st = NULL, f = foreign;
    size_t size = 0;
    if (!foreign) fail("out of memory");
    memcpy(foreign, "TWINSTA1", 8);
    strcpy((char *)foreign + 8, "{00000000-0000-0000-0000-000000000000}");
    if (fmi2SetFMUstate(s->c, f) == fmi2OK || fmi2SerializedFMUstateSize(s->c, f, &size) == fmi2OK ||
        fmi2SerializeFMUstate(s->c, f, small, sizeof small) == fmi2OK || fmi2GetFMUstate(s->c, &f) == fmi2OK ||
        fmi2SetFMUstate(s->c, NULL) == fmi2OK || fmi2DeSerializeFMUstate(s->c, NULL, blob_size, &st) == fmi2OK)
        fail("an FMU-state call accepted a foreign or NULL state");
    free(foreign);
    if (fmi2GetFMUstate(s->c, &st) == fmi2OK) {
        fmi2GetFMUstate(s->c, &st); /* update in place */
        if (fmi2SerializeFMUstate(s->c, st, small, sizeof small) == fmi2OK) fail("serialized into a too small buffer");
        fmi2SerializedFMUstateSize(s->c, st, chance(0.5) ? NULL : &size);
        fmi2SetFMUstate(s->c, st); /* its own state: changes nothing */
        fmi2FreeFMUstate(s->c, &st);
    }
    fmi2FreeFMUstate(s->c, NULL);
    fmi2FreeFMUstate(s->c, &st);
}

/* ------------------------------------------------------------------ crafted states */

/* Index of the first Real of this causality (outputs, inputs) or -1. */
static int first_real(Causality causality) {
    size_t k;
    for (k = 0; k < N_REALS; k++)
        if (VARS_REAL[k].causality == causality) return (int)k;
    return -1;
}

/* The wrapper's invariants, one violation each (case k of a valid 'step complete' state b);
 * returns the words the refusal's message must contain, or NULL past the last case. */
static const char *craft_common(int k, Blob *b) {
    int out = first_real(CAUS_OUTPUT), in = first_real(CAUS_INPUT);
    switch (k) {
        case 0: b->v.state = 0; return "instance state";
        case 1: b->v.state = ST_STEP_COMPLETE | ST_TERMINATED; return "instance state";
        case 2: b->v.state = ST_FATAL; return "instance state";
        case 3: b->v.steps_taken = -1; return "internal steps taken";
        case 4: b->v.steps_taken = INT64_MAX; return "internal steps taken";
        case 5: b->v.state = ST_INIT_MODE; return "internal steps taken"; /* steps before initialization is over */
        case 6: b->v.start_time = NAN; return "start time";
        case 7: b->v.start_time = -INFINITY; return "start time";
        case 8: b->v.r[INTERNAL_STEP_VR] = 0.0; return VARS_REAL[INTERNAL_STEP_VR].name;
        case 9: b->v.r[INTERNAL_STEP_VR] = -b->v.r[INTERNAL_STEP_VR]; return VARS_REAL[INTERNAL_STEP_VR].name;
        case 10: b->v.r[INTERNAL_STEP_VR] = NAN; return VARS_REAL[INTERNAL_STEP_VR].name;
        case 11: b->v.r[INTERNAL_STEP_VR] = VARS_REAL[INTERNAL_STEP_VR].max * 2.0; return VARS_REAL[INTERNAL_STEP_VR].name;
        case 12: b->v.r[in] = NAN; return VARS_REAL[in].name;
        case 13: b->v.r[in] = INFINITY; return VARS_REAL[in].name;
        case 14: b->v.r[out] += 1.0 + fabs(b->v.r[out]); return "output";
        case 15: b->v.r[out] = NAN; return "output";
        case 16: b->header_size = 0; return "not a state of this FMU";
        case 17: b->magic[7] = '2'; return "not a state of this FMU";
        case 18: b->guid[1] ^= 1; return "not a state of this FMU";
        case 19: b->guid[60] = 'x'; return "not a state of this FMU"; /* the padding after the GUID too */
#if N_INTEGERS > 0
        case 20: b->v.i[0] = (int)VARS_INTEGER[0].min - 1; return VARS_INTEGER[0].name; /* every min is > INT_MIN */
        case 21: b->v.i[0] = INT_MIN; return VARS_INTEGER[0].name;
#endif
#if N_BOOLEANS > 0
        case 22: b->v.b[0] = 2; return "neither 0 nor 1";
        case 23: b->v.b[0] = -1; return "neither 0 nor 1";
#endif
        case 24: return NULL;
        default: return "";
    }
}

/* The model's own invariants (model_check_state and model_check), one violation each. */
static const char *craft_model(int k, Blob *b) {
    ModelState *m = &b->v.m;
    (void)m;
    switch (k) {
#ifdef HL_TABLE /* HydraulicLoader: the crash of issue 13 was table_n = 0 under profile 3 */
        case 0: b->v.i[VR_profile] = 3; b->v.i[VR_table_n] = 0; return "table_n";
        case 1: b->v.i[VR_profile] = 3; b->v.i[VR_table_n] = -5; return "table_n";
        case 2: b->v.i[VR_profile] = 3; b->v.i[VR_table_n] = HL_TABLE + 1; return "table_n";
        case 3: b->v.i[VR_profile] = 4; return "profile";
        case 4: b->v.i[VR_profile] = 3; b->v.i[VR_table_n] = 3; b->v.r[VR_table_t_3] = b->v.r[VR_table_t_2]; return "table times";
        case 5: m->load = NAN; return "servo state load";
        case 6: m->load = 1e12; return "servo state load";
        case 7: m->rate_scaled = -INFINITY; return "rate_scaled";
        case 8: m->step_h *= 2.0; return "step matrices made for";
        case 9: m->phi[0] *= 1.0 + 1e-6; return "phi";
        case 10: m->gamma[1] += 1e-3; return "gamma";
#endif
#ifdef OSCILLATION_DRIVE_CONFIG_H
        case 0: memset(m->rng.s, 0, sizeof m->rng.s); return "all zero";
        case 1: m->rng.has_spare = 3; return "has_spare";
        case 2: m->rng.gauss_spare = 100.0; return "spare normal";
        case 3: m->n_window = 0; return "n_window";
        case 4: m->n_block = m->n_window; return "n_block";
        case 5: m->n_on = b->v.steps_taken + 1; return "n_on";
        case 6: m->n_on = -1; return "n_on";
        case 7: m->distance = -1.0; return "distance";
        case 8: m->distance = 1e12; return "distance";
        case 9: m->energy = NAN; return "energy";
        case 10: m->e_block = m->energy * 2.0 + 1.0; return "e_block";
        case 11: m->q_avg = -1.0; return "q_avg";
        case 12: m->t_since_rev = -1.0; return "t_since_rev";
        case 13: m->z_vib = 1.0; return "z_vib";
        case 14: m->has_reversal = 2; return "swing memory";
        case 15: m->rev_sign = 0.5; return "swing memory";
        case 16: b->v.i[VR_waveform] = 2; return "waveform";
        case 17: b->v.r[VR_mu_min] = 1.0; b->v.r[VR_mu_max] = 0.5; return "mu_min";
#endif
#ifdef SD_TEMPS
        case 0: memset(m->rng2.s, 0, sizeof m->rng2.s); return "all zero";
        case 1: m->rng.has_spare = -1; return "has_spare";
        case 2: m->step_h *= 0.5; return "gains made for";
        case 3: m->a_temp *= 1.5; return "gain";
        case 4: m->spike_steps = 0; return "spike_steps";
        case 5: m->spike_steps = -1; return "spike_steps";
        case 6: m->temp_lag[3] = 1000.0; return "temperature sensor lag";
        case 7: m->probe_filt = 1.0; return "probe filter";
        case 8: m->t_probe_body0 = NAN; return "probe body reference";
        case 9: m->spike_left = -1; return "spike_left";
        case 10: m->spike_left = m->spike_steps + 1; return "spike_left";
        case 11: m->spike_value = 1.0; return "spike_value";
        case 12: m->spike_sample = 0.5; return "spike_sample";
        case 13: m->temp_sample[0] = NAN; return "temperature sample";
        case 14: m->probe_sample = 2.0; return "probe_sample";
        case 15: m->probe_in_range = 0.5; return "probe_in_range";
        case 16: m->vibration_sample = INFINITY; return "sample";
        case 17: b->v.r[VR_probe_range_min] = 0.5; b->v.r[VR_probe_range_max] = 0.1; return "probe_range_min";
        case 18: m->rng.owed = -1; return "normals owed";
        case 19: m->rng3.owed = RNG_OWED_MAX + 1; return "normals owed";
#endif
#ifdef TN_NODES
        case 0: m->temp[4] = NAN; return "node temperature";
        case 1: m->temp[4] = 100.0; return "node temperature";
        case 2: m->energy_in = -1.0; return "energy_in";
        case 3: m->energy_in = 1e30; return "energy_in";
        case 4: m->energy_lost = INFINITY; return "energy_lost";
        case 5: m->energy_stored0 = NAN; return "energy_stored0";
        case 6: m->phi_h *= 2.0; return "step matrices made for";
        case 7: m->phi[0] *= 1.0 + 1e-6; return "phi";
        case 8: m->psi[TN_NODES + 1] += 1.0; return "psi";
        case 9: m->gamma[0] = -1.0; return "gamma";
        case 10: m->lambda[2] = NAN; return "lambda";
        case 11: b->v.r[VR_hyd_share_oil] = 0.5; return "hyd_share";
#endif
#ifdef FM_TEMPS
        case 0: b->v.b[VR_reference_at_start] = 1; m->t_ref[2] = 1000.0; return "reference temperature";
        case 1: b->v.b[VR_reference_at_start] = 0; m->t_ref[2] = b->v.r[VR_t_reference] + 1.0; return "reference temperature";
        case 2: m->sliding_distance = -1.0; return "sliding_distance";
        case 3: m->sliding_distance = 1e12; return "sliding_distance";
        case 4: m->wear = -1e-9; return "wear";
        case 5: m->wear = NAN; return "wear";
        case 6: m->wear = 1.0; return "wear";
        case 7: b->v.r[VR_k_spring] = 0.0; b->v.r[VR_k_head] = 0.0; return "k_spring";
#endif
#ifdef SS_TABLE /* SignalSource: no state of its own; its parameters' consistency is all */
        case 0: b->v.i[VR_profile] = 5; return "profile";
        case 1: b->v.i[VR_profile] = 4; b->v.i[VR_table_n] = 0; return "table_n";
        case 2: b->v.i[VR_profile] = 4; b->v.i[VR_table_n] = SS_TABLE + 1; return "table_n";
        case 3: b->v.i[VR_profile] = 4; b->v.i[VR_table_n] = 3; return "table times"; /* all at 0 s */
        case 4: b->v.i[VR_profile] = 1; b->v.r[VR_duration] = 0.0; return "duration";
        case 5: b->v.i[VR_profile] = 2; b->v.r[VR_time_constant] = 0.0; return "time_constant";
        case 6: b->v.i[VR_profile] = 3; b->v.r[VR_period] = 0.0; return "period";
        case 7: b->v.r[VR_value] = NAN; return "value";
        case 8: m->step_ns += 1; return "step_ns";
        case 9: m->scale = 2.0; return "scale";
        case 10: m->scale = NAN; return "scale";
#endif
        case 40: return NULL;
        default: return "";
    }
}

/* Every crafted violation of a valid 'step complete' state is refused, with a message that
 * names it, and leaves the instance unchanged. Returns the number of cases. */
static int crafted_cases(Slot *s) {
    int k, part, n = 0;
    const char *expect;
    fmi2Byte *base;
    /* the start values, 20 internal steps on */
    if (fmi2Reset(s->c) != fmi2OK || fmi2SetupExperiment(s->c, fmi2False, 0.0, 0.0, fmi2False, 0.0) != fmi2OK ||
        fmi2EnterInitializationMode(s->c) != fmi2OK || fmi2ExitInitializationMode(s->c) != fmi2OK ||
        fmi2DoStep(s->c, 0.0, 20.0 * step_of(s), fmi2True) != fmi2OK)
        fail("the crafted cases need a state in 'step complete'");
    s->tainted = 0;
    base = save(s);
    for (part = 0; part < 2; part++) {
        for (k = 0;; k++) {
            Blob b;
            fmi2FMUstate st = NULL;
            Snapshot before;
            memcpy(&b, base, sizeof b);
            expect = part == 0 ? craft_common(k, &b) : craft_model(k, &b);
            if (!expect) break;
            if (!expect[0]) continue;
            snap(s, &before);
            last_message[0] = '\0';
            if (fmi2DeSerializeFMUstate(s->c, (const fmi2Byte *)&b, sizeof b, &st) == fmi2OK)
                fail("crafted %s case %d (%s) was accepted", part ? "model" : "common", k, expect);
            expect_unchanged(s, &before, "a crafted state");
            if (!strstr(last_message, expect))
                fail("crafted %s case %d was refused, but the message does not name '%s'", part ? "model" : "common", k, expect);
            n++;
        }
    }
    free(base);
    return n;
}

/* ------------------------------------------------------------------ main */

static void report(long iterations) {
    int k;
    printf("model %s seed %llu iterations %ld:", MODEL_GUID, (unsigned long long)seed_given, iterations);
    for (k = 0; k < N_MUT; k++) printf(" %s=%lu/%lu", MUT_NAMES[k], accepted[k], refused[k]);
    printf(" crafted=%lu legit=%lu restored=%lu set=%lu/%lu step=%lu/%lu too_long=%lu messages=%lu\n", n_crafted, n_legit, n_restored, n_set_ok,
           n_set_refused, n_step_ok, n_step_refused, n_too_long, n_messages);
}

int main(int argc, char **argv) {
    long iterations;
    size_t k;
    if (argc < 3) {
        fprintf(stderr, "usage: %s SEED ITERATIONS [-v] [-r]\n", argv[0]);
        return 2;
    }
    seed_given = strtoull(argv[1], NULL, 10);
    fz_x = seed_given;
    iterations = strtol(argv[2], NULL, 10);
    for (k = 3; k < (size_t)argc; k++) {
        if (strcmp(argv[k], "-v") == 0) verbose = 1;
        else if (strcmp(argv[k], "-r") == 0) random_only = 1;
    }
    for (k = 0; k < N_SLOTS; k++) start_slot(&slots[k]);
    if (fmi2SerializedFMUstateSize(slots[0].c, NULL, &blob_size) == fmi2OK) fail("a NULL state has a size");
    {
        fmi2FMUstate st = NULL;
        fmi2GetFMUstate(slots[0].c, &st);
        fmi2SerializedFMUstateSize(slots[0].c, st, &blob_size);
        fmi2FreeFMUstate(slots[0].c, &st);
    }
    if (blob_size != sizeof(Blob)) fail("serialized states have %zu bytes, this harness expects %zu", blob_size, sizeof(Blob));
    if (!random_only) n_crafted = (unsigned long)crafted_cases(&slots[0]);
    for (k = 0; k < N_SLOTS; k++) op_run(&slots[k]);
    for (iteration = 0; iteration < iterations; iteration++) {
        Slot *s = &slots[below(N_SLOTS)];
        switch (below(10)) {
            case 0:
            case 1:
            case 2: op_blob(s); break;
            case 3: op_set(s); break;
            case 4: op_get(s); break;
            case 5: op_step(s); break;
            case 6: op_lifecycle(s); break;
            case 7: op_state_api(s); break;
            default: op_run(s); break;
        }
        if (chance(0.25)) check_legit(s);
        if (s->tainted && chance(0.2)) start_slot(s); /* back to legitimate states now and then */
    }
    report(iterations);
    for (k = 0; k < N_SLOTS; k++) fmi2FreeInstance(slots[k].c);
    for (k = 0; k < pool_n; k++) free(pool[k]);
    return 0;
}
