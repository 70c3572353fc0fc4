"""Credibility indexes of an on-line wear curve (Adv. Mech. Eng. 2016, docs/reference/facts.md section 3).

(I) the discrete Frechet distance between the on-line curve and the true (off-line) curve,
by the Eiter and Mannila (1994) recursion; (II) the fluctuation amplitude of the on-line curve,
computed like the roughness Ra: the mean absolute deviation from its mean line.
"""

from __future__ import annotations

import numpy as np


def discrete_frechet(p: np.ndarray, q: np.ndarray) -> float:
    """Discrete Frechet distance between polygonal curves ``p`` (n, d) and ``q`` (m, d).

    Eiter and Mannila's recursion ca(i, j) = max(d(p_i, q_j), min(ca(i-1, j), ca(i-1, j-1),
    ca(i, j-1))), evaluated one anti-diagonal at a time: every cell of an anti-diagonal depends
    only on the two before it, so each is one vectorised numpy step (O(n m) work, O(n + m)
    Python steps, O(n + m) memory).
    """
    p = np.asarray(p, dtype=float)
    q = np.asarray(q, dtype=float)
    if p.ndim == 1:
        p = p[:, None]
    if q.ndim == 1:
        q = q[:, None]
    n, m = len(p), len(q)
    if n == 0 or m == 0:
        raise ValueError("both curves need at least one point")
    q_rev = q[::-1]  # cell (i, k - i) of diagonal k pairs p[i] with q_rev[m - 1 - k + i]
    # diagonal k is stored by i at index i + 1 of an array of n + 1, the rest inf: index 0 is
    # the row before the first, and a cell outside the grid reads inf from its neighbours
    prev2 = np.full(n + 1, np.inf)  # diagonal k-2
    prev1 = np.full(n + 1, np.inf)  # diagonal k-1
    for k in range(n + m - 1):
        lo, hi = max(0, k - m + 1), min(n, k + 1)  # the diagonal's rows i
        d = np.sqrt(np.sum((p[lo:hi] - q_rev[m - 1 - k + lo : m - 1 - k + hi]) ** 2, axis=1))
        cur = np.full(n + 1, np.inf)
        if k == 0:
            cur[1] = d[0]
        else:
            # (i-1, j): prev1 at i-1; (i, j-1): prev1 at i; (i-1, j-1): prev2 at i-1
            reach = np.minimum(np.minimum(prev1[lo:hi], prev1[lo + 1 : hi + 1]), prev2[lo:hi])
            cur[lo + 1 : hi + 1] = np.maximum(d, reach)
        prev2, prev1 = prev1, cur
    return float(prev1[n])


def ra_fluctuation(t: np.ndarray, z: np.ndarray, window_s: float) -> float:
    """Ra-like fluctuation amplitude: mean |z - mean line|.

    The mean line is a centred moving average over ``window_s`` (the wear trend), so the index
    measures the scatter around the trend, not the trend itself.
    """
    t = np.asarray(t, dtype=float)
    z = np.asarray(z, dtype=float)
    if len(z) < 3:
        return 0.0
    dt = float(np.median(np.diff(t)))
    half = max(1, round(window_s / dt / 2))
    kernel = np.ones(2 * half + 1)
    padded = np.pad(z, half, mode="reflect", reflect_type="odd")  # odd: a linear trend continues
    mean_line = np.convolve(padded, kernel / kernel.size, mode="valid")
    return float(np.mean(np.abs(z - mean_line)))
