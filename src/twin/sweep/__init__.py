"""Sweeps, Monte Carlo and sensitivity analysis of scenarios on Dask distributed (``twin sweep``).

A sweep file names a base scenario and a design over keys that ``--set`` accepts
(:mod:`~twin.sweep.spec`); the design's points and seeds are drawn on the client
(:mod:`~twin.sweep.design`); each point is simulated and evaluated in memory on a Dask worker
(:mod:`~twin.sweep.point`, :mod:`~twin.pipeline.cluster`) with the client's binaries shipped to
it (:mod:`~twin.pipeline.shipping`); the results table grows on disk as points finish
(:mod:`~twin.pipeline.results`) and ends with quantiles, SALib's indices
(:mod:`~twin.sweep.analysis`) and figures (:mod:`~twin.sweep.plots`).

Nothing heavy is imported here: ``twin --help`` imports :mod:`twin.sweep.cli`, and pandas,
SALib and Dask load only when a sweep runs.
"""

from __future__ import annotations

from typing import Any

__all__ = ["load_spec", "run_sweep"]


def __getattr__(name: str) -> Any:
    if name == "load_spec":
        from twin.sweep.spec import load_spec

        return load_spec
    if name == "run_sweep":
        from twin.sweep.runner import run_sweep

        return run_sweep
    raise AttributeError(f"module 'twin.sweep' has no attribute {name!r}")
