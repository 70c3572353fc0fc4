/*
 * linalg.h -- the small dense linear algebra the models share (row-major double arrays).
 */
#ifndef TWIN_LINALG_H
#define TWIN_LINALG_H

#include <stddef.h>

/* out = expm(a) for an n x n matrix (scaling and squaring with a Taylor series). out must
 * not alias a; work must hold 3*n*n doubles. Returns 0, or -1 if a has NaN/Inf. */
int la_expm(size_t n, const double *a, double *out, double *work);

/* How many squarings la_expm takes for a (the halvings that bring its infinity norm to 1/2), or
 * -1 if a has NaN/Inf. Each squaring doubles the rounding of the result: 2^s eps relative. */
int la_expm_squarings(size_t n, const double *a);

/* y = m x for an r x c matrix m. */
void la_matvec(size_t r, size_t c, const double *m, const double *x, double *y);

/* x = solution of a x = b (n x n, Gaussian elimination with partial pivoting).
 * a and b are overwritten. Returns 0, or -1 if a is singular. */
int la_solve(size_t n, double *a, double *b);

#endif
