/* A first-order low-pass filter as an FMI 2.0 co-simulation FMU, written for the twin's tests
 * without the twin's FMU wrapper: y' = (u - y) / T, stepped exactly with the input held,
 * y(t + h) = u + (y(t) - u) exp(-h / T). Misuse (unknown value references, h <= 0, T <= 0)
 * returns fmi2Error; what it does not offer (FMU state, derivatives) returns fmi2Error too. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"

#define GUID "{3c1a8f5e-6b2d-4f0e-9a7c-1d2e3f405162}"
enum { VR_U = 1, VR_Y = 2, VR_T = 3 };

typedef struct {
    double u, y, T, time;
    fmi2CallbackFunctions cb;
    char name[64];
} Filter;

static void say(Filter *f, fmi2Status status, const char *message) {
    if (f && f->cb.logger) f->cb.logger(f->cb.componentEnvironment, f->name, status, "logError", "%s", message);
}

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n, const fmi2String cats[]) {
    (void)on; (void)n; (void)cats;
    return c ? fmi2OK : fmi2Error;
}

fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid, fmi2String resources,
                              const fmi2CallbackFunctions *cb, fmi2Boolean visible, fmi2Boolean logging) {
    (void)resources; (void)visible; (void)logging;
    if (type != fmi2CoSimulation || !guid || strcmp(guid, GUID) != 0) return NULL;
    Filter *f = calloc(1, sizeof(Filter));
    if (!f) return NULL;
    f->T = 1.0;
    if (cb) f->cb = *cb;
    strncpy(f->name, name ? name : "LowPass", sizeof(f->name) - 1);
    return f;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDefined, fmi2Real tol, fmi2Real start,
                               fmi2Boolean stopDefined, fmi2Real stop) {
    (void)tolDefined; (void)tol; (void)stopDefined; (void)stop;
    if (!c) return fmi2Error;
    ((Filter *)c)->time = start;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    Filter *f = c;
    if (!f) return fmi2Error;
    if (!(f->T > 0.0) || !isfinite(f->T)) {
        say(f, fmi2Error, "T must be a positive finite time constant");
        return fmi2Error;
    }
    return fmi2OK;
}
fmi2Status fmi2Terminate(fmi2Component c) { return c ? fmi2OK : fmi2Error; }
fmi2Status fmi2Reset(fmi2Component c) {
    Filter *f = c;
    if (!f) return fmi2Error;
    f->u = 0.0; f->y = 0.0; f->T = 1.0; f->time = 0.0;
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real value[]) {
    Filter *f = c;
    if (!f || (n && (!vr || !value))) return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        switch (vr[i]) {
            case VR_U: value[i] = f->u; break;
            case VR_Y: value[i] = f->y; break;
            case VR_T: value[i] = f->T; break;
            default: say(f, fmi2Error, "unknown value reference"); return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real value[]) {
    Filter *f = c;
    if (!f || (n && (!vr || !value))) return fmi2Error;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(value[i])) { say(f, fmi2Error, "not a finite number"); return fmi2Error; }
        switch (vr[i]) {
            case VR_U: f->u = value[i]; break;
            case VR_Y: f->y = value[i]; break; /* its start value (initial="exact") */
            case VR_T: f->T = value[i]; break;
            default: say(f, fmi2Error, "unknown value reference"); return fmi2Error;
        }
    }
    return fmi2OK;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSetPrior) {
    Filter *f = c;
    (void)noSetPrior;
    if (!f || !(h > 0.0) || !isfinite(h)) return fmi2Error;
    f->y = f->u + (f->y - f->u) * exp(-h / f->T);
    f->time = t + h;
    return fmi2OK;
}

/* The rest of the FMI 2.0 API: nothing of it is offered. */
#define NONE_OF(c) ((void)(c), fmi2Error)
fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Integer v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Boolean v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2String v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Boolean v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2String v[]) { (void)vr; (void)v; return (c && n == 0) ? fmi2OK : fmi2Error; }
fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return NONE_OF(c); }
fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate s) { (void)s; return NONE_OF(c); }
fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *s) { (void)s; return NONE_OF(c); }
fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate s, size_t *n) { (void)s; (void)n; return NONE_OF(c); }
fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate s, fmi2Byte b[], size_t n) { (void)s; (void)b; (void)n; return NONE_OF(c); }
fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n, fmi2FMUstate *s) { (void)b; (void)n; (void)s; return NONE_OF(c); }
fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[], size_t nu, const fmi2ValueReference z[], size_t nz, const fmi2Real dv[], fmi2Real dz[]) { (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return NONE_OF(c); }
fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], const fmi2Real v[]) { (void)vr; (void)n; (void)o; (void)v; return NONE_OF(c); }
fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Integer o[], fmi2Real v[]) { (void)vr; (void)n; (void)o; (void)v; return NONE_OF(c); }
fmi2Status fmi2CancelStep(fmi2Component c) { return NONE_OF(c); }
fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) { (void)k; (void)v; return NONE_OF(c); }
fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) { (void)k; (void)v; return NONE_OF(c); }
fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k, fmi2Integer *v) { (void)k; (void)v; return NONE_OF(c); }
fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k, fmi2Boolean *v) { (void)k; (void)v; return NONE_OF(c); }
fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k, fmi2String *v) { (void)k; (void)v; return NONE_OF(c); }
