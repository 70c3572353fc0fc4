/*
 * SensorsDAQ -- the virtual instruments of the bearing tester (equations in readme.md).
 *
 * Every internal step of `solver_step` seconds is one DAQ sample period. Per step, with the
 * inputs held constant over the step (zero-order hold):
 *
 *   temperature channel i:  x_i += a_T (T_i - x_i),        a_T = 1 - exp(-h / temp_tau)
 *                           y_i  = Q(x_i + sigma_T n_i, temp_resolution)
 *   displacement probe:     x_p += a_p (z - x_p),          a_p = 1 - exp(-2 pi f_c h)
 *                           r0   = x_p + k_d (T_body - T_body(0))
 *                           y_p  = clip(Q(r0 + sigma_p n_p, probe_resolution), range)
 *                           in_range = [range_min <= r0 <= range_max]
 *
 * The exact discretisation of the first-order lags is stable for any step. The noise n is
 * drawn once per channel per step from the shared generator (fmus/common/rng.c) whose state
 * lives in ModelState, so FMU get/set/serialize reproduce the noise bit for bit. The outputs
 * are the last sample: they depend on the states only (no direct feedthrough), so setting an
 * input between steps changes nothing until the next doStep.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "model.h"
#include "rng.h"

#define TWO_PI 6.283185307179586476925286766559

/* channel order used by every table below: the paper's eight measuring points */
static const int VR_TRUE[SD_TEMPS] = {VR_t_bearing_block, VR_t_heel_block, VR_t_bearing, VR_t_t_plate,
                                      VR_t_base, VR_t_long_pole, VR_t_detecting_frame, VR_t_room};
static const int VR_MEAS[SD_TEMPS] = {VR_t_bearing_block_meas, VR_t_heel_block_meas, VR_t_bearing_meas,
                                      VR_t_t_plate_meas, VR_t_base_meas, VR_t_long_pole_meas,
                                      VR_t_detecting_frame_meas, VR_t_room_meas};

/* ------------------------------------------------------------------ helpers */

static double quantize(double x, double q) { return q > 0.0 ? q * round(x / q) : x; }

static void make_gains(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    /* -expm1(-x) = 1 - exp(-x) without cancellation for small h/tau */
    m->a_temp = -expm1(-h / comp->v.r[VR_temp_tau]);
    m->a_probe = -expm1(-TWO_PI * comp->v.r[VR_probe_bandwidth] * h);
    m->step_h = h;
}

/* One DAQ sample from the current filter states: draws one noise value per channel, always
 * in the same order and even when a noise std is 0, so the streams do not depend on it. */
static void take_sample(ModelInstance *comp) {
    ModelState *m = &comp->v.m;
    const double *r = comp->v.r;
    double sigma_t = r[VR_temp_noise], q_t = r[VR_temp_resolution];
    double lo = r[VR_probe_range_min], hi = r[VR_probe_range_max];
    double r0, y;
    int i;
    for (i = 0; i < SD_TEMPS; i++) m->temp_sample[i] = quantize(m->temp_lag[i] + sigma_t * rng_gauss(&m->rng), q_t);
    r0 = m->probe_filt + r[VR_probe_zero_drift] * (r[VR_t_probe_body] - m->t_probe_body0);
    y = quantize(r0 + r[VR_probe_noise] * rng_gauss(&m->rng), r[VR_probe_resolution]);
    m->probe_sample = y < lo ? lo : (y > hi ? hi : y);
    m->probe_in_range = (r0 >= lo && r0 <= hi) ? 1.0 : 0.0;
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
    int i;
    rng_seed(&m->rng, (uint64_t)(uint32_t)comp->v.i[VR_seed]);
    make_gains(comp, comp->v.r[VR_solver_step]);
    /* every sensor starts in equilibrium with what it measures */
    for (i = 0; i < SD_TEMPS; i++) m->temp_lag[i] = comp->v.r[VR_TRUE[i]];
    m->probe_filt = comp->v.r[VR_probe_true];
    m->t_probe_body0 = comp->v.r[VR_t_probe_body];
    take_sample(comp); /* the sample at the start time */
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    ModelState *m = &comp->v.m;
    int i;
    if (h != m->step_h) make_gains(comp, h);
    for (i = 0; i < SD_TEMPS; i++) m->temp_lag[i] += m->a_temp * (comp->v.r[VR_TRUE[i]] - m->temp_lag[i]);
    m->probe_filt += m->a_probe * (comp->v.r[VR_probe_true] - m->probe_filt);
    take_sample(comp);
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    const ModelState *m = &comp->v.m;
    int i;
    for (i = 0; i < SD_TEMPS; i++) comp->v.r[VR_MEAS[i]] = m->temp_sample[i];
    comp->v.r[VR_probe_meas] = m->probe_sample;
    comp->v.r[VR_probe_in_range] = m->probe_in_range;
}
