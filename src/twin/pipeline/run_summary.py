"""What a run amounts to: :class:`RunSummary`, the content of summary.json as a value.

The CLI prints its :meth:`~RunSummary.line`, a run folder's summary.json is its
:meth:`~RunSummary.to_json`, and a sweep takes its :meth:`~RunSummary.figures` (a flat dict
of numbers, one column each in a results table).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import platform
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from twin import __version__
from twin.outputs.summary import summary_text

__all__ = ["RunSummary", "Timing"]


@dataclass(frozen=True)
class Timing:
    """Where a run's wall time went (summary.json's ``timing``)."""

    cosim_s: float  # the co-simulation loop alone: the sinks' writing is taken out
    write_s: float  # the sinks' writing while the run went
    total_s: float  # from the process's start until the summary was made
    macro_steps: int
    fmu_steps: int
    realtime_factor: float | None  # seconds simulated by this process per second of cosim_s
    #: simulated time the process started from: a resumed run's checkpoint (``twin resume``), else
    #: the run's start (0, or ``--start-time``)
    resumed_from_s: float = 0.0
    #: the run's phases, s: FMU set-up, opening the outputs, stepping, writing while it ran, the
    #: error model, a short run's rows written after it (``last_rows``: twin.signals.recorder's
    #: hold_last), then each output file as it is closed (benchmarks/bench_phases.py reads it)
    phases_s: Mapping[str, float] = dataclasses.field(default_factory=dict)


def _versions() -> dict[str, str]:
    return {"twin": __version__, "python": platform.python_version()}


#: keys of summary.json that are not the error model's results (RunSummary's own fields)
_FIELDS = frozenset(
    {"scenario", "scenario_file", "status", "seed", "error", "sim_end_s", "errormodel_error"}
    | {"timing", "wall_s", "versions"}
)
#: results that are not figures of a run: the paper's numbers (the same in every run) and
#: which sensors the error model read
_NOT_FIGURES = frozenset({"paper_measured", "temperature_rise_C_paper", "sensors_used"})


@dataclass(frozen=True)
class RunSummary:
    """One run's summary.

    ``status`` is ``"completed"``, ``"failed"`` (``error`` says why; every row up to the
    failure was recorded and evaluated) or ``"interrupted"`` (``error`` names the signal).
    ``results`` are the error model's numbers in summary.json's order (drift, temperature
    rises, error parts, residuals, credibility, the paper's values); empty when it did not
    run, with ``errormodel_error`` saying why where there was a reason.
    """

    scenario: str
    scenario_file: str
    status: str
    seed: int
    sim_end_s: float
    timing: Timing
    error: str | None = None
    errormodel_error: str | None = None
    results: Mapping[str, Any] = field(default_factory=dict)
    versions: Mapping[str, str] = field(default_factory=_versions)

    def to_dict(self) -> dict[str, Any]:
        """summary.json's content, keys in the file's order (a fresh copy)."""
        out: dict[str, Any] = {
            "scenario": self.scenario,
            "scenario_file": self.scenario_file,
            "status": self.status,
            "seed": self.seed,
        }
        if self.error is not None:
            out["error"] = self.error
        out["sim_end_s"] = self.sim_end_s
        if self.errormodel_error is not None:
            out["errormodel_error"] = self.errormodel_error
        out.update(copy.deepcopy(dict(self.results)))
        out["timing"] = dataclasses.asdict(self.timing)
        out["wall_s"] = self.timing.total_s
        out["versions"] = dict(self.versions)
        return out

    def to_json(self) -> str:
        """The text of summary.json, byte for byte."""
        return summary_text(self.to_dict())

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> RunSummary:
        """The summary a summary.json holds (``json.loads`` of it); :meth:`to_json` gives the text back."""
        timing = data["timing"]
        return cls(
            scenario=data["scenario"],
            scenario_file=data["scenario_file"],
            status=data["status"],
            seed=data["seed"],
            sim_end_s=data["sim_end_s"],
            timing=Timing(**{f.name: timing[f.name] for f in dataclasses.fields(Timing) if f.name in timing}),
            error=data.get("error"),
            errormodel_error=data.get("errormodel_error"),
            results={k: v for k, v in data.items() if k not in _FIELDS},
            versions=dict(data["versions"]),
        )

    def figures(self, *, timings: bool = True) -> dict[str, float]:
        """The run's numbers as one flat dict: ``sim_end_s``, every number of the results by
        its dotted path (``drift_mm.predicted``, ``error_parts_mm.thermal``,
        ``compensation.residual_rms_um.after``, ``wear_mm.true``, ``temperature_rise_C.room``,
        ...) and the timings (``timing.cosim_s``). Floats throughout, NaN where a value is
        missing (a real-time factor of a run that took no time); the paper's values and the
        sensors used are left out. A run whose error model did not run has only
        ``sim_end_s`` and the timings.

        ``timings=False``: the results' numbers alone, neither ``sim_end_s`` nor the timings (a
        Monte Carlo's sample, a sweep's point: what its row keeps; the timings are not flattened
        only to be thrown away).
        """
        flat = {"sim_end_s": float(self.sim_end_s)} if timings else {}
        _flatten(self.results, "", flat)
        if timings:
            _flatten(dataclasses.asdict(self.timing), "timing.", flat)
        return flat

    def line(self) -> str:
        """A short human line for the terminal."""
        d = self.results.get("drift_mm", {})
        if "predicted" in d:
            paper = f" (paper {d['paper_measured']:+.3f} mm)" if "paper_measured" in d else ""
            return f"{self.scenario}: {self.status}; drift predicted {d['predicted']:+.4f} mm, probe {d['probe']:+.4f} mm{paper}"
        note = self.results.get("errormodel")
        if isinstance(note, str):  # a run that does not evaluate the error model says why
            why = note.removeprefix("not evaluated: ")
            return f"{self.scenario}: {self.status}; no error model or paper report ({why})"
        return f"{self.scenario}: {self.status}"


def _flatten(data: Mapping[str, Any], prefix: str, out: dict[str, float]) -> None:
    for key, value in data.items():
        if key in _NOT_FIGURES:
            continue
        # most values are plain floats and dicts: taken before the abstract types' checks
        kind = type(value)
        if kind is float:
            out[prefix + key] = value
            continue
        if kind is dict:
            _flatten(value, f"{prefix}{key}.", out)
            continue
        if isinstance(value, bool):
            continue
        if isinstance(value, Mapping):
            _flatten(value, f"{prefix}{key}.", out)
        elif value is None or isinstance(value, (int, float)):
            out[prefix + key] = math.nan if value is None else float(value)
