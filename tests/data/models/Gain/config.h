/* Gain (test-only): no state; the wrapper's fixed internal step is the parameter solver_step. */
#ifndef GAIN_CONFIG_H
#define GAIN_CONFIG_H

typedef struct {
    int unused; /* the gain has no state */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
