"""A whole sweep: design, run every missing point on Dask, write the table, summary and plots.

The output folder holds ``sweep.json`` (what it is), ``results.parquet`` and ``results.csv``
(growing while the sweep runs), and at the end ``summary.json`` and the PNG figures; with
``run_folders = true`` in the sweep file, ``runs/point-<index>/`` holds each point's run folder.
"""

from __future__ import annotations

import functools
import importlib.util
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from twin.cosim.controls import RunControls
from twin.errors import ConfigError, did_you_mean
from twin.files import write_bytes_atomic
from twin.outputs.guard import output_dir, refuse_links
from twin.pipeline.cluster import (
    Payload,
    Record,
    StudyOptions,
    bounded_logs,
    execute,
    failed,
    one_line,
    open_client,
)
from twin.pipeline.point import point_task
from twin.pipeline.prepare import prepare_scenario
from twin.pipeline.results import ResultStore
from twin.pipeline.shipping import BinariesPlugin, collect
from twin.sweep.analysis import named_points
from twin.sweep.design import Design, fingerprint, make_design
from twin.sweep.spec import Spec

#: called after every point: (points done, of which failed, total)
Progress = Callable[[int, int, int], None]
#: the figures a sweep draws (twin.sweep.plots)
_FIGURES = ("sensitivity.png", "scatter.png", "histogram.png")


def _write_folder(out: Path, index: int, files: dict[str, bytes]) -> None:
    """A point's run folder under ``out/runs``; a symlink planted for ``runs`` or the point's
    folder is refused, one of its files replaced, never followed out of ``out``."""
    output_dir(out / "runs")  # a runs/ link planted in the output folder is refused
    folder = output_dir(out / "runs" / f"point-{index:06d}")
    for name, data in files.items():
        if Path(name).name == name:  # a plain file name: nothing lands outside the folder
            write_bytes_atomic(folder / name, data)


class _Collector:
    """Takes each finished point: its row into the table, its run folder, counts and timings."""

    def __init__(self, spec: Spec, design: Design, store: ResultStore, out: Path) -> None:
        self.spec, self.design, self.store, self.out = spec, design, store, out
        self.total, self.done = len(design), len(store)
        self.failed = store.count_failed()
        self.run = 0
        self.point_s = 0.0
        self.peak_rss_mb: dict[int, float] = {}
        self.checked = not spec.outputs
        self.start = self.begin = time.perf_counter()

    def started(self) -> None:
        """The cluster is up: the timings are the points', not the cluster's start."""
        self.start = time.perf_counter()

    def take(self, record: Record) -> None:
        if record["status"] == "ok" and not self.checked:
            try:
                check_outputs(self.spec, record["figures"])
            except ConfigError:
                self.store.discard()  # the corrected sweep file runs into the same --out
                raise
            self.checked = True
        if record.get("files"):
            _write_folder(self.out, record["index"], record["files"])
        self.store.add(self._row(record))
        self.done += 1
        self.run += 1
        self.failed += record["status"] != "ok"
        self.point_s += record.get("point_s", 0.0)
        if "pid" in record:
            pid = record["pid"]
            self.peak_rss_mb[pid] = max(self.peak_rss_mb.get(pid, 0.0), record["peak_rss_mb"])

    def _row(self, record: Record) -> dict[str, Any]:
        i = record["index"]
        figures = record["figures"]
        if self.spec.outputs:
            figures = {k: figures.get(k) for k in self.spec.outputs}
        row = {"point": i, "seed": self.design.seeds[i], "status": record["status"], "error": record["error"]}
        row.update(zip(self.design.names, self.design.rows[i], strict=True))
        row.update(figures)
        return row

    def timing(self, threads: int) -> dict[str, Any]:
        elapsed = time.perf_counter() - self.start
        run = self.run or None
        return {
            "startup_s": self.start - self.begin,
            "elapsed_s": elapsed,
            "points_run": self.run,
            "points_per_s": self.run / elapsed if elapsed > 0 else None,
            "threads": threads,
            "mean_point_s": self.point_s / run if run else None,
            # what a point costs beyond its own run: scheduling, transfer, the client's work
            "overhead_ms_per_point": (elapsed * threads - self.point_s) / run * 1e3 if run else None,
            "write_s": self.store.write_s,
            "peak_rss_mb_per_worker": sorted(self.peak_rss_mb.values()),
        }


