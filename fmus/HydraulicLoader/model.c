/*
 * HydraulicLoader -- the hydraulic loading module of the bearing tester (equations in readme.md).
 *
 *   command     u(t) = s(t) (p(t) + F_off(t)),  p = constant | sine | trapezoid | table profile
 *   servo       F'' + 2 zeta omega_n F' + omega_n^2 F = omega_n^2 u
 *   ripple      F_r = r F sin(2 pi f_r t)
 *   outputs     radial_load = F + F_r,  pressure = radial_load / A,
 *               q_station = s (Q_idle + k |radial_load|)
 *
 * The command is evaluated at the start of each internal step and held over it (zero-order
 * hold). With the scaled rate w = F' / omega_n the servo is
 *
 *   d/dt [F; w] = omega_n [0 1; -1 -2 zeta] [F; w] + omega_n [0; 1] u,
 *
 * and the step map [F; w](t+h) = phi [F; w](t) + gamma u comes from one matrix exponential of
 * the augmented 3x3 system [A B; 0 0] h, computed at initialization: exact for any step, so
 * stable however stiff the servo is against the step. The profile and the ripple are functions
 * of the simulation time t = t0 + k h from the wrapper's integer step counter, so doStep(2h)
 * equals two doStep(h) bit for bit.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "linalg.h"
#include "model.h"

#define TWO_PI 6.283185307179586476925286766559

/* N: no state a run can reach comes near it. |command| <= 9e5 N by the declared ranges (a sine
 * of mean and amplitude <= 3e5 each, plus |load_offset| <= 3e5, times station_on <= 1), and the
 * servo's gain over any command history (the L1 norm of its impulse response, about
 * 2 / (pi zeta) <= 64 at zeta >= 0.01) keeps |F| and |F'| / omega_n below 1e8 N. */
#define LOAD_STATE_BOUND 1e9

enum { PROFILE_CONSTANT = 0, PROFILE_SINE = 1, PROFILE_TRAPEZOID = 2, PROFILE_TABLE = 3 };

static const int VR_TABLE_T[HL_TABLE] = {VR_table_t_1, VR_table_t_2, VR_table_t_3, VR_table_t_4,
                                         VR_table_t_5, VR_table_t_6, VR_table_t_7, VR_table_t_8};
static const int VR_TABLE_F[HL_TABLE] = {VR_table_f_1, VR_table_f_2, VR_table_f_3, VR_table_f_4,
                                         VR_table_f_5, VR_table_f_6, VR_table_f_7, VR_table_f_8};

/* sin(2 pi f t) with the phase reduced to one period first (long runs keep their precision) */
static double sin_cycles(double f, double t) {
    double c = f * t;
    return sin(TWO_PI * (c - floor(c)));
}

static double trapezoid_period(const double *r) {
    return r[VR_t_ramp_up] + r[VR_t_dwell_high] + r[VR_t_ramp_down] + r[VR_t_dwell_low];
}

/* load_low at t = 0, ramp up, dwell high, ramp down, dwell low; periodic */
static double trapezoid(const double *r, double t) {
    double up = r[VR_t_ramp_up], high = r[VR_t_dwell_high], down = r[VR_t_ramp_down];
    double lo = r[VR_load_low], hi = r[VR_load_high];
    double period = trapezoid_period(r);
    double tau = t - period * floor(t / period);
    if (tau < 0.0) tau = 0.0; /* rounding at the period boundary */
    if (tau < up) return lo + (hi - lo) * (tau / up);
    tau -= up;
    if (tau < high) return hi;
    tau -= high;
    if (tau < down) return hi + (lo - hi) * (tau / down);
    return lo;
}

/* linear interpolation through the first table_n points, held before the first and after the last */
static double table(const ModelInstance *comp, double t) {
    const double *r = comp->v.r;
    int n = comp->v.i[VR_table_n], k;
    if (t <= r[VR_TABLE_T[0]]) return r[VR_TABLE_F[0]];
    for (k = 1; k < n; k++) {
        double t1 = r[VR_TABLE_T[k]];
        if (t < t1) {
            double t0 = r[VR_TABLE_T[k - 1]], f0 = r[VR_TABLE_F[k - 1]], f1 = r[VR_TABLE_F[k]];
            return f0 + (f1 - f0) * ((t - t0) / (t1 - t0));
        }
    }
    return r[VR_TABLE_F[n - 1]];
}

static double profile(const ModelInstance *comp, double t) {
    const double *r = comp->v.r;
    switch (comp->v.i[VR_profile]) {
        case PROFILE_SINE: return r[VR_load_mean] + r[VR_load_amplitude] * sin_cycles(r[VR_load_frequency], t);
        case PROFILE_TRAPEZOID: return trapezoid(r, t);
        case PROFILE_TABLE: return table(comp, t);
        default: return r[VR_load_mean];
    }
}

/* the load command at time t with the current inputs */
static double command(const ModelInstance *comp, double t) {
    return comp->v.r[VR_station_on] * (profile(comp, t) + comp->v.r[VR_load_offset]);
}

