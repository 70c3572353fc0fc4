/*
 * SensorsDAQ -- the virtual instruments of the bearing tester (equations in readme.md).
 *
 * Every internal step of `solver_step` seconds is one DAQ sample period. Per step, with the
 * inputs held constant over the step (zero-order hold):
 *
 *   temperature channel i:  x_i += a_T (T_i - x_i),        a_T = 1 - exp(-h / temp_tau)
 *                           y_i  = Q(x_i + sigma_T n_i, temp_resolution)
 *   displacement probe:     x_p += a_p (z - x_p),          a_p = 1 - exp(-2 pi f_c h)
 *                           x    = x_p + bow(x_p)          (linearity error)
 *                           r0   = x + k_d dT_b + s_d dT_b x,   dT_b = T_body - T_body(0)
 *                           y_p  = clip(Q(r0 + sigma_p n_p + s, probe_resolution), range)
 *                           in_range = [range_min <= r0 <= range_max]
 *   interference spike s:   while none is on, one starts with probability 1 - exp(-spike_rate h);
 *                           it keeps a random sign and an Exp(spike_size) magnitude for
 *                           max(1, round(spike_duration / h)) samples; s = 0 otherwise
 *   load cell:              y_F = Q(F + sigma_F n_F, load_resolution)
 *   torque sensor:          y_M = Q(M + sigma_M n_M, torque_resolution)
 *   angle encoder:          y_a = Q(angle, encoder_resolution)
 *   vibration pickup:       y_v = v + sigma_v n_v
 *   probe body thermometer: like a temperature channel, on T_body (its noise from a third stream)
 *
 * The exact discretisation of the first-order lags is stable for any step. The noise n is
 * drawn once per channel per step, always in the same order, from two generators
 * (fmus/common/rng.c) whose states live in ModelState: the first (seed) feeds the temperatures
 * and the probe exactly as before the load/torque/angle/vibration channels and the spikes were
 * added; the second (seed ^ SD_STREAM2_KEY) feeds those, with a fixed number of draws per step;
 * the third (seed ^ SD_STREAM3_KEY) the probe body's thermometer, added after both. So the old outputs stay bit-identical whenever no spike is on, and a parameter of one
 * channel never changes another channel's noise. FMU get/set/serialize reproduce both streams bit
 * for bit. The outputs are the last sample: they depend on the states only (no direct
 * feedthrough), so setting an input between steps changes nothing until the next doStep.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "rng.h"

#define TWO_PI 6.283185307179586476925286766559
/* the largest -ln(u) of a uniform u >= 2^-53: an Exp(1) draw never exceeds 53 ln 2 = 36.74 */
#define EXP_DRAW_MAX 36.8

/* channel order used by every table below: the paper's eight measuring points */
static const int VR_TRUE[SD_TEMPS] = {VR_t_bearing_block, VR_t_heel_block, VR_t_bearing, VR_t_t_plate,
                                      VR_t_base, VR_t_long_pole, VR_t_detecting_frame, VR_t_room};
static const int VR_MEAS[SD_TEMPS] = {VR_t_bearing_block_meas, VR_t_heel_block_meas, VR_t_bearing_meas,
                                      VR_t_t_plate_meas, VR_t_base_meas, VR_t_long_pole_meas,
                                      VR_t_detecting_frame_meas, VR_t_room_meas};

/* ------------------------------------------------------------------ helpers */

/* Rounds to the resolution q. A resolution so fine that x / q leaves the range where doubles
 * hold whole numbers exactly (2^52) changes nothing and could overflow: x is returned. */
static double quantize(double x, double q) {
    double n;
    if (!(q > 0.0)) return x;
    n = x / q;
    return fabs(n) < 4503599627370496.0 ? q * round(n) : x;
}

static void make_gains(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    double n_d = round(comp->v.r[VR_spike_duration] / h);
    /* -expm1(-x) = 1 - exp(-x) without cancellation for small h/tau */
    m->a_temp = -expm1(-h / comp->v.r[VR_temp_tau]);
    m->a_probe = -expm1(-TWO_PI * comp->v.r[VR_probe_bandwidth] * h);
    /* P(at least one arrival of a Poisson process of rate lambda in h); exactly 0 for lambda = 0 */
    m->spike_p = -expm1(-comp->v.r[VR_spike_rate] * h);
    /* bounded by the parameter ranges: spike_duration / solver_step <= 60 / 1e-4 */
    m->spike_steps = n_d < 1.0 ? 1 : (int)n_d;
    m->step_h = h;
}

