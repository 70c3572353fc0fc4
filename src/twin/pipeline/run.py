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
import gc
import json
import os
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import twin.pipeline.montecarlo as montecarlo
from twin.config.spec import NS_PER_S
from twin.cosim.controls import RunControls
from twin.errormodel.evaluate import end_reach_s
from twin.errors import ConfigError
from twin.outputs.run_folder import SUMMARY_JSON, UNCERTAINTY_CSV
from twin.outputs.summary import write_summary
from twin.pipeline.cluster import bounded_logs, execute, failed, one_line, open_client
from twin.pipeline.prepare import PreparedRun, prepare_scenario
from twin.pipeline.run_summary import RunSummary
from twin.pipeline.stages import run_into_folder
from twin.uncertainty.testers import apply

__all__ = ["mark_interrupted", "run", "run_samples"]

#: why a run whose own outputs are complete is "interrupted" (its Monte Carlo is not)
_DURING_MC = "interrupted by {} during the uncertainty's Monte Carlo (the run's own outputs are complete)"


def run(
    prepared: PreparedRun,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
) -> RunSummary:
    """Run ``prepared`` into its folder, then its Monte Carlo (when it has one), and return
    the summary summary.json holds. A signal during the Monte Carlo ends it at once (the
    samples' cluster is closed after summary.json says "interrupted": the run's own outputs
    are complete); a signal that comes after the run's own outputs, before its Monte Carlo,
    makes it "interrupted" too: a summary never says "completed" of a command a signal ended."""
    # the samples' draws before the run (the prior file read, every tester drawn): this
    # process is done with its own outputs before the plot helper has drawn (it imports
    # matplotlib meanwhile), and would otherwise wait for it
    sampling = _sampling(prepared) if prepared.uncertainty is not None else None
    summary = run_into_folder(prepared, controls)
    if prepared.plots is not None:
        prepared.plots.close()  # the plots are drawn: the helper ends before the samples' workers start
        prepared.plots = None
    if summary.status != "completed":
        return summary
    assert prepared.folder is not None  # run_into_folder refuses a run without one
    data = summary.to_dict()
    path = prepared.folder.file(SUMMARY_JSON)

    def interrupted(name: str) -> RunSummary:
        why = _DURING_MC.format(name) if prepared.uncertainty is not None else _AFTER.format(name)
        write_summary(path, data | {"status": "interrupted", "error": why})
        return dataclasses.replace(summary, status="interrupted", error=why)

    if (caught := controls.stopped()) is not None:
        return interrupted(caught)
    if prepared.uncertainty is None:
        return summary
    stopped: list[RunSummary] = []
    mc = run_samples(prepared, controls, lambda name: stopped.append(interrupted(name)), sampling)
    if stopped:
        return stopped[0]
    montecarlo.write_samples(prepared.folder.file(UNCERTAINTY_CSV), mc["rows"])
    montecarlo.add_to_summary(data, mc)
    for report in prepared.reports:
        report.add_uncertainty(data, mc["rows"])
    write_summary(prepared.folder.file(SUMMARY_JSON), data)
    line = montecarlo.line(data)
    if line is not None:
        controls.echo(line)
    return RunSummary.from_dict(data)


def _sampling(prepared: PreparedRun) -> tuple[dict[str, str], montecarlo.Maker]:
    """The Monte Carlo's input groups and its sampler (:func:`montecarlo.sampler`): the prior
    is drawn around the scenario before an updated tester's values were set."""
    assert prepared.uncertainty is not None
    return montecarlo.sampler(prepared.uncertainty, prepared.prior_scenario or prepared.scenario)


