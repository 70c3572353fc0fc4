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
from twin.errors import RunError

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

    The FMU instances come from the process's pool (:func:`twin.fmu.pool.sweep_pool`): a
    worker's points after the first reuse the instances of the point before, reset.
    Raises :class:`~twin.errors.RunError` when the run fails (an FMU error).
    """
    from twin.fmu.pool import sweep_pool
    from twin.pipeline import run_point as simulate_and_evaluate

    summary = simulate_and_evaluate(scenario, pool=sweep_pool())
    if summary.status == "failed":
        raise RunError(summary.error or "the run failed")
    return flatten(summary.results)


def run_point_folder(scenario: Scenario) -> tuple[dict[str, float], dict[str, bytes]]:
    """Like :func:`run_point`, but through the whole pipeline: the run folder's files (name ->
    bytes) come back with the figures."""
    from twin.pipeline import run

    with tempfile.TemporaryDirectory(prefix="twin-sweep-point-") as tmp:
        summary = run(scenario, Path(tmp))
        files = {p.name: p.read_bytes() for p in sorted(Path(tmp).iterdir()) if p.is_file()}
    return flatten(summary.results), files