/* Advance the interference process by one step. Three uniforms are drawn every step, whatever
 * the parameters and whether or not a spike is on, so the draws that follow never shift. */
static void update_spike(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    double u_start = rng_uniform(&m->rng2);
    double u_size = rng_uniform(&m->rng2); /* in (0, 1]: -log is finite */
    double u_sign = rng_uniform(&m->rng2);
    if (m->spike_left > 0) m->spike_left--; /* the previous sample used one */
    if (m->spike_left == 0 && u_start <= m->spike_p) {
        double size = -comp->v.r[VR_spike_size] * log(u_size); /* exponential, mean spike_size */
        m->spike_value = u_sign <= 0.5 ? size : -size;
        m->spike_left = m->spike_steps;
    }
}

/* What a sample taken now draws from: the live streams, filter states and inputs. */
static void sample_source(const ModelInstance *comp, SampleSource *src) {
    const ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    src->rng = m->rng;
    src->rng2 = m->rng2;
    src->rng3 = m->rng3;
    memcpy(src->temp_lag, m->temp_lag, sizeof src->temp_lag);
    src->probe_filt = m->probe_filt;
    src->body_lag = m->body_lag;
    src->spike_value = m->spike_value;
    src->spike_left = m->spike_left;
    src->t_probe_body = r[VR_t_probe_body];
    src->load_true = r[VR_load_true];
    src->torque_true = r[VR_torque_true];
    src->vibration_true = r[VR_vibration_true];
    src->angle_true = r[VR_angle_true];
}

/* One DAQ sample from `src` (filter states, interference, inputs, and the streams it draws
 * from, which it advances): draws one noise value per channel, always in the same order and
 * even when a noise std is 0, so the streams do not depend on it. The parameters it reads are
 * fixed after initialization. */
static void take_sample(ModelInstance *comp, SampleSource *src) {
    ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    double sigma_t = r[VR_temp_noise], q_t = r[VR_temp_resolution];
    double lo = r[VR_probe_range_min], hi = r[VR_probe_range_max];
    double r0, x, y, u, d_body;
    int i;
    /* first stream: the temperatures, then the probe (the order of the first version) */
    for (i = 0; i < SD_TEMPS; i++) m->temp_sample[i] = quantize(src->temp_lag[i] + sigma_t * rng_gauss(&src->rng), q_t);
    /* the probe's bow-shaped linearity error, zero at both ends of its range, then its zero
     * drift and its span drift (the gain acts on the indicated position; a zero span drift adds
     * an exact 0.0, so the reading keeps its bits) */
    u = (src->probe_filt - lo) / (hi - lo);
    x = src->probe_filt + r[VR_probe_nonlinearity] * (hi - lo) * 4.0 * u * (1.0 - u);
    d_body = src->t_probe_body - m->t_probe_body0;
    r0 = x + r[VR_probe_zero_drift] * d_body;
    if (r[VR_probe_span_drift] != 0.0) r0 += r[VR_probe_span_drift] * d_body * x;
    x = r0 + r[VR_probe_noise] * rng_gauss(&src->rng);
    /* the spike after filtering and zero drift, before quantization and clipping; added only
     * while one is on, so without a spike x keeps its bits (even a -0.0) */
    if (src->spike_left > 0) x += src->spike_value;
    y = quantize(x, r[VR_probe_resolution]);
    m->probe_sample = y < lo ? lo : (y > hi ? hi : y);
    m->probe_in_range = (r0 >= lo && r0 <= hi) ? 1.0 : 0.0;
    m->spike_sample = src->spike_left > 0 ? 1.0 : 0.0;
    /* second stream: load, torque, vibration */
    m->load_sample = quantize(src->load_true + r[VR_load_noise] * rng_gauss(&src->rng2), r[VR_load_resolution]);
    m->torque_sample = quantize(src->torque_true + r[VR_torque_noise] * rng_gauss(&src->rng2), r[VR_torque_resolution]);
    m->vibration_sample = src->vibration_true + r[VR_vibration_noise] * rng_gauss(&src->rng2);
    m->angle_sample = quantize(src->angle_true, r[VR_encoder_resolution]); /* no noise */
    /* third stream: the probe body's thermometer */
    m->body_sample = quantize(src->body_lag + sigma_t * rng_gauss(&src->rng3), q_t);
}

