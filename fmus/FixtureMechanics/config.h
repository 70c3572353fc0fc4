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

/* trigonometry of angles that change with the temperatures or not at all (the block's tilt,
 * the probe's tilt, the runout's phase), asked for at every output (model.h, Memo) */
enum { MEMO_TILT_COS, MEMO_TILT_SIN, MEMO_RUNOUT_PHASE, MEMO_PROBE_TILT, FM_MEMOS };
#define MODEL_MEMOS FM_MEMOS

#endif
