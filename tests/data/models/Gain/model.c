/* Gain (test-only): y = k u + w at every instant, so y follows its inputs at once when they are
 * set after a step (direct feedthrough, declared in modelDescription.xml's ModelStructure). */
#include "model.h"

int model_check(ModelInstance *comp, char *msg, size_t msg_size) {
    (void)comp;
    (void)msg;
    (void)msg_size;
    return 0;
}

fmi2Status model_initialize(ModelInstance *comp) {
    (void)comp;
    return fmi2OK;
}

fmi2Status model_step(ModelInstance *comp, double h) {
    (void)comp;
    (void)h;
    return fmi2OK;
}

void model_outputs(ModelInstance *comp) {
    double *r = comp->v.r;
    r[VR_y] = r[VR_k] * r[VR_u] + r[VR_w];
}

int model_check_state(const ModelInstance *comp, StateCheck *c) {
    (void)comp;
    (void)c;
    return 0;
}
