"""Output sinks of a run: ``signals.csv``, ``summary.json``, ``recording.rrd``, the error-budget PNG.

Every output is a :class:`~twin.outputs.sink.Sink` (open / write block / close with the
run's outcome / fail), one module per file format; :mod:`twin.outputs.run_folder` names the
files of a run folder and makes its sinks.

Every name is loaded on first use (PEP 562 ``__getattr__``): importing rerun and matplotlib
takes a noticeable time, which commands that never write them should not pay, and the plot
helper (:mod:`twin.outputs.plot_process`, started before the run imports numpy) needs none
of the writers.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from twin.outputs.csv import SignalsCsvWriter, read_signals_csv, units_sidecar_path, write_signals_csv
    from twin.outputs.plots import error_budget_png
    from twin.outputs.rerun_rec import RecordingWriter, read_recording, write_recording
    from twin.outputs.run_folder import RunFolder
    from twin.outputs.sink import Outcome, Sink
    from twin.outputs.summary import to_jsonable, write_summary

__all__ = [
    "Outcome",
    "RecordingWriter",
    "RunFolder",
    "SignalsCsvWriter",
    "Sink",
    "error_budget_png",
    "read_recording",
    "read_signals_csv",
    "to_jsonable",
    "units_sidecar_path",
    "write_recording",
    "write_signals_csv",
    "write_summary",
]

_LAZY = {
    "SignalsCsvWriter": "twin.outputs.csv",
    "read_signals_csv": "twin.outputs.csv",
    "units_sidecar_path": "twin.outputs.csv",
    "write_signals_csv": "twin.outputs.csv",
    "RunFolder": "twin.outputs.run_folder",
    "Outcome": "twin.outputs.sink",
    "Sink": "twin.outputs.sink",
    "to_jsonable": "twin.outputs.summary",
    "write_summary": "twin.outputs.summary",
    "RecordingWriter": "twin.outputs.rerun_rec",
    "read_recording": "twin.outputs.rerun_rec",
    "write_recording": "twin.outputs.rerun_rec",
    "error_budget_png": "twin.outputs.plots",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(module), name)
