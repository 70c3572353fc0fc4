/* FixtureMechanics: model-specific configuration. */
#ifndef MECHANICS_CONFIG_H
#define MECHANICS_CONFIG_H

#define FM_TEMPS 14

typedef struct {
    double t_ref[FM_TEMPS];   /* temperatures of zero thermal displacement, K */
    double wear;              /* liner wear depth (Archard state), m */
    double sliding_distance;  /* accumulated sliding distance in the liner, m */
    double creep;             /* liner creep under the held load, m (first-order lag) */
    double liner_play;        /* liner compression after the hysteresis (play operator) state, m */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
