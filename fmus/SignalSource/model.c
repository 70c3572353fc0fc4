/*
 * SignalSource -- the twin's input profiles as an FMU output (equations in readme.md).
 *
 *   0 constant      y = value
 *   1 ramp          y = start + (end - start) clip((t - delay) / duration, 0, 1)
 *   2 exponential   y = start + rise s (-expm1(-max(t, 0) / time_constant)),
 *                   s = 1 / -expm1(-rise_at / time_constant) if rise_at > 0, else 1
 *   3 sine          y = mean + amplitude sin(2 pi t / period + phase)
 *   4 table         linear interpolation through (table_t_k, table_v_k), k = 1..table_n,
 *                   the first value before the first time, the last after the last
 *
 * Why it exists: an SSP archive the twin exports has to carry the inputs its scenario drives
 * by a profile, so that another master (libcosim, OMSimulator, fmpy) runs the same system.
 * Each formula is written in the order of operations of twin.config.profiles (numpy), and the
 * time is the master's: t = (n * step_ns) / 1e9 from an integer count of nanoseconds, never a
 * sum of floats, so a master on the same clock gets the twin's profile values (the libm's
 * expm1 and numpy's may differ in the last bit).
 */
#include <math.h>
#include <stdio.h>

#include "model.h"

/* numpy's np.pi: the double nearest pi (M_PI is not ISO C) */
#define SS_PI 3.14159265358979323846

enum { P_CONSTANT = 0, P_RAMP = 1, P_EXPONENTIAL = 2, P_SINE = 3, P_TABLE = 4 };

/* the table's variables are numbered consecutively (modelDescription.xml): checked here, at
 * compile time, so that the index arithmetic below cannot drift from the XML */
typedef char table_t_consecutive[(VR_table_t_64 - VR_table_t_1 == SS_TABLE - 1) ? 1 : -1];
typedef char table_v_consecutive[(VR_table_v_64 - VR_table_v_1 == SS_TABLE - 1) ? 1 : -1];

#define T_K(r, k) ((r)[VR_table_t_1 + (k)])
#define V_K(r, k) ((r)[VR_table_v_1 + (k)])

static int64_t step_ns_of(double h) { return (int64_t)llround(h * 1e9); }

static double scale_of(const double *r) {
    return r[VR_rise_at] > 0.0 ? 1.0 / -expm1(-r[VR_rise_at] / r[VR_time_constant]) : 1.0;
}

/* The time as the twin's master computes it for a tick: whole nanoseconds divided by 1e9 (the
 * master's steps are integer nanoseconds, the solver step rounded to them); a count too large
 * for 64-bit nanoseconds falls back to the wrapper's clock. */
static double exact_time(const ModelInstance *comp) {
    int64_t step_ns = comp->v.m.step_ns, n = comp->v.steps_taken;
    if (step_ns > 0 && n >= 0 && n <= INT64_C(9000000000000000000) / step_ns)
        return comp->v.start_time + (double)(n * step_ns) / 1e9;
    return model_time(comp);
}

/* np.interp: the segment j with t_j <= t < t_(j+1), slope (v1 - v0) / (t1 - t0), then
 * slope (t - t_j) + v_j; exactly v_j at a point's own time (numpy's fallback for a slope that
 * is not finite is never needed: model_check refuses such a table) */
static double table(const ModelInstance *comp, double t) {
    const double *r = comp->v.r;
    int n = comp->v.i[VR_table_n], j;
    double slope;
    if (t <= T_K(r, 0)) return V_K(r, 0);
    if (t >= T_K(r, n - 1)) return V_K(r, n - 1);
    for (j = 0; j < n - 2 && !(t < T_K(r, j + 1)); j++) {
    }
    if (t == T_K(r, j)) return V_K(r, j);
    slope = (V_K(r, j + 1) - V_K(r, j)) / (T_K(r, j + 1) - T_K(r, j));
    return slope * (t - T_K(r, j)) + V_K(r, j); /* finite: model_check refuses an infinite slope */
}

static double profile(const ModelInstance *comp, double t) {
    const double *r = comp->v.r;
    double x;
    switch (comp->v.i[VR_profile]) {
        case P_RAMP:
            x = (t - r[VR_delay]) / r[VR_duration];
            x = x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x);
            return r[VR_start] + (r[VR_end] - r[VR_start]) * x;
        case P_EXPONENTIAL:
            return r[VR_start] + r[VR_rise] * comp->v.m.scale * -expm1(-fmax(t, 0.0) / r[VR_time_constant]);
        case P_SINE: return r[VR_mean] + r[VR_amplitude] * sin(2.0 * SS_PI * t / r[VR_period] + r[VR_phase]);
        case P_TABLE: return table(comp, t);
        default: return r[VR_value];
    }
}

