"""Credibility indexes of an on-line wear curve (Adv. Mech. Eng. 2016, docs/reference/facts.md section 3).

(I) the discrete Frechet distance between the on-line curve and the true (off-line) curve,
by the Eiter and Mannila (1994) recursion; (II) the fluctuation amplitude of the on-line curve,
computed like the roughness Ra: the mean absolute deviation from its mean line.
"""

from __future__ import annotations

import numpy as np

#: curves of up to this many pairs of points have their distances computed at once (below it
#: the n x m matrix is a few tens of MB at most); longer ones one anti-diagonal at a time
MATRIX_CELLS = 2_000_000


def discrete_frechet(p: np.ndarray, q: np.ndarray) -> float:
    """Discrete Frechet distance between polygonal curves ``p`` (n, d) and ``q`` (m, d).

    Eiter and Mannila's recursion ca(i, j) = max(d(p_i, q_j), min(ca(i-1, j), ca(i-1, j-1),
    ca(i, j-1))), evaluated one anti-diagonal at a time: every cell of an anti-diagonal depends
    only on the two before it, so each is one vectorised numpy step (O(n m) work, O(n + m)
    Python steps, O(n + m) memory beyond the distances).

    The distances d(p_i, q_j) are computed for all pairs at once (up to :data:`MATRIX_CELLS`
    of them, else per anti-diagonal), each as the same sum of squares; the recursion only
    takes minima and maxima of them, which are exact, so the result is the same double
    either way.
    """
    return discrete_frechets([p], q)[0]


def discrete_frechets(ps: list[np.ndarray], q: np.ndarray) -> list[float]:
    """:func:`discrete_frechet` of each curve of ``ps`` (all of one length n) against ``q``:
    their recursions run side by side, one numpy step per anti-diagonal for all of them (a
    run's curve before and after compensation against its true wear), each cell the same
    double as alone."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 1:
        q = q[:, None]
    p = np.stack([np.asarray(c, dtype=float) for c in ps])
    if p.ndim == 2:
        p = p[:, :, None]
    c, n, m = p.shape[0], p.shape[1], len(q)
    if n == 0 or m == 0:
        raise ValueError("both curves need at least one point")
    if n * m <= MATRIX_CELLS:
        # cell (i, j) at i * m + j: the anti-diagonal i + j = k is every (m - 1)-th of them
        # one row per curve, or one for all where they are the same (broadcast in the steps)
        flat = np.sqrt(_squares(p, q)).reshape(-1, n * m)

        def distances(k: int, lo: int, hi: int) -> np.ndarray:
            first = lo * (m - 1) + k
            return flat[:, first : first + (hi - lo - 1) * (m - 1) + 1 : max(m - 1, 1)]

    else:
        q_rev = q[::-1]  # cell (i, k - i) of diagonal k pairs p[i] with q_rev[m - 1 - k + i]

        def distances(k: int, lo: int, hi: int) -> np.ndarray:
            diff = p[:, lo:hi] - q_rev[None, m - 1 - k + lo : m - 1 - k + hi]
            return np.sqrt(np.sum(diff**2, axis=2))

    # diagonal k is stored by i at index i + 1 of an array of n + 1, the rest inf: index 0 is
    # the row before the first, and a cell outside the grid reads inf from its neighbours. Three
    # arrays take turns (k, k-1, k-2): a diagonal's rows only move up with k, so what an
    # array held three diagonals before lies where the next reads find inf or is overwritten
    cur, prev1, prev2 = (np.full((c, n + 1), np.inf) for _ in range(3))
    reach = np.empty((c, n))
    for k in range(n + m - 1):
        lo, hi = max(0, k - m + 1), min(n, k + 1)  # the diagonal's rows i
        d = distances(k, lo, hi)
        if k == 0:
            cur[:, 1] = d[:, 0]
        else:
            # (i-1, j): prev1 at i-1; (i, j-1): prev1 at i; (i-1, j-1): prev2 at i-1
            r = reach[:, : hi - lo]
            np.minimum(prev1[:, lo:hi], prev1[:, lo + 1 : hi + 1], out=r)
            np.minimum(r, prev2[:, lo:hi], out=r)
            np.maximum(d, r, out=cur[:, lo + 1 : hi + 1])
        cur, prev1, prev2 = prev2, cur, prev1
    return prev1[:, n].tolist()


def _squares(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The squared distances of every point of each curve of ``p`` (c, n, d) to every point of
    ``q`` (m, d), shape (c, n, m), or (1, n, m) where the curves are the same: the coordinates'
    squares added in order, as np.sum adds them, one coordinate at a time over the whole
    matrix (np.sum over a last axis of two is a slow strided loop); a coordinate every curve
    shares with the others (their common time axis) is squared once."""
    total: np.ndarray | None = None
    for axis in range(q.shape[1]):
        column = p[:, :, axis]
        if (column == column[:1]).all():  # the same for every curve
            diff = column[0][:, None] - q[None, :, axis]
            square = (diff * diff)[None]
        else:
            diff = column[:, :, None] - q[None, None, :, axis]
            square = diff * diff
        total = square if total is None else total + square
    assert total is not None
    return total


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
