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

/* libm calls whose arguments change with the temperatures or not at all (model.h, Memo): the
 * trigonometry of the block's tilt, the probe's tilt, the runout's phase and the swing angle
 * (constant while the transmission is off), asked for at every output; the creep's gain, the
 * same every internal step; the running-in's exponential of -s/s0 (constant while nothing
 * slides, and one step's end is the next step's start and the outputs') */
enum {
    MEMO_TILT_COS,
    MEMO_TILT_SIN,
    MEMO_RUNOUT_PHASE,
    MEMO_PROBE_TILT,
    MEMO_ANGLE_COS,
    MEMO_RUNOUT_COS,
    MEMO_CREEP_GAIN,
    MEMO_RUNNING_IN,
    FM_MEMOS
};
#define MODEL_MEMOS FM_MEMOS

#endif