def run_samples(
    prepared: PreparedRun,
    controls: RunControls,
    on_stop: Callable[[str], Any] | None = None,
    sampling: tuple[dict[str, str], montecarlo.Maker] | None = None,
) -> dict[str, Any]:
    """The prepared run's Monte Carlo: per sample its room shape and figures, in sample order.

    Samples run in this process, :data:`IN_PROCESS_BATCH` at a time with their FMUs stepped
    together (:func:`twin.pipeline.point.batch_tasks`; prior and updated sample ``i`` in one
    batch: :func:`_batches`), for as long as the samples left would
    take less than a local cluster saves: then the rest go to Dask (:func:`_cluster_pays`).
    ``controls.stop`` answering a signal's name ends it after the samples done so far
    (``"interrupted"`` then names it); ``on_stop(name)`` is called then, before a cluster
    closes (closing it takes seconds the command may not be given); ``sampling``, its sampler
    made already (:func:`_sampling`)."""
    unc = prepared.uncertainty
    assert unc is not None
    # the updated prediction's sample i is prior sample i with the tester's posterior draw i set
    groups, make = sampling if sampling is not None else _sampling(prepared)
    tester = prepared.tester
    updated = min(unc.samples, len(tester.draws)) if tester is not None else 0
    makers = {montecarlo.PRIOR: make}
    if tester is not None and updated:
        makers = _paired_draws(make, updated)
        makers[montecarlo.UPDATED] = montecarlo.updated_sampler(makers[montecarlo.UPDATED], tester)
    total = unc.samples + updated

    def which(i: int) -> tuple[str, int]:
        return (montecarlo.PRIOR, i) if i < unc.samples else (montecarlo.UPDATED, i - unc.samples)

    # a sample reports its drift and parts (montecarlo.SAMPLE_COLUMNS), not the credibility
    # indexes: their Frechet recursion would be half of each sample's evaluation
    evaluation = dataclasses.replace(prepared.evaluation, credibility=False)
    # nor any figure that reads every row (the parts' rms, the spikes, the residuals): its
    # figures are read off its record's ends, and a batch records the rows there only (the DAQ's
    # noise, the rows' copies and the error model then cost a thirtieth in the paper's replay)
    ends_s = end_reach_s(evaluation, prepared.scenario.output_interval_ns / NS_PER_S)
    shapes: dict[int, str] = {}
    drawn: dict[int, dict[str, float]] = {}
    # the samples share their structure (only values differ): each plan is made from the last
    last: list[PreparedRun] = []

    def payload(i: int) -> dict[str, Any]:
        try:
            predictive, j = which(i)
            scenario, shapes[i], drawn[i] = makers[predictive](j)
        except ConfigError as exc:
            return failed(i, one_line(exc))
        point = prepare_scenario(scenario, evaluation, last[0].plan if last else None)
        last[:] = [point]
        return {"index": i, "run": point, "end_figures_s": ends_s}

    told = f" and {updated} of the updated tester's posterior" if updated else ""
    controls.echo(f"uncertainty: {unc.samples} prior samples{told} of {prepared.scenario.name}")
    start = time.perf_counter()
    progress = montecarlo.Progress(total, controls.echo, start)
    records: dict[int, dict[str, Any]] = {}
    # what lives now (the modules, the nominal run) lives through the samples: kept out of the
    # collector's full passes, which would walk it again and again while the samples come and go
    gc.freeze()
    try:
        left = _in_process(_batches(unc.samples, updated), payload, controls, records, progress)
    finally:
        gc.unfreeze()
    threads = 1
    if left and controls.stopped() is None:
        controls.echo(f"uncertainty: the other {len(left)} samples on Dask (a local cluster)")
        threads = _on_dask(left, payload, controls, records, progress, on_stop)
    elif (caught := controls.stopped()) is not None and on_stop is not None:
        on_stop(caught)
    rows = [
        {"sample": which(i)[1], "predictive": which(i)[0], "room_shape": shapes.get(i, ""),
         "status": records[i]["status"], "error": records[i]["error"], **records[i]["figures"],
         **drawn.get(i, {})}
        for i in sorted(records)
    ]  # fmt: skip
    return {
        "inputs": [n for n in groups if n not in montecarlo.ROOM_INPUTS and n != montecarlo.NOISE_INPUT],
        "groups": groups,
        "rows": rows,
        "wall_s": time.perf_counter() - start,
        "workers": threads,
        "interrupted": controls.stopped(),
        "tester": str(tester.path) if tester is not None else None,
    }


#: samples a batch in process holds at most: their FMUs stepped together, the progress told and
#: a signal heeded between two batches (a batch of the paper replay takes a few tenths of a second)
IN_PROCESS_BATCH = 20
#: batches whose ticks run ahead of the one the error model evaluates: with one, the stepping
#: thread of a batch that finished early left its core idle until the next batch was opened
#: (the paper replay's run waited about 10 ms on every other batch, 0.13 s in all); with two,
#: a batch is always stepping
STEPPED_AHEAD = 2
#: what a local cluster costs before its first sample, s: its worker processes start and
#: import the twin (about a second and a half of both cores on the developers' 2-core machine),
#: with a margin for its scheduler
CLUSTER_START_S = 3.0
#: what a sample costs on a worker, in CPU, over its cost in a batch in process: there the master
#: runs it alone, its task is made and shipped from this process (measured on the paper replay)
ON_DASK = 1.3


def _cluster_pays(
    left: int, wall_s: float, cpu_s: float, cores: int | None = None, others: float = 0.0
) -> bool:
    """Whether ``left`` samples finish sooner on a local cluster of one worker per core than
    in process, where a sample took ``wall_s`` (its batch's ticks already run beside the batch
    before: two threads) and ``cpu_s`` CPU seconds: on the cluster each costs :data:`ON_DASK`
    times that CPU, shared out over the cores other work leaves free (``others``: the cores
    other processes kept busy meanwhile; at least one), and what that saves must exceed the
    cluster's start. A machine busy with other work stretches a sample's wall time in process,
    but gives the workers no more cores: counted on every core, a loaded machine sent its
    samples to a cluster that took longer still."""
    n = cores if cores is not None else (os.cpu_count() or 1)
    free = max(1.0, n - others)
    return left * (wall_s - cpu_s * ON_DASK / free) > CLUSTER_START_S