/* A sample taken now, drawing from the live streams. */
static void take_sample_now(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    SampleSource src;
    sample_source(comp, &src);
    take_sample(comp, &src);
    m->rng = src.rng;
    m->rng2 = src.rng2;
    m->rng3 = src.rng3;
}

/* What take_sample draws, without the sample: a sample before the last of a communication
 * step is overwritten before anyone reads it (and the last is taken from a copy of the
 * streams), so only its random draws matter (they keep the
 * streams, and with them every later sample, bit-identical to drawing it: doStep(2h) still
 * equals two doStep(h)). The filters and the interference process run on every step. */
static void skip_sample(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    /* the first and third streams draw nothing else on the live state: their skips are owed,
     * and advanced over in one jump when a sample is read (model_outputs); the second's are
     * made now, its spike draws coming between them */
    rng_owe_gauss(&m->rng, SD_TEMPS + 1); /* the temperatures, the probe */
    rng_skip_gauss(&m->rng2, 3);          /* load, torque, vibration */
    rng_owe_gauss(&m->rng3, 1);           /* the probe body's thermometer */
}

/* ------------------------------------------------------------------ model contract */

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    const double *r = comp->v.r;
    if (!(r[VR_probe_range_min] < r[VR_probe_range_max])) {
        snprintf(msg, msg_size, "probe_range_min = %g m must be below probe_range_max = %g m", r[VR_probe_range_min],
                 r[VR_probe_range_max]);
        return -1;
    }
    return 0;
}

fmi2Status model_initialize(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    uint64_t seed = (uint64_t)(uint32_t)comp->v.i[VR_seed];
    int i;
    rng_seed(&m->rng, seed);
    rng_seed(&m->rng2, seed ^ SD_STREAM2_KEY);
    rng_seed(&m->rng3, seed ^ SD_STREAM3_KEY);
    make_gains(comp, comp->v.r[VR_solver_step]);
    /* every sensor starts in equilibrium with what it measures, and no spike is on */
    for (i = 0; i < SD_TEMPS; i++) m->temp_lag[i] = comp->v.r[VR_TRUE[i]];
    m->probe_filt = comp->v.r[VR_probe_true];
    m->t_probe_body0 = comp->v.r[VR_t_probe_body];
    m->body_lag = comp->v.r[VR_t_probe_body];
    m->spike_left = 0;
    m->spike_value = 0.0;
    comp->deferred.pending = 0;
    take_sample_now(comp); /* the sample at the start time */
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    int i;
    if (h != m->step_h) make_gains(comp, h);
    for (i = 0; i < SD_TEMPS; i++) m->temp_lag[i] += m->a_temp * (comp->v.r[VR_TRUE[i]] - m->temp_lag[i]);
    m->probe_filt += m->a_probe * (comp->v.r[VR_probe_true] - m->probe_filt);
    m->body_lag += m->a_temp * (comp->v.r[VR_t_probe_body] - m->body_lag);
    update_spike(comp);
    /* the last sample of the communication step is what the outputs show: kept to be taken when
     * they are read (model_outputs), its draws skipped on the live streams as an earlier
     * sample's are; taking it from the kept copy draws the same numbers */
    if (comp->last_substep) {
        sample_source(comp, &comp->deferred.source);
        comp->deferred.pending = 1;
    }
    skip_sample(comp);
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    double *r = comp->v.r;
    int i;
    if (comp->deferred.pending) { /* the step's last sample, taken now */
        SampleSource *src = &comp->deferred.source;
        /* the live streams are the kept copies and the skips owed since: the copies advanced
         * over what they owe are the live streams' state too, which then owe only those skips
         * (so the stretch a stream owes between two reads stays as long as the reads' spacing) */
        const int64_t since = m->rng.owed - src->rng.owed, since3 = m->rng3.owed - src->rng3.owed;
        comp->deferred.pending = 0;
        rng_settle(&src->rng);
        rng_settle(&src->rng3);
        m->rng = src->rng;
        m->rng.owed = since;
        m->rng3 = src->rng3;
        m->rng3.owed = since3;
        take_sample(comp, src);
    }
    for (i = 0; i < SD_TEMPS; i++) r[VR_MEAS[i]] = m->temp_sample[i];
    r[VR_probe_meas] = m->probe_sample;
    r[VR_probe_in_range] = m->probe_in_range;
    r[VR_load_meas] = m->load_sample;
    r[VR_torque_meas] = m->torque_sample;
    r[VR_angle_meas] = m->angle_sample;
    r[VR_vibration_meas] = m->vibration_sample;
    r[VR_spike] = m->spike_sample;
    r[VR_t_probe_body_meas] = m->body_sample;
}

