/* OscillationDrive: model-specific configuration (the swing's phase, the friction integrals,
 * the heat-averaging block and the drive vibration). */
#ifndef OSCILLATION_DRIVE_CONFIG_H
#define OSCILLATION_DRIVE_CONFIG_H

#include <stdint.h>

#include "rng.h"

typedef struct {
    Rng rng;              /* vibration noise generator (fmus/common/rng.h), part of the FMU state */
    int64_t n_on;         /* internal steps taken with the drive on: phase = frequency * (n_on * h) cycles */
    int64_t n_window;     /* internal steps per q_avg_window block */
    int64_t n_block;      /* internal steps of the current (incomplete) block */
    double e_block;       /* J: friction energy of the current block */
    double q_avg;         /* W: mean friction heat of the last completed block */
    double energy;        /* J: friction energy since initialization */
    double distance;      /* m: sliding distance since initialization */
    double t_since_rev;   /* s: time since the last reversal of the swing */
    double rev_sign;      /* +1 / -1: direction of the motion after the last reversal */
    double z_vib;         /* m: the last vibration sample */
    int has_reversal;     /* 0 until the first reversal (no ringing before it) */
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

/* the friction coefficient's pressure and temperature factors: their arguments change with
 * the load and the bearing's temperature, not with every step (model.h, Memo) */
enum { MEMO_PRESSURE, MEMO_TEMPERATURE, OD_MEMOS };
#define MODEL_MEMOS OD_MEMOS

#endif
