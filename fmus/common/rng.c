/*
 * rng.c -- splitmix64 -> xoshiro256** generator with uniform and Box-Muller normal draws
 * (see rng.h). Moved unchanged from SensorsDAQ, whose noise stays bit-identical.
 */
#include "rng.h"

#include <math.h>
#include <stddef.h>

#define RNG_TWO_PI 6.283185307179586476925286766559

static uint64_t splitmix64(uint64_t *x) {
    uint64_t z = (*x += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
}

static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

void rng_seed(Rng *r, uint64_t seed) {
    uint64_t x = seed;
    int k;
    /* splitmix64 never yields an all-zero xoshiro state from consecutive outputs */
    for (k = 0; k < 4; k++) r->s[k] = splitmix64(&x);
    r->has_spare = 0;
    r->gauss_spare = 0.0;
    r->spare_u2 = 0.0;
}

/* xoshiro256** (Blackman and Vigna 2018) */
uint64_t rng_next_u64(Rng *r) {
    uint64_t *s = r->s;
    const uint64_t result = rotl(s[1] * 5, 7) * 9;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double rng_uniform(Rng *r) {
    return ((double)(rng_next_u64(r) >> 11) + 1.0) * (1.0 / 9007199254740992.0); /* 2^-53 */
}

double rng_gauss(Rng *r) {
    double u1, u2, rad;
    if (r->has_spare == 1) {
        r->has_spare = 0;
        return r->gauss_spare;
    }
    if (r->has_spare == 2) { /* the spare a skip left uncomputed: the same expression as below */
        r->has_spare = 0;
        rad = sqrt(-2.0 * log(r->gauss_spare));
        return rad * sin(RNG_TWO_PI * r->spare_u2);
    }
    u1 = rng_uniform(r);
    u2 = rng_uniform(r);
    rad = sqrt(-2.0 * log(u1));
    r->gauss_spare = rad * sin(RNG_TWO_PI * u2);
    r->has_spare = 1;
    return rad * cos(RNG_TWO_PI * u2);
}

void rng_skip_gauss(Rng *r, int n) {
    while (n > 0) {
        if (r->has_spare) { /* the kept value (or its uniforms), unread */
            r->has_spare = 0;
            n--;
        } else if (n == 1) { /* half a pair: its second value is the next draw's, kept uncomputed */
            r->gauss_spare = rng_uniform(r);
            r->spare_u2 = rng_uniform(r);
            r->has_spare = 2;
            n = 0;
        } else { /* a whole pair, both values unread: its two uniforms only */
            (void)rng_next_u64(r);
            (void)rng_next_u64(r);
            n -= 2;
        }
    }
}

/* the largest |normal| rng_gauss can return: sqrt(-2 ln 2^-53) = 8.5716..., rounded up */
#define RNG_GAUSS_MAX 8.5717

const char *rng_problem(const Rng *r) {
    if (!(r->s[0] | r->s[1] | r->s[2] | r->s[3])) return "the xoshiro256** state is all zero (its stream would be constant)";
    if (r->has_spare < 0 || r->has_spare > 2) return "has_spare is not 0, 1 or 2";
    if (r->has_spare == 2) {
        if (!(r->gauss_spare > 0.0 && r->gauss_spare <= 1.0 && r->spare_u2 > 0.0 && r->spare_u2 <= 1.0))
            return "a pending spare normal's uniforms are not in (0, 1]";
    } else if (!(fabs(r->gauss_spare) <= RNG_GAUSS_MAX))
        return "the spare normal is not one Box-Muller can draw";
    return NULL;
}
