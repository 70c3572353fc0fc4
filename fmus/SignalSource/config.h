/* SignalSource: model-specific configuration. The output is a function of the time alone; the
 * state holds only what is precomputed from the parameters at initialization. */
#ifndef SIGNAL_SOURCE_CONFIG_H
#define SIGNAL_SOURCE_CONFIG_H

#include <stdint.h>

#define SS_TABLE 64 /* points of the table profile */

typedef struct {
    int64_t step_ns; /* the solver step in whole nanoseconds: the master's clock */
    double scale;    /* exponential: 1 / -expm1(-rise_at / time_constant), or 1 without rise_at */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
