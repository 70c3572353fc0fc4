"""From input to a run's files: one place that checks, the stages of one run, and many runs.

::

    source, --set ──prepare──> PreparedRun ──run──> the run folder (+ its Monte Carlo)
                                   │
                                   ├──simulate─> Simulation ─evaluate_run─> Evaluated ─summarize─> RunSummary
                                   └──run_point (a study's point, in memory; many on Dask)

- :mod:`~twin.pipeline.prepare`: :func:`prepare` turns input into a checked
  :class:`PreparedRun` (``twin validate`` is this alone), :func:`prepare_resume` a killed run;
- :mod:`~twin.pipeline.stages`: the stages of one run, composed into a run folder or in memory;
- :mod:`~twin.pipeline.run`: :func:`run`, what ``twin run`` is (the run, its Monte Carlo);
- :mod:`~twin.pipeline.montecarlo`: the uncertainty of a run's prediction;
- :mod:`~twin.pipeline.cluster`, :mod:`~twin.pipeline.shipping`, :mod:`~twin.pipeline.point`,
  :mod:`~twin.pipeline.results`: many runs on Dask (the client, the binaries shipped to the
  workers, what a worker runs for a point, the results table); :mod:`~twin.pipeline.worker_state`
  whether a worker's binaries installed, without Dask's import;
- :mod:`~twin.pipeline.compensation` (:func:`compensate`): the error model on a CSV of
  measurements, a lab's or a run's.
"""

from typing import Any

from twin.cosim.controls import RunControls
from twin.pipeline.prepare import PreparedRun, RunOptions, prepare, prepare_resume, prepare_scenario
from twin.pipeline.run import run
from twin.pipeline.run_summary import RunSummary, Timing
from twin.pipeline.stages import (
    Evaluated,
    Simulation,
    evaluate_run,
    run_into_folder,
    run_point,
    simulate,
    summarize,
    write_outputs,
)

__all__ = [
    "Evaluated",
    "PreparedRun",
    "RunControls",
    "RunOptions",
    "RunSummary",
    "Simulation",
    "Timing",
    "compensate",
    "evaluate_run",
    "prepare",
    "prepare_resume",
    "prepare_scenario",
    "run",
    "run_into_folder",
    "run_point",
    "simulate",
    "summarize",
    "write_outputs",
]


def __getattr__(name: str) -> Any:
    """:func:`compensate`, imported when first asked for: ``twin run`` does not load what only
    ``twin compensate`` uses (its streaming reader and evaluation)."""
    if name == "compensate":
        from twin.pipeline.compensation import compensate

        return compensate
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
