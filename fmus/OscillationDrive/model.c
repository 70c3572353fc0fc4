/*
 * OscillationDrive -- the swing of the testing spindle and the friction in the bearing
 * (equations in readme.md).
 *
 * The motion is a function of the phase theta (in cycles), not integrated:
 *
 *   theta = f * (n_on * h)            n_on = internal steps taken with the drive on
 *   angle = A s(x),  omega = A f s'(x),   x = theta - floor(theta)
 *   s(x)  = sin(2 pi x)  (sine)  or  the unit triangle 4x | 2 - 4x | 4x - 4  (triangular)
 *
 * While the drive runs, theta = f (t - t0) exactly (the same integer clock as the wrapper's
 * time); when drive_on is 0 the counter stops, so the angle is held and a restart continues
 * from the same phase without a jump.
 *
 * Per internal step (inputs held: zero-order hold) the swept angle is the exact total
 * variation of the angle over the step, A [V(theta1) - V(theta0)], with V the cumulative
 * variation of s (4 per cycle, monotone pieces split at the reversals x = 1/4, 3/4). So
 *
 *   sliding distance += (d_k/2) A dV,     friction energy += mu |F| (d_k/2) A dV
 *
 * are exact integrals of |omega| d_k/2 and mu |F| |omega| d_k/2 over the step, for any step.
 * The friction heat averaged over blocks of q_avg_window (aligned to the start time, on the
 * internal step grid) is therefore independent of how the master splits its steps.
 *
 * Vibration (per internal step): after each reversal a damped ringing
 * sign * a_v exp(-t/tau_v) sin(2 pi f_v t), plus (drive on only) a seeded Gaussian sample of
 * std sigma_v truncated at 4 std. One normal is drawn every step, on or off, so the stream
 * depends only on the step count.
 */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "rng.h"

#define TWO_PI 6.283185307179586476925286766559
#define NOISE_CLIP 4.0      /* vibration noise truncated at this many std */
#define CYCLE_SNAP 1e-9     /* cycles: a cycle counts as complete within this many cycles */

enum { WAVE_SINE = 0, WAVE_TRIANGLE = 1 };

/* ------------------------------------------------------------------ kinematics */

static int drive_is_on(const ModelInstance *comp) { return comp->v.r[VR_drive_on] >= 0.5; }

/* phase in cycles after n steps with the drive on: from the integer counter, never summed */
static double phase_of(const ModelInstance *comp, int64_t n) {
    return comp->v.r[VR_frequency] * ((double)n * comp->v.r[VR_solver_step]);
}

/* unit shape s(x) and its derivative ds/dx for x in [0, 1) */
static double shape(int wave, double x) {
    if (wave == WAVE_TRIANGLE) return x < 0.25 ? 4.0 * x : (x < 0.75 ? 2.0 - 4.0 * x : 4.0 * x - 4.0);
    return sin(TWO_PI * x);
}

static double shape_slope(int wave, double x) {
    /* at a corner of the triangle the slope of the piece starting there */
    if (wave == WAVE_TRIANGLE) return (x < 0.25 || x >= 0.75) ? 4.0 : -4.0;
    return TWO_PI * cos(TWO_PI * x);
}

/* cumulative variation of s from 0 to x in [0, 1): 0..4, monotone; pieces split at the
 * reversals so the sum |ds| is exact (1 at x = 1/4, 3 at x = 3/4) */
static double variation_in_cycle(int wave, double x) {
    double s;
    if (wave == WAVE_TRIANGLE) return 4.0 * x; /* constant speed */
    s = sin(TWO_PI * x);
    if (x < 0.25) return s;
    if (x < 0.75) return 2.0 - s;
    return 4.0 + s;
}

/* total variation of s between phases th0 <= th1 (in units of the amplitude) */
static double variation(int wave, double th0, double th1) {
    double k0 = floor(th0), k1 = floor(th1);
    double dv = 4.0 * (k1 - k0) + variation_in_cycle(wave, th1 - k1) - variation_in_cycle(wave, th0 - k0);
    return dv > 0.0 ? dv : 0.0; /* never negative from rounding at a flat top */
}

/* ------------------------------------------------------------------ friction */

