/* SensorsDAQ: model-specific configuration (channel counts and the state of every instrument). */
#ifndef SENSORS_DAQ_CONFIG_H
#define SENSORS_DAQ_CONFIG_H

#include "rng.h"

#define SD_TEMPS 8 /* the paper's eight temperature measuring points */

typedef struct {
    /* deterministic noise generator (fmus/common/rng.h): xoshiro256** seeded by splitmix64,
     * Gaussian by Box-Muller; a plain struct, so it is part of the FMU state */
    Rng rng;
    /* discretisation of the lags for the step they were made for (exact: 1 - exp(-h/tau)) */
    double step_h;
    double a_temp;
    double a_probe;
    /* filter states */
    double temp_lag[SD_TEMPS]; /* K: the sensing elements' temperatures */
    double probe_filt;         /* m: the probe's low-passed head position */
    double t_probe_body0;      /* K: probe body temperature at initialization (zero-drift reference) */
    /* the last DAQ sample: what the outputs show until the next internal step */
    double temp_sample[SD_TEMPS];
    double probe_sample;
    double probe_in_range;
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

#endif
