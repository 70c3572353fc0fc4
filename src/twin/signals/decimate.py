"""Fewer rows for a picture, with every extreme kept.

A plot of a long record draws a few thousand of its rows: the figure is about 800 pixels wide,
and drawing every sample costs seconds without changing a pixel. Taking every k-th row is not
honest: a spike between two taken rows is not drawn at all (two injected spikes of a lab file
vanished so). The rows kept here are, per bucket of the time axis, the first and the last row
and, of every column, the first row holding its smallest and the first holding its largest
finite value (and the first non-finite one, so a gap stays a gap): the M4 aggregation of Jugel
et al., "M4: a visualization-oriented time series data aggregation", PVLDB 7(10), 2014,
applied to every column at once, so the columns still share one time axis. A line through
those rows covers, in each bucket, exactly the range the whole record covers there.

:func:`plot_rows` picks the rows of a record held whole; the buckets are fractions of the
time span, so picking again from the rows picked gives the same rows (a plot drawn from a
decimated table, by another process, draws what it would draw from the whole one).
:func:`extreme_rows` is the per-bucket step, which a record streamed chunk by chunk applies
with buckets of row indices (:mod:`twin.errormodel.streaming`).
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = ["BUCKETS", "LIMIT", "extreme_rows", "plot_rows"]

#: buckets across the time axis: more than the pixels of a panel's width
BUCKETS = 1000
#: a record of at most this many rows is drawn whole
LIMIT = 4 * BUCKETS


def _first_per_bucket(hit: np.ndarray, segment: np.ndarray, keep: np.ndarray) -> None:
    """Mark in ``keep`` the first row of ``hit`` (row indices, increasing) in each segment."""
    if hit.size:
        _, first = np.unique(segment[hit], return_index=True)
        keep[hit[first]] = True


def extreme_rows(bucket: np.ndarray, columns: Iterable[np.ndarray]) -> np.ndarray:
    """The indices (increasing) of the rows to keep of rows whose bucket numbers are ``bucket``
    (runs of equal numbers, as a time axis gives): in each run its first and last row and, of
    each column, the first row of its smallest, of its largest finite value and of a
    non-finite one."""
    n = int(bucket.shape[0])
    if n == 0:
        return np.zeros(0, dtype=np.intp)
    starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])
    ends = np.r_[starts[1:], n] - 1
    segment = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, n]))
    keep = np.zeros(n, dtype=bool)
    keep[starts] = True
    keep[ends] = True
    for values in columns:
        v = np.asarray(values, dtype=float)
        finite = np.isfinite(v)
        low = np.where(finite, v, np.inf)
        high = np.where(finite, v, -np.inf)
        for arr, extreme in (
            (low, np.minimum.reduceat(low, starts)),
            (high, np.maximum.reduceat(high, starts)),
        ):
            _first_per_bucket(np.flatnonzero(finite & (arr == extreme[segment])), segment, keep)
        _first_per_bucket(np.flatnonzero(~finite), segment, keep)
    return np.flatnonzero(keep)


def plot_rows(time: np.ndarray, columns: Iterable[np.ndarray], buckets: int = BUCKETS) -> np.ndarray:
    """The indices of the rows a plot draws of a record (its ``time`` and the ``columns`` it
    draws): all of them up to :data:`LIMIT` rows, else :func:`extreme_rows` over ``buckets``
    equal parts of the time span."""
    n = int(time.shape[0])
    if n <= LIMIT:
        return np.arange(n)
    t = np.asarray(time, dtype=float)
    span = float(t[-1] - t[0])
    if np.isfinite(span) and span > 0:
        bucket = np.clip(((t - t[0]) / span * buckets).astype(np.int64), 0, buckets - 1)
    else:  # no usable span (a constant or broken time axis): equal counts of rows
        bucket = np.arange(n) * buckets // n
    return extreme_rows(bucket, columns)