/* ------------------------------------------------------------------ model contract */

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    const double *r = comp->v.r;
    int p = comp->v.i[VR_profile], n = comp->v.i[VR_table_n], k;
    /* the XML ranges guard these for a host that honours them; the model never relies on it */
    if (p < PROFILE_CONSTANT || p > PROFILE_TABLE) {
        snprintf(msg, msg_size, "profile = %d: must be 0 (constant), 1 (sine), 2 (trapezoid) or 3 (table)", p);
        return -1;
    }
    if (n < 2 || n > HL_TABLE) {
        snprintf(msg, msg_size, "table_n = %d: must be 2..%d", n, HL_TABLE);
        return -1;
    }
    /* only the active profile's data must be consistent */
    if (p == PROFILE_TRAPEZOID && !(trapezoid_period(r) > 0.0)) {
        snprintf(msg, msg_size,
                 "trapezoid period t_ramp_up + t_dwell_high + t_ramp_down + t_dwell_low = %g s: at least one "
                 "duration must be positive",
                 trapezoid_period(r));
        return -1;
    }
    if (p == PROFILE_TABLE) {
        for (k = 1; k < n; k++) {
            if (!(r[VR_TABLE_T[k]] > r[VR_TABLE_T[k - 1]])) {
                snprintf(msg, msg_size, "table times must increase strictly: table_t_%d = %g s is not after table_t_%d = %g s",
                         k + 1, r[VR_TABLE_T[k]], k, r[VR_TABLE_T[k - 1]]);
                return -1;
            }
        }
    }
    return 0;
}

/* phi, gamma for step h from one exponential of the augmented system [A B; 0 0] h */
static fmi2Status make_step_matrices(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    double wn = TWO_PI * comp->v.r[VR_servo_frequency], zeta = comp->v.r[VR_servo_damping];
    double aug[9], e[9], work[27];
    memset(aug, 0, sizeof aug);
    aug[0 * 3 + 1] = wn * h;
    aug[1 * 3 + 0] = -wn * h;
    aug[1 * 3 + 1] = -2.0 * zeta * wn * h;
    aug[1 * 3 + 2] = wn * h;
    if (la_expm(3, aug, e, work) != 0) {
        log_error(comp, "servo matrix is not finite: check servo_frequency and servo_damping");
        return fmi2Error;
    }
    m->phi[0] = e[0];
    m->phi[1] = e[1];
    m->phi[2] = e[3];
    m->phi[3] = e[4];
    m->gamma[0] = e[2];
    m->gamma[1] = e[5];
    m->step_h = h;
    return fmi2OK;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    /* unloaded cylinder at rest, or already in steady state at the command */
    m->load = comp->v.b[VR_start_at_command] ? command(comp, model_time(comp)) : 0.0;
    m->rate_scaled = 0.0;
    return make_step_matrices(comp, comp->v.r[VR_solver_step]);
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    double u, f, w;
    if (h != m->step_h && make_step_matrices(comp, h) != fmi2OK) return fmi2Error;
    u = command(comp, model_time(comp)); /* at the start of the step, held over it */
    f = m->phi[0] * m->load + m->phi[1] * m->rate_scaled + m->gamma[0] * u;
    w = m->phi[2] * m->load + m->phi[3] * m->rate_scaled + m->gamma[1] * u;
    m->load = f;
    m->rate_scaled = w;
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    const ModelState *m = &comp->v.m;
    double *r = comp->v.r;
    double t = model_time(comp);
    double ripple = r[VR_ripple_fraction] * m->load * sin_cycles(r[VR_ripple_frequency], t);
    double load = m->load + ripple;
    r[VR_load_command] = command(comp, t);
    r[VR_load_ripple] = ripple;
    r[VR_radial_load] = load;
    r[VR_pressure] = load / r[VR_piston_area];
    r[VR_q_station] = r[VR_station_on] * (r[VR_q_idle] + r[VR_k_heat_load] * fabs(load));
}

/* A state handed back: the servo states finite and bounded, the step matrices those of the
 * parameters (table_n, profile and the table's order are model_check's). */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    ModelInstance fresh = *comp;
    if (state_bad_real(c, "servo state load", m->load, -LOAD_STATE_BOUND, LOAD_STATE_BOUND) ||
        state_bad_real(c, "servo state rate_scaled", m->rate_scaled, -LOAD_STATE_BOUND, LOAD_STATE_BOUND))
        return -1;
    if (m->step_h != comp->v.r[VR_solver_step]) {
        state_fail(c, "step matrices made for %.17g s, not for solver_step = %.17g s", m->step_h, comp->v.r[VR_solver_step]);
        return -1;
    }
    if (make_step_matrices(&fresh, m->step_h) != fmi2OK) {
        state_fail(c, "the servo's step matrices cannot be computed from the parameters");
        return -1;
    }
    if (state_bad_match(c, "phi", m->phi, fresh.v.m.phi, 4) || state_bad_match(c, "gamma", m->gamma, fresh.v.m.gamma, 2))
        return -1;
    return 0;
}
