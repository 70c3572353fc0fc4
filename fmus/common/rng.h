/*
 * rng.h -- the deterministic random generator the models share.
 *
 * xoshiro256** (Blackman and Vigna 2018) seeded through splitmix64; uniforms in (0, 1];
 * standard normals by Box-Muller (the second value of each pair is kept for the next draw).
 *
 * The whole generator is one plain struct (no pointers, no globals): a model keeps it inside
 * its ModelState, so FMU get/set/serialize state reproduce the random stream bit for bit and
 * the same seed always gives the same numbers.
 */
#ifndef TWIN_RNG_H
#define TWIN_RNG_H

#include <stdint.h>

/* the most normals a stream may owe (rng_owe_gauss): far beyond any run (a DAQ at 10 kHz owes
 * 1e5 a second: 2^50 is three centuries), and far from int64_t's end */
#define RNG_OWED_MAX ((int64_t)1 << 50)

typedef struct {
    uint64_t s[4];      /* xoshiro256** state (never all zero after rng_seed) */
    double gauss_spare; /* has_spare 1: the second Box-Muller value, returned by the next rng_gauss;
                           has_spare 2: the first uniform of the pair whose second value it is */
    int has_spare;      /* 0 none, 1 a spare normal, 2 a spare not computed yet (rng_skip_gauss) */
    double spare_u2;    /* has_spare 2: the pair's second uniform */
    int64_t owed;       /* normals skipped on credit (rng_owe_gauss), not yet advanced over: the
                           next draw advances over them first (rng_settle) */
} Rng;

/* Expand a seed into the 256-bit state by splitmix64 and drop any spare normal. */
void rng_seed(Rng *r, uint64_t seed);

/* Next raw 64-bit output of xoshiro256**. */
uint64_t rng_next_u64(Rng *r);

/* Uniform in (0, 1]: ((x >> 11) + 1) * 2^-53, never 0 (so log() of it is finite). */
double rng_uniform(Rng *r);

/* Standard normal N(0, 1) by Box-Muller; each pair costs two uniforms. */
double rng_gauss(Rng *r);

/* Advance r exactly as n calls of rng_gauss would, computing only a value that is kept as the
 * spare (the one the next rng_gauss returns): the draws of a DAQ sample nobody reads. */
void rng_skip_gauss(Rng *r, int n);

/* The same as rng_skip_gauss(r, n), on credit: only counted now, and advanced over at once by
 * the next draw from r (or rng_settle), by a jump of the generator where the stretch is long.
 * For a stream a model only skips between the draws it reads: the stream then stays bit for
 * bit what skipping at once would make of it. */
void rng_owe_gauss(Rng *r, int n);

/* Advance r over the normals it owes (rng_owe_gauss), exactly as rng_skip_gauss would have
 * (which is rng_owe_gauss, then this). */
void rng_settle(Rng *r);

/* NULL if r can be a generator's state (after rng_seed and any draws), else why not: the
 * xoshiro256** state is never all zero, has_spare is 0, 1 or 2, a pending pair's uniforms are
 * in (0, 1], and the spare normal is one
 * Box-Muller can give (|x| <= sqrt(-2 ln 2^-53) ~ 8.57, the uniforms being >= 2^-53), and
 * the normals owed are not negative nor more than RNG_OWED_MAX.
 * For the FMU state checks of the models that carry a generator. */
const char *rng_problem(const Rng *r);

#endif
