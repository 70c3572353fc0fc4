/* FixtureMechanics: model-specific configuration. */
#ifndef MECHANICS_CONFIG_H
#define MECHANICS_CONFIG_H

#define FM_TEMPS 10

typedef struct {
    double t_ref[FM_TEMPS]; /* temperatures of zero thermal displacement, K */
    double z_tplate0;       /* reserved for the wear state of the loading/oscillation models */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
