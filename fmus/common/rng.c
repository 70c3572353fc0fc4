/*
 * rng.c -- splitmix64 -> xoshiro256** generator with uniform and Box-Muller normal draws
 * (see rng.h), and normals skipped at once or on credit. Moved unchanged from SensorsDAQ, whose
 * noise stays bit-identical.
 */
#include "rng.h"

#include <math.h>
#include <stddef.h>
#include <string.h>

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
    r->owed = 0;
}

/* xoshiro256** (Blackman and Vigna 2018): one step, whatever is owed (the draws below settle
 * that first) */
static uint64_t next_raw(Rng *r) {
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

static double uniform_raw(Rng *r) {
    return ((double)(next_raw(r) >> 11) + 1.0) * (1.0 / 9007199254740992.0); /* 2^-53 */
}

uint64_t rng_next_u64(Rng *r) {
    if (r->owed) rng_settle(r);
    return next_raw(r);
}

double rng_uniform(Rng *r) {
    if (r->owed) rng_settle(r);
    return uniform_raw(r);
}

double rng_gauss(Rng *r) {
    double u1, u2, rad;
    if (r->owed) rng_settle(r);
    if (r->has_spare == 1) {
        r->has_spare = 0;
        return r->gauss_spare;
    }
    if (r->has_spare == 2) { /* the spare a skip left uncomputed: the same expression as below */
        r->has_spare = 0;
        rad = sqrt(-2.0 * log(r->gauss_spare));
        return rad * sin(RNG_TWO_PI * r->spare_u2);
    }
    u1 = uniform_raw(r);
    u2 = uniform_raw(r);
    rad = sqrt(-2.0 * log(u1));
    r->gauss_spare = rad * sin(RNG_TWO_PI * u2);
    r->has_spare = 1;
    return rad * cos(RNG_TWO_PI * u2);
}

/* n normals unread: what rng_settle does with n more owed (a skip on credit, settled now) */
void rng_skip_gauss(Rng *r, int n) {
    rng_owe_gauss(r, n);
    rng_settle(r);
}

/* ---- skipping on credit: a jump of the generator over a long stretch
 *
 * xoshiro256's state transition T is linear over GF(2), and its characteristic polynomial P
 * has degree 256: T^m = (x^m mod P)(T) (Cayley-Hamilton), so m steps are the sum of the states
 * T^i s (i < 256) whose coefficient in x^m mod P is 1: 256 steps and a few XORs, whatever m,
 * the polynomial once made (about 2 log2 m products mod P, a few microseconds; the last few
 * are kept per thread, a model owing the same stretch between its reads again and again). */

/* P minus its x^256 term, bit i (of word i / 64) the coefficient of x^i. Found by
 * Berlekamp-Massey on the low bit of s[0] over 1,024 steps; checked against the reference
 * implementation's jump(): x^(2^128) mod P gives its JUMP constants
 * (0x180ec6d33cfd0aba, 0xd5a61266f0c9392c, 0xa9582618e03fc9aa, 0x39abdc4529b1661c). */
static const uint64_t RNG_CHARPOLY[4] = {0x9d116f2bb0f0f001ULL, 0x0280002bcefd1a5eULL, 0x04b4edcf26259f85ULL,
                                         0x0003c03c3f3ecb19ULL};

/* below this many steps, stepping is cheaper than a jump (256 steps, and the polynomial) */
#define RNG_JUMP_MIN 4096
#define RNG_JUMP_KEPT 4

#if defined(_MSC_VER)
#define RNG_THREAD_LOCAL __declspec(thread)
#elif defined(__GNUC__)
#define RNG_THREAD_LOCAL __thread
#else
#define RNG_THREAD_LOCAL _Thread_local
#endif

/* the jump polynomials made last on this thread, by their number of steps (0: none); a cache of
 * a pure function of m, so no instance or thread can see another's */
static RNG_THREAD_LOCAL struct {
    uint64_t m;
    uint64_t q[4];
} jumps_kept[RNG_JUMP_KEPT];
static RNG_THREAD_LOCAL int jump_next;

/* r = a * b mod P (GF(2) polynomials of degree < 256) */
static void poly_mulmod(uint64_t r[4], const uint64_t a_in[4], const uint64_t b[4]) {
    uint64_t a[4], acc[4] = {0, 0, 0, 0};
    int i, k;
    memcpy(a, a_in, sizeof a);
    for (i = 0; i < 256; i++) {
        uint64_t top;
        if ((b[i >> 6] >> (i & 63)) & 1u)
            for (k = 0; k < 4; k++) acc[k] ^= a[k];
        top = a[3] >> 63; /* a *= x, then x^256 = the rest of P */
        a[3] = (a[3] << 1) | (a[2] >> 63);
        a[2] = (a[2] << 1) | (a[1] >> 63);
        a[1] = (a[1] << 1) | (a[0] >> 63);
        a[0] <<= 1;
        if (top)
            for (k = 0; k < 4; k++) a[k] ^= RNG_CHARPOLY[k];
    }
    memcpy(r, acc, sizeof acc);
}

/* x^m mod P, kept for the next jump of as many steps */
static const uint64_t *jump_polynomial(uint64_t m) {
    uint64_t q[4] = {1, 0, 0, 0}, x[4] = {2, 0, 0, 0};
    uint64_t e = m;
    int j;
    for (j = 0; j < RNG_JUMP_KEPT; j++)
        if (jumps_kept[j].m == m) return jumps_kept[j].q;
    while (e) {
        if (e & 1u) poly_mulmod(q, q, x);
        e >>= 1;
        if (e) poly_mulmod(x, x, x);
    }
    j = jump_next;
    jump_next = (jump_next + 1) % RNG_JUMP_KEPT;
    jumps_kept[j].m = m;
    memcpy(jumps_kept[j].q, q, sizeof q);
    return jumps_kept[j].q;
}

/* m steps of the generator, their outputs unread */
static void advance(Rng *r, uint64_t m) {
    if (m < RNG_JUMP_MIN) {
        while (m--) (void)next_raw(r);
        return;
    }
    {
        const uint64_t *q = jump_polynomial(m);
        uint64_t acc[4] = {0, 0, 0, 0};
        int i, k;
        for (i = 0; i < 256; i++) {
            if ((q[i >> 6] >> (i & 63)) & 1u)
                for (k = 0; k < 4; k++) acc[k] ^= r->s[k];
            (void)next_raw(r);
        }
        memcpy(r->s, acc, sizeof acc);
    }
}

void rng_owe_gauss(Rng *r, int n) {
    if (n > 0) r->owed += n;
}

/* Advance over the normals owed as that many rng_gauss calls would, computing only a value kept
 * as the spare: the kept value (or its uniforms) first, then the whole pairs (their uniforms
 * unread, in one advance), then half a pair whose uniforms are kept for the next draw. */
void rng_settle(Rng *r) {
    int64_t n = r->owed;
    r->owed = 0;
    if (n <= 0) return;
    if (r->has_spare) {
        r->has_spare = 0;
        n--;
    }
    advance(r, (uint64_t)(n / 2) * 2u);
    if (n % 2) {
        r->gauss_spare = uniform_raw(r);
        r->spare_u2 = uniform_raw(r);
        r->has_spare = 2;
    }
}

/* the largest |normal| rng_gauss can return: sqrt(-2 ln 2^-53) = 8.5716..., rounded up */
#define RNG_GAUSS_MAX 8.5717

const char *rng_problem(const Rng *r) {
    if (!(r->s[0] | r->s[1] | r->s[2] | r->s[3])) return "the xoshiro256** state is all zero (its stream would be constant)";
    if (r->has_spare < 0 || r->has_spare > 2) return "has_spare is not 0, 1 or 2";
    if (r->owed < 0 || r->owed > RNG_OWED_MAX) return "the normals owed are negative or beyond RNG_OWED_MAX";
    if (r->has_spare == 2) {
        if (!(r->gauss_spare > 0.0 && r->gauss_spare <= 1.0 && r->spare_u2 > 0.0 && r->spare_u2 <= 1.0))
            return "a pending spare normal's uniforms are not in (0, 1]";
    } else if (!(fabs(r->gauss_spare) <= RNG_GAUSS_MAX))
        return "the spare normal is not one Box-Muller can draw";
    return NULL;
}