def _machine_busy_s() -> float | None:
    """CPU seconds every process of the machine has run since it started (Linux's /proc/stat:
    all but idle and waiting for disks), or None where that cannot be read."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            fields = f.readline().split()
        ticks = [int(x) for x in fields[1:9]]
    except (OSError, ValueError):
        return None
    if len(ticks) < 5:
        return None
    return (sum(ticks) - ticks[3] - ticks[4]) / os.sysconf("SC_CLK_TCK")


def _others(busy0: float | None, busy1: float | None, cpu_s: float, wall_s: float) -> float:
    """The cores other processes kept busy over ``wall_s``, from the machine's busy time
    (:func:`_machine_busy_s` before and after) less this process's ``cpu_s``; 0 unknown."""
    if busy0 is None or busy1 is None or wall_s <= 0:
        return 0.0
    return max(0.0, (busy1 - busy0 - cpu_s) / wall_s)


def _paired_draws(make: montecarlo.Maker, updated: int) -> dict[str, montecarlo.Maker]:
    """Prior sample ``i``'s draw for the prior and for the updated prediction (what its updated
    sample sets the posterior on): made once, kept from the prior sample to the updated one
    (the two come in one batch: :func:`_batches`), which sets the posterior on it; made again,
    with the posterior at once, where the prior's was not kept."""
    kept: dict[int, montecarlo.Draw] = {}

    def prior(i: int, posterior: Mapping[str, float] | None = None) -> montecarlo.Draw:
        draw = make(i, posterior)
        if i < updated:
            kept[i] = draw
        return draw

    def again(i: int, posterior: Mapping[str, float] | None = None) -> montecarlo.Draw:
        draw = kept.pop(i, None)
        if draw is None:
            return make(i, posterior)
        if posterior is None:
            return draw
        return montecarlo.Draw(apply(draw.scenario, posterior), draw.room_shape, draw.inputs | posterior)

    return {montecarlo.PRIOR: prior, montecarlo.UPDATED: again}


