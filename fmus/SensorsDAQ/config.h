/* SensorsDAQ: model-specific configuration (channel counts and the state of every instrument). */
#ifndef SENSORS_DAQ_CONFIG_H
#define SENSORS_DAQ_CONFIG_H

#include "rng.h"

#define SD_TEMPS 8 /* the paper's eight temperature measuring points */

/* The second noise stream is seeded with seed ^ SD_STREAM2_KEY: its high bits are set, so it never
 * coincides with the first stream of any seed (0 .. 2^31-1). */
#define SD_STREAM2_KEY 0xD1B54A32D192ED03ULL
/* The third stream (the probe body's thermometer, added last) is seeded with seed ^ SD_STREAM3_KEY:
 * a stream of its own, so adding that channel left every other channel's draws as they were. */
#define SD_STREAM3_KEY 0x9E3779B97F4A7C15ULL

typedef struct {
    /* deterministic noise generators (fmus/common/rng.h): xoshiro256** seeded by splitmix64,
     * Gaussian by Box-Muller; plain structs, so they are part of the FMU state.
     * rng:  temperatures and probe noise (unchanged since the first version of this FMU);
     * rng2: load, torque and vibration noise and the interference spikes;
     * rng3: the probe body's thermometer */
    Rng rng;
    Rng rng2;
    Rng rng3;
    /* discretisation for the step it was made for */
    double step_h;
    double a_temp;      /* 1 - exp(-h/temp_tau) */
    double a_probe;     /* 1 - exp(-2 pi f_c h) */
    double spike_p;     /* probability that a spike starts in one step: 1 - exp(-spike_rate h) */
    int spike_steps;    /* samples a spike lasts: max(1, round(spike_duration / h)) */
    /* filter states */
    double temp_lag[SD_TEMPS]; /* K: the sensing elements' temperatures */
    double probe_filt;         /* m: the probe's low-passed head position */
    double t_probe_body0;      /* K: probe body temperature at initialization (zero and span drift reference) */
    double body_lag;           /* K: the probe body thermometer's sensing element */
    /* interference on the probe */
    int spike_left;     /* samples the current spike still covers, this one included (0 = none) */
    double spike_value; /* m: signed size of the current spike */
    /* the last DAQ sample: what the outputs show until the next internal step */
    double temp_sample[SD_TEMPS];
    double probe_sample;
    double probe_in_range;
    double load_sample;
    double torque_sample;
    double angle_sample;
    double vibration_sample;
    double spike_sample;
    double body_sample;
} ModelState;

#define INTERNAL_STEP_VR VR_solver_step

/* What one DAQ sample is drawn from: the three streams where the sample starts drawing, the
 * filter states, the interference and the inputs it reads. The sample of a communication
 * step's last internal step is taken from a copy of these when its outputs are read (the
 * wrapper's deferred outputs: MODEL_DEFERS_OUTPUTS), while the live streams skip its draws:
 * a sample nobody reads then costs no logarithm, sine or cosine, and one that is read has
 * the bits it had when it was taken at once. The first and third streams owe their skips
 * (rng_owe_gauss), the copy with them: a read advances the copy over what it owes, and the
 * live streams become it again, owing only the skips since (model_outputs). */
typedef struct {
    Rng rng;
    Rng rng2;
    Rng rng3;
    double temp_lag[SD_TEMPS];
    double probe_filt;
    double body_lag;
    double spike_value;
    int spike_left;
    double t_probe_body;
    double load_true;
    double torque_true;
    double vibration_true;
    double angle_true;
} SampleSource;

typedef struct {
    int pending; /* 1: the outputs are the sample of `source`, not taken yet */
    SampleSource source;
} ModelDeferred;

#define MODEL_DEFERS_OUTPUTS 1

#endif
