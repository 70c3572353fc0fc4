/*
 * linalg.c -- dense helpers for the models: matrix exponential, mat-vec, linear solve.
 * Sizes are tiny (tens of rows), so plain loops are the clearest and fast enough; the
 * exponential is computed once per initialization, never in the step loop.
 */
#include "linalg.h"

#include <math.h>
#include <string.h>

static void matmul(size_t n, const double *a, const double *b, double *out) {
    size_t i, j, k;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) {
            double s = 0.0;
            for (k = 0; k < n; k++) s += a[i * n + k] * b[k * n + j];
            out[i * n + j] = s;
        }
    }
}

int la_expm_squarings(size_t n, const double *a) {
    double norm = 0.0;
    int squarings = 0;
    size_t i, j;
    /* infinity norm decides how often to halve: Taylor converges fast for ||A|| <= 1/2 */
    for (i = 0; i < n; i++) {
        double row = 0.0;
        for (j = 0; j < n; j++) {
            if (!isfinite(a[i * n + j])) return -1;
            row += fabs(a[i * n + j]);
        }
        if (row > norm) norm = row;
    }
    if (!isfinite(norm)) return -1;
    while (norm > 0.5) {
        norm *= 0.5;
        squarings++;
    }
    return squarings;
}

int la_expm(size_t n, const double *a, double *out, double *work) {
    double *scaled = work, *term = work + n * n, *tmp = work + 2 * n * n;
    double scale;
    int squarings = la_expm_squarings(n, a), k;
    size_t i;

    if (squarings < 0) return -1;
    scale = ldexp(1.0, -squarings);
    for (i = 0; i < n * n; i++) scaled[i] = a[i] * scale;

    /* out = I + A + A^2/2! + ... ; 20 terms at ||A|| <= 1/2 leave < 1e-25 relative */
    memset(out, 0, n * n * sizeof *out);
    for (i = 0; i < n; i++) out[i * n + i] = 1.0;
    memcpy(term, out, n * n * sizeof *term);
    for (k = 1; k <= 20; k++) {
        matmul(n, term, scaled, tmp);
        for (i = 0; i < n * n; i++) {
            term[i] = tmp[i] / (double)k;
            out[i] += term[i];
        }
    }
    for (k = 0; k < squarings; k++) {
        matmul(n, out, out, tmp);
        memcpy(out, tmp, n * n * sizeof *out);
    }
    return 0;
}

void la_matvec(size_t r, size_t c, const double *m, const double *x, double *y) {
    size_t i, j;
    for (i = 0; i < r; i++) {
        double s = 0.0;
        for (j = 0; j < c; j++) s += m[i * c + j] * x[j];
        y[i] = s;
    }
}

int la_solve(size_t n, double *a, double *b) {
    size_t i, j, k;
    for (k = 0; k < n; k++) {
        size_t p = k;
        double best = fabs(a[k * n + k]);
        for (i = k + 1; i < n; i++) {
            if (fabs(a[i * n + k]) > best) {
                best = fabs(a[i * n + k]);
                p = i;
            }
        }
        if (!(best > 0.0)) return -1;
        if (p != k) {
            for (j = 0; j < n; j++) {
                double t = a[k * n + j];
                a[k * n + j] = a[p * n + j];
                a[p * n + j] = t;
            }
            {
                double t = b[k];
                b[k] = b[p];
                b[p] = t;
            }
        }
        for (i = k + 1; i < n; i++) {
            double f = a[i * n + k] / a[k * n + k];
            for (j = k; j < n; j++) a[i * n + j] -= f * a[k * n + j];
            b[i] -= f * b[k];
        }
    }
    for (k = n; k-- > 0;) {
        double s = b[k];
        for (j = k + 1; j < n; j++) s -= a[k * n + j] * b[j];
        b[k] = s / a[k * n + k];
    }
    return 0;
}