def inputs(spec: Spec, design: Design) -> dict[str, str]:
    """What decides a row, by name (:mod:`twin.pipeline.provenance`): the sweep file's fixed
    overrides and outputs, the design (every point's values and seed), the base scenario's
    files and the scenario they make, the code that runs a point. A resume with any of them
    changed is refused, naming it."""
    from twin.outputs.run_folder import scenario_fingerprint
    from twin.pipeline.provenance import code_digests, digest, file_digests, scenario_files

    return (
        {
            "sweep.set": digest(list(spec.fixed)),
            "sweep.outputs": digest(list(spec.outputs)),
            "design": fingerprint(design),
        }
        | file_digests(scenario_files(spec.scenario.source_path))
        | {"base scenario": scenario_fingerprint(spec.scenario)[:16]}
        | code_digests()
    )


def check_outputs(spec: Spec, figures: Iterable[str]) -> None:
    """The outputs (and main output) the sweep file names are among a point's ``figures``."""
    known = set(figures)
    for key, wanted in [("sweep.outputs", o) for o in spec.outputs] + [("sweep.main", spec.main)]:
        if wanted is not None and wanted not in known:
            raise ConfigError(
                f"no figure {wanted!r}{did_you_mean(wanted, known)} (the figures are: {', '.join(sorted(known))})",
                source=str(spec.path),
                key=key,
            )


def _probe(
    spec: Spec, todo: list[int], payload: Callable[[int], Payload | Record], controls: RunControls
) -> bool:
    """Run the first point that can run here, before the cluster starts, and check the
    outputs the sweep file names against its figures (a misspelt output is bad input, found
    before anything is written). True when checked; False when that point failed (the first
    point that finishes on the cluster is checked instead)."""
    from twin.pipeline.point import figures
    from twin.pipeline.stages import run_point

    for i in todo[:8]:
        item = payload(i)
        if "status" in item:
            continue
        summary = run_point(item["run"], controls)
        if summary.status != "completed":
            return False
        check_outputs(spec, figures(summary))
        return True
    return False


class SweepInterrupted(Exception):
    """A sweep stopped by a signal (its name is the message); the finished points are kept."""


def run_sweep(
    spec: Spec,
    out: Path,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
    options: StudyOptions = StudyOptions(),  # noqa: B008
    *,
    task: Callable[[Payload], Record] = point_task,
    on_record: Callable[[Record], None] | None = None,
) -> dict[str, Any]:
    """Run ``spec`` into ``out`` and return the summary (also written to summary.json).

    ``options`` say where the points run and whether only the missing ones; ``controls``
    where to say what happens (``echo``) and when to stop: a signal's name from
    ``controls.stop`` ends the sweep after the points that finished (their table is kept)
    with :class:`SweepInterrupted`. ``task`` is what workers run per point (tests and the
    benchmark swap it); ``on_record`` sees every record as it arrives (the benchmark reads
    timings from it).
    """
    from twin.outputs.summary import write_summary
    from twin.sweep.analysis import summarise
    from twin.sweep.plots import draw_all, labels

    design = make_design(spec)
    base = prepare_scenario(spec.scenario)  # the error model's configuration, checked once
    if len(design) == 0:
        raise ConfigError("empty design: no point", source=str(spec.path))
    meta = {
        "sweep": spec.name,
        "spec_file": str(spec.path),
        "points": len(design),
        "fingerprint": fingerprint(design),
        "inputs": inputs(spec, design),
    }
    # a link planted where the sweep writes (a figure, its table, runs/) is refused before
    # any point runs: the twin writes nothing through one (twin.outputs.guard)
    refuse_links(out, ("runs", "sweep.json", "results.parquet", "results.csv", "summary.json", *_FIGURES))
    store = ResultStore(out, design.names, meta, resume=options.resume, size=len(design))
    done = store.done
    todo = [i for i in range(len(design)) if i not in done]
    collector = _Collector(spec, design, store, out)
    controls.echo(
        f"sweep {spec.name}: {len(design)} points ({spec.design}), {len(todo)} to run; results in {out}"
    )

    payload = functools.partial(_payload, spec, design, base.evaluation)
    threads = 0
    if todo and (spec.outputs or spec.main) and not store.resumed:
        collector.checked = _probe(spec, todo, payload, controls)
    collector.checked |= store.resumed  # its outputs were checked when it began
    if controls.stopped():  # a signal during the first point: no cluster to start
        raise SweepInterrupted(str(controls.stopped()))
    if not todo:
        store.start()
    try:
        if todo:
            with bounded_logs(), open_client(options.scheduler, options.workers) as client:
                threads = _announce(client, controls.echo, local=options.scheduler is None)
                client.register_plugin(BinariesPlugin(collect()))
                store.start()
                collector.started()
                records = execute(client, todo, payload, task, controls.stop)
                _take(records, collector, on_record, options.progress, controls)
                if caught := controls.stopped():
                    # before the cluster closes: its close takes seconds the command may not get
                    store.flush(force=True)
                    write_summary(out / "summary.json", interrupted(spec, collector, caught))
    finally:
        store.flush(force=True)
    if caught := controls.stopped():
        if not todo:
            write_summary(out / "summary.json", interrupted(spec, collector, caught))
        raise SweepInterrupted(caught)
    table = store.table()
    summary = summarise(spec, table, len(design), collector.timing(threads))
    write_summary(out / "summary.json", summary)
    names = labels(design.names, list(summary["outputs"]), spec.scenario)
    draw_all(out, spec.design, table, design.names, summary, names)
    return summary


