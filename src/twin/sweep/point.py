"""One point of a sweep: simulate and evaluate a scenario in memory, return its figures.

This is the pipeline's simulate + evaluate stages without a run folder; the figures are the
numbers of the error model's summary, flattened to dotted names
(``compensation.residual_rms_um.after``). :func:`run_point_folder` writes the usual run
folder instead (when a sweep file asks for run folders) and returns its files as bytes, so
a worker on another machine can send them back.
"""

from __future__ import annotations

import math
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from twin.config.spec import Scenario

#: the sections of a run's summary that hold figures of the run (not timings, versions or the
#: paper's constants, which are the same for every point)
FIGURE_SECTIONS = (
    "drift_mm",
    "temperature_rise_C",
    "error_parts_mm",
    "error_parts_rms_um",
    "thermal_parts_mm",
    "interference_spikes",
    "wear_mm",
    "compensation",
    "credibility",
)
_NOT_FIGURES = {"drift_mm.paper_measured"}


def flatten(summary: Mapping[str, Any]) -> dict[str, float]:
    """The numbers of a summary's figure sections as ``{"a.b.c": value}`` (booleans left out)."""
    out: dict[str, float] = {}

    def walk(prefix: str, node: Any) -> None:
        if isinstance(node, Mapping):
            for k, v in node.items():
                walk(f"{prefix}.{k}", v)
        elif isinstance(node, int | float) and not isinstance(node, bool) and prefix not in _NOT_FIGURES:
            out[prefix] = float(node)
        elif node is None:
            out[prefix] = math.nan

    for section in FIGURE_SECTIONS:
        if section in summary:
            walk(section, summary[section])
    return out


def run_point(scenario: Scenario) -> dict[str, float]:
    """Co-simulate ``scenario`` in memory, evaluate the error model, return the figures.

    Raises :class:`~twin.errors.RunError` when the run fails (an FMU error).
    """
    from twin.cosim.master import Master
    from twin.errormodel.config import evaluation_config
    from twin.errormodel.evaluate import evaluate

    cfg = evaluation_config(scenario)
    result = Master(scenario).run()
    if result.error is not None:
        raise result.error
    assert result.table is not None
    return flatten(evaluate(result.table, cfg).summary)


def run_point_folder(scenario: Scenario) -> tuple[dict[str, float], dict[str, bytes]]:
    """Like :func:`run_point`, but through the whole pipeline: the run folder's files (name ->
    bytes) come back with the figures."""
    from twin.pipeline import run

    with tempfile.TemporaryDirectory(prefix="twin-sweep-point-") as tmp:
        summary = run(scenario, Path(tmp))
        files = {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir()) if p.is_file()}
    return flatten(summary), files
