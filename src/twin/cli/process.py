"""Settings of a process that runs the twin alone (``twin run`` from the console script or
``python -m twin``, not a program that calls :func:`twin.cli.main`): the one place where the
process is tuned for speed. Each is measured with ``python benchmarks/bench_phases.py``; the
run's outputs do not change.

* OpenBLAS (numpy's and scipy's) on one thread (``OPENBLAS_NUM_THREADS=1``, set by
  :func:`before_numpy` before numpy loads): a run multiplies small arrays only, where a second
  BLAS thread has nothing to share, yet it spins after each call on the core the plot helper
  draws on. The plot helper inherits it; a Monte Carlo's Dask workers are set so by Dask.
* pyarrow's buffers from the system allocator (``ARROW_DEFAULT_MEMORY_POOL=system``), and
  mimalloc, which rerun allocates with, handing freed memory back after a millisecond
  (``MIMALLOC_PURGE_DELAY=1``): both allocators otherwise keep the blocks a flush of rows freed
  for a while, and the next flush comes before they are given back (the MIL endurance run's
  peak memory). Not at once (0): rerun's file writer then gave back each chunk's buffers as
  it wrote the chunk and faulted fresh pages in for the next, two thirds of the MIL endurance
  run's page faults (149,000 of the run's, 54,000 with a millisecond's delay; its peak memory
  the same within the sampling's spread). A setting the user has made in the environment
  stays theirs.
* What is imported by now lives as long as the process: it is frozen out of the garbage
  collector's walks (each full collection, and the one at exit).
"""

from __future__ import annotations

import gc
import os

__all__ = ["before_numpy", "settle"]


def before_numpy() -> None:
    """Tune this process's threads (see the module); made before numpy loads."""
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def settle() -> None:
    """Tune this process for one run (see the module); made before rerun and pyarrow load."""
    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    os.environ.setdefault("MIMALLOC_PURGE_DELAY", "1")
    gc.freeze()