def _payload(spec: Spec, design: Design, evaluation: Any, i: int) -> Payload | Record:
    """Point ``i`` prepared for a worker, or its failure record (a value its FMU refuses)."""
    try:
        point = prepare_scenario(design.point(spec.scenario, i), evaluation)
    except ConfigError as exc:
        return failed(i, one_line(exc))
    return {"index": i, "run": point, "folders": spec.run_folders}


def interrupted(spec: Spec, collector: _Collector, name: str) -> dict[str, Any]:
    """The summary of a sweep a signal stopped: how far it came (its table holds those points;
    ``twin sweep --resume`` runs the rest)."""
    return {
        "sweep": spec.name,
        "status": "interrupted",
        "error": f"interrupted by {name}",
        "points": collector.total,
        "done": collector.done,
        "failed": collector.failed,
    }


def _take(
    records: Iterable[Record],
    collector: _Collector,
    on_record: Callable[[Record], None] | None,
    progress: Progress | None,
    controls: RunControls,
) -> None:
    """Collect the records as they arrive, until the last or until a signal came."""
    for record in records:
        collector.take(record)
        if on_record is not None:
            on_record(record)
        if progress is not None:
            progress(collector.done, collector.failed, collector.total)
        collector.store.flush()
        if controls.stopped():
            return  # the caller's client closes the cluster on the way out


def _announce(client: Any, echo: Callable[[str], None], local: bool) -> int:
    """Print where the sweep runs; returns the number of worker threads."""
    from twin.pipeline.cluster import dashboard

    threads = client.nthreads()
    link = dashboard(client)
    echo(f"scheduler {client.scheduler.address}: {len(threads)} workers, {sum(threads.values())} threads")
    if link and local and importlib.util.find_spec("bokeh") is None:
        link += " (its pages need bokeh>=3.1: pip install bokeh)"
    echo(f"dashboard: {link}" if link else "dashboard: none (the scheduler serves none)")
    return max(1, sum(threads.values()))


def summary_line(summary: dict[str, Any], out: Path) -> str:
    """The sweep's last line: points, failures, time, and its main output's quantiles."""
    t = summary["timing"]
    line = (
        f"sweep {summary['sweep']}: {summary['points']} points, {summary['ok']} ok, {summary['failed']} failed"
        f" ({t['points_run']} run in {t['elapsed_s']:.1f} s)"
    )
    if summary["failed"]:
        line += f"; failed points: {named_points(summary['failed_points'])} (errors in results.csv)"
    main = summary.get("main_output")
    stats = summary["outputs"].get(main, {}) if main else {}
    if stats.get("n"):
        line += f"; {main}: median {stats['q50']:.4g}, 5-95 % [{stats['q05']:.4g}, {stats['q95']:.4g}]"
    skipped = summary.get("indices", {}).get(main, {}).get("skipped") if main else None
    if skipped:
        line += f"; no indices: {skipped}"
    return f"{line}; outputs: {out}"
