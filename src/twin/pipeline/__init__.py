"""A run from scenario to files, as stages with typed hand-offs.

::

    Scenario ──simulate──> Simulation ──evaluate_run──> Evaluated ──summarize──> RunSummary
       │           │                                        │                        │
       │      rows stream to the sinks                      └──────write_outputs─────┘
       │      (signals.csv, recording.rrd)                   (errormodel.csv, PNG, summary.json)
       └── twin.config.load.load_scenario

:func:`run` composes them into a run folder (:mod:`twin.outputs.run_folder`),
:func:`resume_run` continues one from its checkpoint, :func:`run_point` simulates and
evaluates in memory (a sweep's point), :func:`compensate` evaluates a CSV of measurements.
"""

from twin.pipeline.compensation import compensate
from twin.pipeline.run_summary import RunSummary, Timing
from twin.pipeline.stages import (
    Evaluated,
    Simulation,
    evaluate_run,
    resume_run,
    run,
    run_point,
    simulate,
    summarize,
    write_outputs,
)

__all__ = [
    "Evaluated",
    "RunSummary",
    "Simulation",
    "Timing",
    "compensate",
    "evaluate_run",
    "resume_run",
    "run",
    "run_point",
    "simulate",
    "summarize",
    "write_outputs",
]