/* ------------------------------------------------------------------ model contract */

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    const double *r = comp->v.r;
    int p = comp->v.i[VR_profile], n = comp->v.i[VR_table_n], k;
    /* the XML ranges guard these for a host that honours them; the model never relies on it */
    if (p < P_CONSTANT || p > P_TABLE) {
        snprintf(msg, msg_size, "profile = %d: must be 0 (constant), 1 (ramp), 2 (exponential), 3 (sine) or 4 (table)", p);
        return -1;
    }
    if (n < 2 || n > SS_TABLE) {
        snprintf(msg, msg_size, "table_n = %d: must be 2..%d", n, SS_TABLE);
        return -1;
    }
    /* only the active profile's data must be consistent; every parameter is finite (the
     * wrapper refuses others), so what is left is a value range that overflows: checked on the
     * quantities each formula forms, so that y is finite at every time */
    if (p == P_RAMP && !(r[VR_duration] > 0.0)) {
        snprintf(msg, msg_size, "duration = %g s: a ramp needs a positive duration", r[VR_duration]);
        return -1;
    }
    if (p == P_RAMP && !isfinite(r[VR_end] - r[VR_start])) {
        snprintf(msg, msg_size, "end - start overflows: start = %g, end = %g", r[VR_start], r[VR_end]);
        return -1;
    }
    if (p == P_EXPONENTIAL && !(r[VR_time_constant] > 0.0)) {
        snprintf(msg, msg_size, "time_constant = %g s: must be positive", r[VR_time_constant]);
        return -1;
    }
    if (p == P_EXPONENTIAL) {
        double scale = scale_of(r);
        if (!isfinite(r[VR_rise] * scale) || !isfinite(r[VR_start] + r[VR_rise] * scale)) {
            snprintf(msg, msg_size, "the rise scaled to rise_at = %g s overflows (time_constant = %g s, rise = %g)",
                     r[VR_rise_at], r[VR_time_constant], r[VR_rise]);
            return -1;
        }
    }
    if (p == P_SINE && !(r[VR_period] > 0.0)) {
        snprintf(msg, msg_size, "period = %g s: must be positive", r[VR_period]);
        return -1;
    }
    if (p == P_SINE && !isfinite(fabs(r[VR_mean]) + fabs(r[VR_amplitude]))) {
        snprintf(msg, msg_size, "mean +- amplitude overflows: mean = %g, amplitude = %g", r[VR_mean], r[VR_amplitude]);
        return -1;
    }
    if (p == P_TABLE) {
        for (k = 1; k < n; k++) {
            if (!(T_K(r, k) > T_K(r, k - 1))) {
                snprintf(msg, msg_size, "table times must increase strictly: table_t_%d = %g s is not after table_t_%d = %g s",
                         k + 1, T_K(r, k), k, T_K(r, k - 1));
                return -1;
            }
            if (!isfinite((V_K(r, k) - V_K(r, k - 1)) / (T_K(r, k) - T_K(r, k - 1)))) {
                snprintf(msg, msg_size, "the table's slope between points %d and %d overflows", k, k + 1);
                return -1;
            }
        }
    }
    return 0;
}

fmi2Status model_initialize(ModelInstance *comp) {
    comp->v.m.step_ns = step_ns_of(comp->v.r[VR_solver_step]);
    comp->v.m.scale = comp->v.i[VR_profile] == P_EXPONENTIAL ? scale_of(comp->v.r) : 1.0;
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    (void)comp;
    (void)h;
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) { comp->v.r[VR_y] = profile(comp, exact_time(comp)); }

/* A state handed back: what is precomputed must be what the parameters give (the parameters,
 * the clock and the output the wrapper checks). */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    int64_t want_ns = step_ns_of(comp->v.r[VR_solver_step]);
    double want_scale = comp->v.i[VR_profile] == P_EXPONENTIAL ? scale_of(comp->v.r) : 1.0;
    if (state_bad_int(c, "step_ns (the solver step in nanoseconds)", m->step_ns, want_ns, want_ns)) return -1;
    if (state_bad_match(c, "scale (the exponential's rise_at scaling)", &m->scale, &want_scale, 1)) return -1;
    return 0;
}
