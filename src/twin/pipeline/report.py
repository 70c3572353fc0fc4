"""What a measured experiment a scenario replays adds to the run's summary.

A scenario that replays a measured experiment names it in its ``[reference]`` table (the
paper's thermal experiment: ``experiment = "li2017"``). The pipeline knows no experiment: the
caller hands :func:`~twin.pipeline.prepare.prepare` a function (:data:`Reports`) that makes
the scenario's :class:`Report` objects from that table (``twin run`` hands
:func:`twin.validation.reports`); each says which recorded columns it reads, adds its figures
to the run's results before summary.json is written, and adds what the Monte Carlo says of
them (where the measured value falls in the predicted distribution).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

from twin.config.spec import Scenario
from twin.cosim.plan import Plan
from twin.signals.table import SignalTable

__all__ = ["Report", "Reports"]


class Report(Protocol):
    """One measured experiment set beside a run of the scenario that replays it.

    A report may also have ``measured_drift_m`` (the drift the experiment measured at the
    probe over the run, m) and ``measured_by`` (who, for a legend): the error-budget plot draws
    it beside the prediction."""

    def columns(self, plan: Plan) -> set[str]:
        """The recorded columns it reads (kept in memory through the run)."""
        ...

    def add(self, results: dict[str, Any], table: SignalTable) -> None:
        """Add its figures to the run's results (the error model's), from the kept columns."""
        ...

    def add_uncertainty(self, summary: dict[str, Any], samples: Sequence[Mapping[str, Any]]) -> None:
        """Add what the run's Monte Carlo (its samples' figures) says of its figures."""
        ...


#: the reports of a scenario (checked from its ``[reference]`` table; none without one)
Reports = Callable[[Scenario], Sequence[Report]]