static double friction_coefficient(ModelInstance *comp) {
    const double *r = comp->v.r;
    double p = fabs(r[VR_radial_load]) / (r[VR_d_k] * r[VR_liner_width]);
    double n = r[VR_mu_pressure_exponent];
    double f_p = 1.0, f_t, mu, a, b;
    Memo *memo = comp->memo;
    if (n != 0.0 && p > 0.0) {
        a = p / r[VR_p_ref];
        b = -n;
        f_p = memo_hit(&memo[MEMO_PRESSURE], a, b) ? memo[MEMO_PRESSURE].value
                                                  : memo_keep(&memo[MEMO_PRESSURE], a, b, pow(a, b));
    } else if (n != 0.0) {
        f_p = HUGE_VAL; /* no load: clipped to mu_max */
    }
    a = -r[VR_mu_temp_coeff] * (r[VR_t_bearing] - r[VR_t_ref]);
    f_t = memo_call(&memo[MEMO_TEMPERATURE], exp, a);
    mu = r[VR_mu_ref] > 0.0 ? r[VR_mu_ref] * f_p * f_t : 0.0;
    if (mu < r[VR_mu_min]) mu = r[VR_mu_min];
    if (mu > r[VR_mu_max]) mu = r[VR_mu_max];
    return mu;
}

/* ------------------------------------------------------------------ model contract */

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    const double *r = comp->v.r;
    double h = r[VR_solver_step], w = r[VR_q_avg_window];
    double n = floor(w / h + 0.5);
    if (!(r[VR_mu_min] <= r[VR_mu_max])) {
        snprintf(msg, msg_size, "mu_min = %g must not exceed mu_max = %g", r[VR_mu_min], r[VR_mu_max]);
        return -1;
    }
    if (n < 1.0 || fabs(n * h - w) > 1e-9 * w) {
        snprintf(msg, msg_size, "q_avg_window = %.12g s must be a positive multiple of solver_step = %.12g s", w, h);
        return -1;
    }
    if (comp->v.i[VR_waveform] != WAVE_SINE && comp->v.i[VR_waveform] != WAVE_TRIANGLE) {
        snprintf(msg, msg_size, "waveform = %d must be 0 (sine) or 1 (triangular)", comp->v.i[VR_waveform]);
        return -1;
    }
    return 0;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    memset(m, 0, sizeof *m);
    rng_seed(&m->rng, (uint64_t)(uint32_t)comp->v.i[VR_seed]);
    m->n_window = (int64_t)llround(r[VR_q_avg_window] / r[VR_solver_step]);
    m->rev_sign = 1.0;
    /* n_on = 0: angle 0, moving towards +amplitude; no energy yet, q_friction_avg = 0 until
     * the first block completes; no reversal yet, so no ringing and vibration_z = 0 */
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    const int wave = comp->v.i[VR_waveform];
    const double radius = 0.5 * r[VR_d_k];
    double swept = 0.0, de, noise, ring = 0.0;
    int on = drive_is_on(comp), reversed = 0;

    if (on) {
        double th0 = phase_of(comp, m->n_on), th1 = phase_of(comp, m->n_on + 1);
        /* reversals at theta = 1/4 + k/2; N(theta) = reversals in (0, theta] */
        double n0 = floor(2.0 * th0 + 0.5), n1 = floor(2.0 * th1 + 0.5);
        swept = r[VR_amplitude] * variation(wave, th0, th1);
        if (n1 > n0) {
            double th_rev = 0.5 * (n1 - 0.5); /* the last reversal inside this step */
            m->t_since_rev = (th1 - th_rev) / r[VR_frequency];
            m->rev_sign = fmod(n1, 2.0) == 1.0 ? -1.0 : 1.0; /* odd: at +amplitude, now moving down */
            m->has_reversal = 1;
            reversed = 1;
        }
        m->n_on++;
    }
    if (!reversed) m->t_since_rev += h;

    /* friction over the step with mu and F held: exact integrals of |omega| */
    de = friction_coefficient(comp) * fabs(r[VR_radial_load]) * radius * swept;
    m->distance += radius * swept;
    m->energy += de;
    m->e_block += de;
    if (++m->n_block >= m->n_window) {
        m->q_avg = m->e_block / ((double)m->n_window * h);
        m->e_block = 0.0;
        m->n_block = 0;
    }

    /* vibration sample at the end of the step */
    noise = rng_gauss(&m->rng);
    if (noise > NOISE_CLIP) noise = NOISE_CLIP;
    if (noise < -NOISE_CLIP) noise = -NOISE_CLIP;
    if (m->has_reversal) {
        double t = m->t_since_rev;
        ring = m->rev_sign * r[VR_vibration_amplitude] * exp(-t / r[VR_vibration_decay]) *
               sin(TWO_PI * r[VR_vibration_frequency] * t);
    }
    m->z_vib = ring + (on ? r[VR_vibration_noise] * noise : 0.0);
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    const ModelState *m = &comp->v.m;
    double *r = comp->v.r;
    const int wave = comp->v.i[VR_waveform];
    const double radius = 0.5 * r[VR_d_k];
    const double force = fabs(r[VR_radial_load]);
    double theta = phase_of(comp, m->n_on);
    double x = theta - floor(theta);
    double omega = drive_is_on(comp) ? r[VR_amplitude] * r[VR_frequency] * shape_slope(wave, x) : 0.0;
    double mu = friction_coefficient(comp);
    double speed = fabs(omega) * radius;

    r[VR_angle] = r[VR_amplitude] * shape(wave, x);
    r[VR_angular_velocity] = omega;
    r[VR_sliding_speed] = speed;
    r[VR_contact_pressure] = force / (r[VR_d_k] * r[VR_liner_width]);
    r[VR_friction_coefficient] = mu;
    r[VR_friction_torque] = omega > 0.0 ? -mu * force * radius : (omega < 0.0 ? mu * force * radius : 0.0);
    r[VR_q_friction] = mu * force * speed;
    r[VR_q_friction_avg] = m->q_avg;
    r[VR_friction_energy] = m->energy;
    r[VR_vibration_z] = m->z_vib;
    r[VR_sliding_distance] = m->distance;
    r[VR_cycles] = floor(theta + CYCLE_SNAP);
}

