/*
 * expm_blocks_check.c -- ThermalNetwork's step matrices from its four-block exponential
 * (expm_blocks, model.c) against the whole augmented matrix's (la_expm, linalg.c), for random
 * networks and steps: every entry the same double (a zero's sign aside). Built by
 * tests/fmus/test_expm_blocks.py with the model's sources, this file including model.c for
 * its static functions.
 *
 * Usage: expm_blocks_check TRIALS SEED [nudge]; prints "checked=N squarings=LO..HI
 * mismatches=M" and exits 1 on a mismatch. With "nudge", la_expm is given A's first entry one
 * ulp off: then the entries must differ (the comparison can fail).
 */
#include "model.c"

#include <stdio.h>
#include <stdlib.h>

static uint64_t rng_state;

static double uniform01(void) { /* xorshift64*: enough for test data */
    rng_state ^= rng_state >> 12;
    rng_state ^= rng_state << 25;
    rng_state ^= rng_state >> 27;
    return (double)((rng_state * 0x2545F4914F6CDD1DULL) >> 11) * (1.0 / 9007199254740992.0);
}

static double log_uniform(double lo, double hi) { return pow(10.0, lo + (hi - lo) * uniform01()); }

/* A random network's augmented matrix times h, laid out as augmented() lays it out. */
static void random_augmented(double *aug) {
    enum { n = TN_NODES, N = TN_AUG };
    double c[TN_NODES], h = log_uniform(-2.0, 3.6);
    int i, j, k;
    memset(aug, 0, sizeof(double) * N * N);
    for (i = 0; i < n; i++) c[i] = log_uniform(-1.0, 6.0);
    for (k = 0; k < 3 * n; k++) { /* edges, some repeated: conductances add */
        double g = log_uniform(-3.0, 2.0);
        i = (int)(uniform01() * n);
        j = (int)(uniform01() * n);
        if (i == j) continue;
        aug[i * N + i] -= g / c[i];
        aug[i * N + j] += g / c[i];
        aug[j * N + j] -= g / c[j];
        aug[j * N + i] += g / c[j];
    }
    for (i = 0; i < n; i++) {
        double groom = uniform01() < 0.3 ? 0.0 : log_uniform(-3.0, 1.0);
        aug[i * N + i] -= groom / c[i];
        aug[i * N + 2 * n + 0] = groom / c[i];
        aug[i * N + 2 * n + 1] = uniform01() / c[i];
        aug[i * N + 2 * n + 2] = uniform01() < 0.5 ? 0.0 : uniform01() / c[i];
        aug[i * N + 2 * n + 3] = i == POLE_LOWER ? 1.0 / c[i] : 0.0;
        aug[(n + i) * N + i] = 1.0;
    }
    for (i = 0; i < N * N; i++) aug[i] *= h;
}

static int differ(const double *block, const double *whole, int rows, int cols, int row0, int col0) {
    int i, j, bad = 0;
    for (i = 0; i < rows; i++)
        for (j = 0; j < cols; j++)
            if (!(block[i * cols + j] == whole[(row0 + i) * TN_AUG + col0 + j])) bad++;
    return bad;
}

int main(int argc, char **argv) {
    enum { n = TN_NODES, q = TN_INPUTS, N = TN_AUG };
    static double aug[N * N], e[N * N], work[3 * N * N];
    ModelState m;
    int trials = argc > 1 ? atoi(argv[1]) : 200, t, bad = 0, lo = 1000, hi = -1;
    const int nudge = argc > 3 && strcmp(argv[3], "nudge") == 0;
    rng_state = 0x9E3779B97F4A7C15ULL ^ (uint64_t)(argc > 2 ? strtoull(argv[2], NULL, 10) : 1);
    for (t = 0; t < trials; t++) {
        int s;
        random_augmented(aug);
        s = la_expm_squarings(N, aug);
        if (s < lo) lo = s;
        if (s > hi) hi = s;
        if (expm_blocks(aug, &m) != 0) {
            printf("trial %d: not finite\n", t);
            return 1;
        }
        if (nudge) aug[0] = nextafter(aug[0], 0.0);
        if (la_expm(N, aug, e, work) != 0) {
            printf("trial %d: not finite\n", t);
            return 1;
        }
        bad += differ(m.phi, e, n, n, 0, 0) + differ(m.gamma, e, n, q, 0, 2 * n) + differ(m.psi, e, n, n, n, 0) +
               differ(m.lambda, e, n, q, n, 2 * n);
    }
    printf("checked=%d squarings=%d..%d mismatches=%d\n", trials, lo, hi, bad);
    return bad != 0;
}
