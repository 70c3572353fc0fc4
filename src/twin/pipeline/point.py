"""What a Dask worker runs for one point of a study: a prepared run, in memory, to its figures;
and points run in process, their FMUs stepped together (:func:`batch_tasks`).

A point is a :class:`~twin.pipeline.prepare.PreparedRun` without a folder (a sweep's point, a
Monte Carlo's sample); its figures are the numbers of its summary's results, flattened to
dotted names (``compensation.residual_rms_um.after``; :meth:`RunSummary.figures`), timings
left out. A sweep that asks for run folders gets each point's folder back as bytes, so a
worker on another machine can send them. A point whose payload has ``end_figures_s`` (a Monte
Carlo's sample) reports the figures read off its record's ends alone
(:data:`twin.errormodel.evaluate.END_FIGURES`), and a batch records only the rows they read: those within
``end_figures_s`` of either end (None: every row).
"""

from __future__ import annotations

import os
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.cosim.batch import Batch, structure, unbatchable
from twin.errormodel.evaluate import end_figures
from twin.errors import RunError
from twin.fmu.pool import SlotPool, sweep_pool
from twin.pipeline.cluster import Payload, Record, one_line, peak_rss_mb
from twin.pipeline.prepare import PreparedRun, RunOptions, prepare
from twin.pipeline.run_summary import RunSummary
from twin.pipeline.stages import (
    Simulation,
    evaluate_run,
    evaluate_runs,
    run_into_folder,
    run_point,
    summarize,
)
from twin.pipeline.worker_state import check_worker

__all__ = ["Tasks", "abandon", "batch_tasks", "figures", "finish_tasks", "point_task", "start_tasks"]


def figures(summary: RunSummary) -> dict[str, float]:
    """A point's figures: its summary's numbers, without the timings."""
    figures = summary.figures(timings=False)
    return {k: v for k, v in figures.items() if not k.startswith("timing.") and k != "sim_end_s"}


def _in_memory(prepared: PreparedRun) -> dict[str, float]:
    """Run the point in memory with the worker's pooled FMU instances (a worker's points after
    the first reuse the instances of the point before, reset); a failed run raises."""
    summary = run_point(prepared, pool=sweep_pool())
    if summary.status == "failed":
        raise RunError(summary.error or "the run failed")
    return figures(summary)


def _with_folder(prepared: PreparedRun) -> tuple[dict[str, float], dict[str, bytes]]:
    """Run the point through the whole pipeline into a temporary run folder; its figures and
    its files (name -> bytes)."""
    with tempfile.TemporaryDirectory(prefix="twin-point-") as tmp:
        options = RunOptions(folder=True, out=Path(tmp), force=True, check_fmus=False)
        with prepare(prepared.scenario, (), options) as point:
            summary = run_into_folder(point)
        files = {
            p.name: p.read_bytes()
            for p in sorted(Path(tmp).iterdir())
            if p.is_file() and not p.name.startswith(".")
        }
    return figures(summary), files


def point_task(payload: Payload) -> Record:
    """What a worker runs for one point (``payload``: its ``index``, the prepared ``run``,
    whether it wants its ``folders`` and whether it reports its ``end_figures_s`` only): never
    raises, a failure is a failed record.

    Returns the figures, the run folder's files when asked, and for the benchmark the seconds
    the point took and the worker process's peak resident memory.
    """
    start = time.perf_counter()
    record: dict[str, Any] = {
        "index": payload["index"],
        "status": "ok",
        "error": "",
        "figures": {},
        "files": {},
    }
    try:
        check_worker()
        if payload.get("folders"):
            record["figures"], record["files"] = _with_folder(payload["run"])
        else:
            record["figures"] = _in_memory(payload["run"])
        if "end_figures_s" in payload:
            record["figures"] = end_figures(record["figures"])
    except Exception as exc:
        record.update(status="failed", error=one_line(exc))
    record["point_s"] = time.perf_counter() - start
    record["pid"] = os.getpid()
    record["peak_rss_mb"] = peak_rss_mb()
    return record


@dataclass
class Tasks:
    """Points on their way (:func:`start_tasks`): the records of those that ran alone, and
    each batch of the others with its points and the thread stepping it."""

    payloads: list[Payload]
    records: dict[int, Record] = field(default_factory=dict)
    batches: list[tuple[Batch, list[Payload], threading.Thread]] = field(default_factory=list)
    errors: list[BaseException] = field(default_factory=list)
    start: float = field(default_factory=time.perf_counter)


