"""twin: co-simulation digital twin of a self-lubricating spherical plain bearing tester.

Data flow, one sub-package per stage, each importing only those listed below it:

- ``twin.cli``          the ``twin`` command: one module per command, parsing and printing
- ``twin.calibration``  the makers of parameter and coefficients files (geometry, calibrate, identify)
- ``twin.sweep``        sweeps, Monte Carlo and sensitivity analysis on Dask
- ``twin.validation``   held-out testers, the paper's experiment beside its replay
- ``twin.pipeline``     prepare (input -> a checked run), the stages of a run, many runs on Dask
- ``twin.errormodel``   the paper's comprehensive (multi-body) error model
- ``twin.cosim``        the simpy-scheduled co-simulation master
- ``twin.outputs``      the run folder: CSV, summary.json, rerun recording, plots
- ``twin.uncertainty``  what is not known of a tester: spreads, testers as built, room curves
- ``twin.exchange``     a scenario's system as SSP for other FMI tools
- ``twin.config``       scenario files (TOML, SSP) -> a checked scenario value; the one reader
- ``twin.fmu``          the C FMUs in ``fmus/``: described, built, loaded (fmpy)
- ``twin.signals``      the signal table the master records
- ``twin.errors``, ``twin.seeds``, ``twin.files``, ``twin.paper``: errors, seeds, atomic
  writes, the seed paper's numbers

Sources: "facts N" in the code is section N of ``docs/reference/facts.md``.
"""

from __future__ import annotations

__version__ = "0.1.0"