/* The counters of a state handed back: the heat-averaging block as initialization made it
 * (n_window = q_avg_window / solver_step) and aligned to the start (n_block = steps mod
 * n_window), and no more steps with the drive on than steps. */
static int bad_counters(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    int64_t steps = comp->v.steps_taken;
    int64_t n_window = (int64_t)llround(comp->v.r[VR_q_avg_window] / comp->v.r[VR_solver_step]);
    if (m->n_window != n_window)
        return state_fail(c, "n_window = %lld is not q_avg_window / solver_step = %lld", (long long)m->n_window,
                          (long long)n_window);
    if (m->n_block != steps % n_window)
        return state_fail(c, "n_block = %lld is not the %lld steps taken modulo n_window = %lld", (long long)m->n_block,
                          (long long)steps, (long long)n_window);
    return state_bad_int(c, "n_on", m->n_on, 0, steps);
}

/* A state handed back: the generator valid, the counters consistent, every integral finite,
 * >= 0 and within what the phase and the ranges allow (the sliding distance at most 4 amplitudes
 * per cycle swept, the energy at most mu_max |F|max per metre), the swing's memory consistent and
 * the vibration sample within ringing plus clipped noise. */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    const double h = r[VR_solver_step], elapsed = (double)comp->v.steps_taken * h;
    const double f_max = fmax(fabs(real_var(VR_radial_load)->min), fabs(real_var(VR_radial_load)->max));
    /* the bounds are products of the parameters, with 1e-6 for rounding and DBL_MIN for an
     * underflow: a subnormal amplitude (5e-324 rad) gives a bound of 0 but a distance of 5e-324 m */
    const double d_max = 0.5 * r[VR_d_k] * r[VR_amplitude] * 4.0 * (phase_of(comp, m->n_on) + 1.0) * (1.0 + 1e-6) + DBL_MIN;
    const double z_max = (r[VR_vibration_amplitude] + NOISE_CLIP * r[VR_vibration_noise]) * (1.0 + 1e-9);
    const char *why = rng_problem(&m->rng);
    if (why) {
        state_fail(c, "noise generator: %s", why);
        return -1;
    }
    if (bad_counters(comp, c) || state_bad_real(c, "distance", m->distance, 0.0, d_max) ||
        state_bad_real(c, "energy", m->energy, 0.0, r[VR_mu_max] * f_max * m->distance * (1.0 + 1e-6) + DBL_MIN) ||
        state_bad_real(c, "e_block", m->e_block, 0.0, m->energy * (1.0 + 1e-6) + DBL_MIN) ||
        state_bad_real(c, "q_avg", m->q_avg, 0.0, HUGE_VAL) ||
        state_bad_real(c, "t_since_rev", m->t_since_rev, -h, elapsed * (1.0 + 1e-6) + h) ||
        state_bad_real(c, "z_vib", m->z_vib, -z_max, z_max))
        return -1;
    if ((m->has_reversal != 0 && m->has_reversal != 1) || (m->rev_sign != 1.0 && m->rev_sign != -1.0) ||
        (!m->has_reversal && m->rev_sign != 1.0)) {
        state_fail(c, "swing memory has_reversal = %d, rev_sign = %g is not one a swing leaves", m->has_reversal, m->rev_sign);
        return -1;
    }
    return 0;
}