def _batches(prior: int, updated: int) -> list[list[int]]:
    """The Monte Carlo's samples (``prior`` ones, then ``updated`` ones: sample ``prior + i``
    is prior sample ``i`` with the tester's posterior draw ``i`` set), batch by batch, at most
    :data:`IN_PROCESS_BATCH` and a tenth of them a batch (the progress is told every tenth).

    Prior sample ``i`` and updated sample ``i`` fall in one batch: the posterior sets some
    FMUs' parameters only, so the others' runs are the same in both and a batch runs them
    once (:func:`twin.cosim.batch.identities`)."""
    size = max(1, min(IN_PROCESS_BATCH, (prior + updated) // 10))
    pairs = min(size // 2, updated)
    out: list[list[int]] = []
    for j in range(0, updated if pairs else 0, max(pairs, 1)):
        drawn = range(j, min(j + pairs, updated))
        out.append([*drawn, *(prior + i for i in drawn)])
    rest = list(range(updated, prior) if pairs else range(prior + updated))  # a batch of one: no pairs
    out += [rest[j : j + size] for j in range(0, len(rest), size)]
    return out


@dataclasses.dataclass
class _Pace:
    """The samples run in process so far (from the second batch: the first also made the
    pool's instances), their CPU and wall seconds and the machine's busy seconds meanwhile,
    summed: the choice of a cluster is made on them all, not on one batch that a burst of
    other work (a compiler, another test) stretched, which once sent a loaded machine's last
    samples to a cluster that had no free core either."""

    samples: int = 0
    cpu_s: float = 0.0
    wall_s: float = 0.0
    busy_s: float | None = 0.0  # None: the machine's busy time is not known

    def add(self, samples: int, cpu_s: float, wall_s: float, busy_s: float | None) -> None:
        self.samples += samples
        self.cpu_s += cpu_s
        self.wall_s += wall_s
        self.busy_s = None if busy_s is None or self.busy_s is None else self.busy_s + busy_s

    def cluster_pays(self, left: int) -> bool:
        """Whether the ``left`` samples would finish sooner on a local cluster
        (:func:`_cluster_pays` on the samples so far)."""
        if not self.samples:
            return False
        others = _others(0.0, self.busy_s, self.cpu_s, self.wall_s) if self.busy_s is not None else 0.0
        return _cluster_pays(left, self.wall_s / self.samples, self.cpu_s / self.samples, others=others)


def _in_process(
    batches: list[list[int]],
    payload: Callable[[int], dict[str, Any]],
    controls: RunControls,
    records: dict[int, dict[str, Any]],
    progress: montecarlo.Progress,
) -> list[int]:
    """Run the samples in this process, ``batches`` in turn, into ``records``, until none is
    left, a signal stops it or a cluster pays for the rest (:func:`_cluster_pays`); returns
    the samples left. A batch's ticks run (in a thread of their own) while the batches before
    are evaluated, :data:`STEPPED_AHEAD` of them in flight: the FMUs' stepping and the error
    model's Python share the two cores."""
    from twin.fmu.pool import SlotPool
    from twin.pipeline.point import Tasks, abandon, finish_tasks, start_tasks

    size = max((len(b) for b in batches), default=1)
    # the batches stepped ahead and the one being started hold their instances at once
    pool = SlotPool(per_key=(STEPPED_AHEAD + 1) * size)
    waiting = list(batches)
    left = [i for b in batches for i in b]
    batches_done = 0
    pending: list[Tasks] = []  # started, oldest first
    pace = _Pace()
    files: dict[str, Path] = {}  # the models' files, found by the first batch for all of them

    def finish(tasks: Tasks) -> None:
        for record in finish_tasks(tasks):
            records[record["index"]] = record
        progress.done(len(records))

    try:
        while waiting and controls.stopped() is None:
            # its wall time and its CPU time (every thread's): a machine busy with other work
            # makes a sample slower in process and on a cluster alike
            t0, w0, b0 = time.process_time(), time.perf_counter(), _machine_busy_s()
            batch = waiting.pop(0)
            left = left[len(batch) :]
            items = [payload(i) for i in batch]
            records.update({r["index"]: r for r in items if "status" in r})
            pending.append(start_tasks([p for p in items if "status" not in p], pool, files))
            if len(pending) > STEPPED_AHEAD:
                finish(pending.pop(0))
            # judged once a batch is finished in each turn: the turns before evaluated none
            batches_done += 1
            b1 = _machine_busy_s()
            if batches_done <= STEPPED_AHEAD:
                continue
            busy = b1 - b0 if b0 is not None and b1 is not None else None
            pace.add(len(batch), time.process_time() - t0, time.perf_counter() - w0, busy)
            if pace.cluster_pays(len(left)):
                break
        while pending and controls.stopped() is None:
            finish(pending.pop(0))  # finish_tasks gives its instances back even when it raises
    finally:
        for tasks in pending:
            abandon(tasks)
        pool.clear()
    return left


def _on_dask(
    indices: list[int],
    payload: Callable[[int], dict[str, Any]],
    controls: RunControls,
    records: dict[int, dict[str, Any]],
    progress: montecarlo.Progress,
    on_stop: Callable[[str], Any] | None,
) -> int:
    """Run the samples on a local cluster into ``records``; returns its worker threads."""
    # Dask loads here: a Monte Carlo that stays in process never pays for distributed's import
    from twin.pipeline.point import point_task
    from twin.pipeline.shipping import BinariesPlugin, collect

    with bounded_logs(), open_client(None, None) as client:
        client.register_plugin(BinariesPlugin(collect()))
        threads = max(1, sum(client.nthreads().values()))
        for record in execute(client, indices, payload, point_task, controls.stop):
            records[record["index"]] = record
            progress.done(len(records))
            if controls.stopped() is not None:
                break
        if (caught := controls.stopped()) is not None and on_stop is not None:
            on_stop(caught)  # the client closes the cluster on the way out
    return threads


#: why a run without a Monte Carlo whose outputs are complete is "interrupted"
_AFTER = "interrupted by {} after the run's outputs were written (they are complete)"


def mark_interrupted(folder: Path, name: str, monte_carlo: bool, scenario: str) -> str | None:
    """Make the run folder's summary.json say "interrupted" (by the signal ``name``) where it
    says "completed" (the run's own outputs, before or during its ``monte_carlo``), or write a
    short one where the run had not written its own yet (as a failed run's, so the folder is
    never left without one): what the signal's watcher does when it has to end a ``twin run``
    itself (a stretch that did not stop in time). Returns why the run is "interrupted" (None
    when its summary says it failed)."""
    path = folder / SUMMARY_JSON
    if not path.exists():
        why = f"interrupted by {name} while the run was under way (what it had recorded is kept)"
        write_summary(path, {"scenario": scenario, "status": "interrupted", "error": why})
        return why
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict):
        return None
    if data.get("status") != "completed":  # "interrupted" already, or "failed" (its error says more)
        return str(data.get("error")) if data.get("status") == "interrupted" else None
    why = (_DURING_MC if monte_carlo else _AFTER).format(name)
    write_summary(path, data | {"status": "interrupted", "error": why})
    return why
