"""What ``twin run`` is: a prepared run into its folder, then its Monte Carlo, then what the
measured experiment it replays makes of both.

::

    PreparedRun ──run_into_folder──> the run folder (signals.csv, ..., summary.json)
         │
         └── [uncertainty] ──samples on Dask──> uncertainty.csv, the interval in summary.json
                 (each sample a prepared point: twin.pipeline.point, on twin.pipeline.cluster)
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import twin.pipeline.montecarlo as montecarlo
from twin.cosim.controls import RunControls
from twin.errors import ConfigError
from twin.outputs.run_folder import SUMMARY_JSON, UNCERTAINTY_CSV
from twin.outputs.summary import write_summary
from twin.pipeline.cluster import execute, failed, one_line, open_client
from twin.pipeline.prepare import PreparedRun, prepare_scenario
from twin.pipeline.run_summary import RunSummary
from twin.pipeline.stages import run_into_folder

__all__ = ["run", "run_samples"]


def run(
    prepared: PreparedRun,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
) -> RunSummary:
    """Run ``prepared`` into its folder, then its Monte Carlo (when it has one), and return
    the summary summary.json holds. A signal during the Monte Carlo ends it after the samples
    that finished; summary.json then says "interrupted" (the run's own outputs are complete)."""
    summary = run_into_folder(prepared, controls)
    if prepared.plots is not None:
        prepared.plots.close()  # the plots are drawn: the helper ends before the samples' workers start
        prepared.plots = None
    if prepared.uncertainty is None or summary.status != "completed" or controls.stopped() is not None:
        return summary
    assert prepared.folder is not None  # run_into_folder refuses a run without one
    data = summary.to_dict()
    mc = run_samples(prepared, controls)
    if mc["interrupted"]:
        why = f"interrupted by {mc['interrupted']} during the uncertainty's Monte Carlo (the run's own outputs are complete)"
        data.update(status="interrupted", error=why)
        write_summary(prepared.folder.file(SUMMARY_JSON), data)
        return dataclasses.replace(summary, status="interrupted", error=why)
    montecarlo.write_samples(prepared.folder.file(UNCERTAINTY_CSV), mc["rows"])
    montecarlo.add_to_summary(data, mc)
    for report in prepared.reports:
        report.add_uncertainty(data, mc["rows"])
    write_summary(prepared.folder.file(SUMMARY_JSON), data)
    line = montecarlo.line(data)
    if line is not None:
        controls.echo(line)
    return RunSummary.from_dict(data)


def run_samples(prepared: PreparedRun, controls: RunControls) -> dict[str, Any]:
    """The prepared run's Monte Carlo on Dask (a local cluster): per sample its room shape and
    figures, in sample order. ``controls.stop`` answering a signal's name ends it after the
    samples done so far (``"interrupted"`` then names it)."""
    # Dask loads here, with the Monte Carlo: a run without one and ``twin compensate`` (which
    # imports this package) never pay for distributed's import
    from twin.pipeline.point import point_task
    from twin.pipeline.shipping import BinariesPlugin, collect

    unc = prepared.uncertainty
    assert unc is not None
    names, make = montecarlo.sampler(unc, prepared.scenario)
    shapes: dict[int, str] = {}

    def payload(i: int) -> dict[str, Any]:
        try:
            scenario, shapes[i] = make(i)
        except ConfigError as exc:
            return failed(i, one_line(exc))
        return {"index": i, "run": prepare_scenario(scenario, prepared.evaluation)}

    controls.echo(f"uncertainty: {unc.samples} samples of {prepared.scenario.name} on Dask")
    start = time.perf_counter()
    records: dict[int, dict[str, Any]] = {}
    with open_client(None, None) as client:
        client.register_plugin(BinariesPlugin(collect()))
        threads = max(1, sum(client.nthreads().values()))
        for record in execute(client, range(unc.samples), payload, point_task):
            records[record["index"]] = record
            if controls.stopped() is not None:
                break  # the client closes the cluster on the way out
    rows = [
        {"sample": i, "room_shape": shapes.get(i, ""), "status": records[i]["status"],
         "error": records[i]["error"], **records[i]["figures"]}
        for i in sorted(records)
    ]  # fmt: skip
    return {
        "inputs": names,
        "rows": rows,
        "wall_s": time.perf_counter() - start,
        "workers": threads,
        "interrupted": controls.stopped(),
    }