def start_tasks(payloads: list[Payload], pool: SlotPool, files: dict[str, Path] | None = None) -> Tasks:
    """Start in-memory points (``payloads`` as :func:`point_task` takes them) in this process:
    the points of one structure (a Monte Carlo's samples) are loaded as one batch
    (:class:`twin.cosim.batch.Batch`: each point's rows bit for bit its own run's) whose ticks
    run in a thread of their own, while the caller goes on (evaluating the batch before: the
    compiled stepper releases the interpreter's lock); a point that cannot join a batch runs
    alone through :func:`point_task`, now. :func:`finish_tasks` gives the records. ``files``
    (shared by the caller's calls) keeps the models' files the first batch found."""
    tasks = Tasks(payloads)
    groups: dict[tuple[object, ...], list[Payload]] = {}
    for payload in payloads:
        plan = payload["run"].plan
        if payload.get("folders") or unbatchable(plan) is not None:
            tasks.records[payload["index"]] = point_task(payload)
        else:
            ends = ("end_figures_s" in payload, payload.get("end_figures_s"))
            groups.setdefault((structure(plan), ends), []).append(payload)
    try:
        for (_, (_, ends_s)), group in groups.items():
            runs: list[PreparedRun] = [p["run"] for p in group]
            keep = set().union(*(run.keep() for run in runs))
            batch = Batch([run.plan for run in runs], keep, pool, ends_s, files)
            thread = threading.Thread(target=_attempt, args=(batch, tasks.errors))
            tasks.batches.append((batch, group, thread))
            batch.open()
            thread.start()
    except BaseException:  # a signal while loading: what was started is given back
        abandon(tasks)
        raise
    return tasks


def _attempt(batch: Batch, errors: list[BaseException]) -> None:
    try:
        batch.attempt()
    except BaseException as exc:  # handed to finish_tasks, raised in the caller's thread
        errors.append(exc)


def finish_tasks(tasks: Tasks) -> list[Record]:
    """The records of started points, in their order: each batch's points evaluated as
    :func:`point_task` evaluates one; a point whose FMUs failed in its batch runs alone
    through :func:`point_task` (the master says how it fails)."""
    try:
        for batch, group, thread in tasks.batches:
            thread.join()
            if tasks.errors:
                raise tasks.errors[0]
            batch.step()  # a copy that failed: the others again without it
            done = batch.results()
            each = (time.perf_counter() - tasks.start) / max(len(tasks.payloads), 1)
            ran = {
                j: Simulation(payload["run"], result, result.table)
                for j, payload in enumerate(group)
                if (result := done.results.get(j)) is not None
            }
            # the batch's samples evaluated together where they can be (their numbers are
            # each one's own), else one by one
            together = dict(zip(ran, evaluate_runs(list(ran.values())) or (), strict=False))
            for j, payload in enumerate(group):
                simulation = ran.get(j)
                if simulation is None:
                    tasks.records[payload["index"]] = point_task(payload)
                    continue
                record = _record(payload["index"])
                try:
                    evaluated = together.get(j) or evaluate_run(simulation, columns=False)
                    record["figures"] = figures(summarize(simulation, evaluated))
                    if "end_figures_s" in payload:  # the others were read off the rows kept
                        record["figures"] = end_figures(record["figures"])
                except Exception as exc:
                    record.update(status="failed", error=one_line(exc))
                record["point_s"] = each
                tasks.records[payload["index"]] = record
    finally:
        abandon(tasks)
    return [tasks.records[p["index"]] for p in tasks.payloads]


def abandon(tasks: Tasks) -> None:
    """Wait for every batch's thread (its ticks cannot be cut short: a batch takes tenths of a
    second) and give its instances back (idempotent)."""
    for batch, _, thread in tasks.batches:
        if thread.ident is not None:
            thread.join()
        batch.close()


def batch_tasks(payloads: list[Payload], pool: SlotPool) -> list[Record]:
    """The records of in-memory points run in this process: :func:`start_tasks`, then
    :func:`finish_tasks`."""
    return finish_tasks(start_tasks(payloads, pool))


def _record(index: int) -> Record:
    return {"index": index, "status": "ok", "error": "", "figures": {}, "files": {}, "pid": os.getpid()}
