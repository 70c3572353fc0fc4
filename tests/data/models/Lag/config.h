/* Lag (test-only): its one state, the lagged temperature. */
#ifndef LAG_CONFIG_H
#define LAG_CONFIG_H

typedef struct {
    double x; /* degC */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
