"""Sweeps, Monte Carlo and sensitivity analysis of scenarios on Dask distributed (``twin sweep``).

A sweep file names a base scenario and a design over keys that ``--set`` accepts
(:mod:`~twin.sweep.spec`); the design's points and seeds are drawn on the client
(:mod:`~twin.sweep.design`); each point is simulated and evaluated in memory on a Dask worker
(:mod:`~twin.sweep.point`, :mod:`~twin.sweep.execute`) with the client's binaries shipped to
it (:mod:`~twin.sweep.shipping`); the results table grows on disk as points finish
(:mod:`~twin.sweep.results`) and ends with quantiles, SALib's indices
(:mod:`~twin.sweep.analysis`) and figures (:mod:`~twin.sweep.plots`).
"""

from __future__ import annotations

from twin.sweep.runner import run_sweep
from twin.sweep.spec import Spec, load_spec

__all__ = ["Spec", "load_spec", "run_sweep"]
