/* Lag (test-only): x' = (u - x) / T stepped exactly for u held over the internal step,
 * x(t + h) = u + (x(t) - u) exp(-h / T); the output is the state (no direct feedthrough). */
#include <math.h>

#include "model.h"

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    (void)comp;
    (void)msg;
    (void)msg_size;
    return 0;
}

fmi2Status model_initialize(ModelInstance *comp) {
    comp->v.m.x = comp->v.r[VR_x0];
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    const double u = comp->v.r[VR_u];
    comp->v.m.x = u + (comp->v.m.x - u) * exp(-h / comp->v.r[VR_T]);
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) { comp->v.r[VR_y] = comp->v.m.x; }

int model_check_state(const ModelInstance *comp, StateCheck *c) {
    return state_bad_real(c, "x", comp->v.m.x, -273.15, HUGE_VAL) ? -1 : 0;
}