/* The generators and the gains of a state handed back: both streams valid, the gains and the
 * spike length those of the parameters. */
static int bad_setup(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    ModelInstance fresh = *comp;
    const double got[3] = {m->a_temp, m->a_probe, m->spike_p};
    double want[3];
    const char *why = rng_problem(&m->rng);
    if (why || (why = rng_problem(&m->rng2)) || (why = rng_problem(&m->rng3))) return state_fail(c, "noise generator: %s", why);
    if (m->step_h != comp->v.r[VR_solver_step])
        return state_fail(c, "gains made for %.17g s, not for solver_step = %.17g s", m->step_h, comp->v.r[VR_solver_step]);
    make_gains(&fresh, m->step_h);
    if (m->spike_steps != fresh.v.m.spike_steps)
        return state_fail(c, "spike_steps = %d is not what spike_duration gives (%d)", m->spike_steps, fresh.v.m.spike_steps);
    want[0] = fresh.v.m.a_temp;
    want[1] = fresh.v.m.a_probe;
    want[2] = fresh.v.m.spike_p;
    return state_bad_match(c, "gain (a_temp, a_probe, spike_p)", got, want, 3);
}

/* A state handed back: generators and gains (bad_setup), every lag within the range of the
 * input it follows, the spike process consistent (remaining samples within its length, a size
 * an exponential draw can have), the last sample finite and the probe's clipped to its range. */
int model_check_state(const ModelInstance *comp, StateCheck *c) {
    const ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    const double spike_max = r[VR_spike_size] * EXP_DRAW_MAX;
    const double other_samples[4] = {m->load_sample, m->torque_sample, m->angle_sample, m->vibration_sample};
    int i;
    if (bad_setup(comp, c)) return -1;
    for (i = 0; i < SD_TEMPS; i++)
        if (state_bad_follower(c, "temperature sensor lag", m->temp_lag[i], VR_TRUE[i])) return -1;
    if (state_bad_follower(c, "probe filter", m->probe_filt, VR_probe_true) ||
        state_bad_follower(c, "probe body reference", m->t_probe_body0, VR_t_probe_body) ||
        state_bad_follower(c, "probe body thermometer lag", m->body_lag, VR_t_probe_body) ||
        state_bad_real(c, "body_sample", m->body_sample, -HUGE_VAL, HUGE_VAL) ||
        state_bad_int(c, "spike_left", m->spike_left, 0, m->spike_steps) ||
        state_bad_real(c, "spike_value", m->spike_value, -spike_max, spike_max) ||
        state_bad_real(c, "spike_sample", m->spike_sample, m->spike_left > 0, m->spike_left > 0) ||
        state_bad_reals(c, "temperature sample", m->temp_sample, SD_TEMPS, -HUGE_VAL, HUGE_VAL) ||
        state_bad_real(c, "probe_sample", m->probe_sample, r[VR_probe_range_min], r[VR_probe_range_max]) ||
        state_bad_real(c, "probe_in_range", m->probe_in_range, 0.0, 1.0) ||
        (m->probe_in_range != 0.0 && m->probe_in_range != 1.0 && state_fail(c, "probe_in_range is neither 0 nor 1")) ||
        state_bad_reals(c, "load/torque/angle/vibration sample", other_samples, 4, -HUGE_VAL, HUGE_VAL))
        return -1;
    return 0;
}
