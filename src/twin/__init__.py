"""twin: co-simulation digital twin of a self-lubricating spherical plain bearing tester.

Data flow (one sub-package per stage):

- ``twin.fmu``        build the C FMUs in ``fmus/`` and load them (fmpy)
- ``twin.config``     scenario files (TOML) -> frozen, validated specs
- ``twin.cosim``      the simpy-scheduled co-simulation master
- ``twin.signals``    the signal table the master records
- ``twin.errormodel`` the paper's comprehensive (multi-body) error model
- ``twin.outputs``    CSV, summary.json, rerun recording, plots
- ``twin.cli``        the ``twin`` command
"""

from __future__ import annotations

__version__ = "0.1.0"
