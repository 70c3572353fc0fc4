"""Runs for the tests, through the twin's own front door: :func:`twin.pipeline.prepare` then
:func:`twin.pipeline.run` (what ``twin run`` does), or a point in memory."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from twin.config.spec import Scenario
from twin.pipeline import RunControls, RunOptions, RunSummary, prepare, prepare_scenario, run, run_point
from twin.validation import reports


def run_into(
    scenario: Scenario | str | Path | None,
    out: Path,
    overrides: Sequence[str] = (),
    controls: RunControls = RunControls(),  # noqa: B008
    **options: Any,
) -> RunSummary:
    """Run ``scenario`` into the run folder ``out`` as ``twin run`` does (its reports, an
    earlier run replaced, no Monte Carlo unless ``samples`` asks for one)."""
    options = {"samples": 0, "force": True, "reports": reports} | options
    with prepare(scenario, overrides, RunOptions(folder=True, out=out, **options), controls) as prepared:
        return run(prepared, controls)


def point(scenario: Scenario, **kw: Any) -> RunSummary:
    """``scenario`` simulated and evaluated in memory (a study's point)."""
    return run_point(prepare_scenario(scenario), **kw)
