/*
 * model.h -- the contract between the one FMI 2.0 co-simulation wrapper (fmi2_wrapper.c)
 * and a model (fmus/<Model>/model.c).
 *
 * The wrapper owns the FMI API: instance life cycle, the call-sequence state machine,
 * value access with range/NaN checks, the fixed-step loop of fmi2DoStep and FMU state
 * (get/set/serialize). A model only supplies its variables (generated from its
 * modelDescription.xml into model_vars.h) and its equations:
 *
 *   model_check       parameters consistent? (called at exitInitializationMode)
 *   model_initialize  precompute from parameters, set initial states and outputs
 *   model_step        advance the states by exactly one internal step
 *   model_outputs     recompute outputs from states and inputs (after set of inputs)
 *
 * All model data lives in ModelInstance.v (plain doubles/ints, no pointers), so an FMU
 * state is a byte copy of that struct and serialization is trivially portable between
 * instances of the same build.
 */
#ifndef TWIN_MODEL_H
#define TWIN_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "fmi2Functions.h"

/* Causality and variability as declared in modelDescription.xml. */
typedef enum { CAUS_PARAMETER, CAUS_CALCULATED_PARAMETER, CAUS_INPUT, CAUS_OUTPUT, CAUS_LOCAL, CAUS_INDEPENDENT } Causality;
typedef enum { VAR_CONSTANT, VAR_FIXED, VAR_TUNABLE, VAR_DISCRETE, VAR_CONTINUOUS } Variability;

typedef struct {
    const char *name;
    Causality causality;
    Variability variability;
    double start; /* for integers/booleans the start value as double */
    double min;   /* -HUGE_VAL if none declared */
    double max;   /* +HUGE_VAL if none declared */
} VarInfo;

/* Generated per model from its modelDescription.xml: N_REALS, N_INTEGERS, N_BOOLEANS,
 * VR_<name> (index into the value arrays), the VarInfo tables and MODEL_GUID. It also
 * includes the model's config.h, which declares ModelState (the model's own states and
 * precomputed data) and INTERNAL_STEP_VR (the parameter holding the fixed solver step). */
#include "model_vars.h"

typedef enum {
    ST_INSTANTIATED = 1 << 0,
    ST_INIT_MODE = 1 << 1,
    ST_STEP_COMPLETE = 1 << 2,
    ST_STEP_FAILED = 1 << 3,
    ST_TERMINATED = 1 << 4,
    ST_ERROR = 1 << 5,
    ST_FATAL = 1 << 6
} InstanceState;

/* Everything that makes up an FMU state: copied byte for byte by get/set/serialize. */
typedef struct {
    double r[N_REALS > 0 ? N_REALS : 1];
    int i[N_INTEGERS > 0 ? N_INTEGERS : 1];
    int b[N_BOOLEANS > 0 ? N_BOOLEANS : 1];
    double start_time;
    int64_t steps_taken; /* internal steps since start: time = start_time + steps_taken * h */
    int state;           /* InstanceState at the time of the snapshot */
    ModelState m;
} ModelValues;

typedef struct ModelInstance {
    char *instance_name;
    fmi2CallbackLogger logger;
    fmi2ComponentEnvironment env;
    int logging_on;
    int state; /* InstanceState */
    ModelValues v;
} ModelInstance;

/* Logging helpers (implemented in the wrapper); errors are always logged. */
void log_error(ModelInstance *comp, const char *fmt, ...);
void log_info(ModelInstance *comp, const char *fmt, ...);

/* Current time of the instance from the integer step counter (never summed floats). */
double model_time(const ModelInstance *comp);

/* ---- to be implemented by every model ---- */

/* Return 0 if the parameters are consistent, else write a one-line reason into msg. */
int model_check(ModelInstance *comp, char *msg, size_t msg_size);
/* Precompute, set the initial states and outputs. Return fmi2OK or fmi2Error (logged). */
fmi2Status model_initialize(ModelInstance *comp);
/* Advance the states by one internal step of length h. Return fmi2OK or fmi2Error. */
fmi2Status model_step(ModelInstance *comp, double h);
/* Recompute the outputs from the states and the current inputs. */
void model_outputs(ModelInstance *comp);

#endif
