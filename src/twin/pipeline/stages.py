"""The stages of one run, each callable alone, and the two ways they compose: into a run folder
(:func:`run_into_folder`) and in memory (:func:`run_point`).

::

    PreparedRun ─simulate─> Simulation ─evaluate_run─> Evaluated ─summarize─> RunSummary
                   │ rows stream to the sinks            │                      │
                   │ (signals.csv, recording.rrd)        └─────write_outputs────┘
                                                          (errormodel.csv, PNG, summary.json)

A run folder's sinks (:mod:`twin.outputs.run_folder`) are opened by :func:`simulate` and
receive the rows while the co-simulation goes, so a killed run keeps what it recorded;
:func:`write_outputs` closes them with the run's outcome. A run that fails part way (an FMU
error) still evaluates and writes everything recorded up to the failure, with a summary
saying ``"status": "failed"`` and why; :func:`run_into_folder` then raises
:class:`~twin.errors.RunError`.
"""

from __future__ import annotations

import ctypes
import dataclasses
import functools
import time
from collections.abc import Collection, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from twin.config.spec import NS_PER_S, Scenario
from twin.cosim.controls import RunControls
from twin.cosim.master import Master, RunResult
from twin.errormodel.evaluate import evaluate, evaluate_many, evaluation_signals
from twin.errormodel.factors import FACTORS
from twin.errormodel.settings import EvaluationConfig
from twin.errors import ConfigError, RunError, TwinError
from twin.fmu.pool import SlotPool
from twin.outputs.fmi_log import FmiLogFile
from twin.outputs.plots import BudgetColumns
from twin.outputs.run_folder import (
    FMI_LOG,
    SUMMARY_JSON,
    Checkpoint,
    RunFolder,
    RunMeta,
    RunOutputs,
    scenario_fingerprint,
)
from twin.outputs.scene3d import ROLES as SCENE_ROLES
from twin.outputs.scene3d import tester_scene
from twin.outputs.sink import DISK_FULL_ERRNOS, Outcome, Sink
from twin.outputs.summary import write_summary
from twin.pipeline.prepare import PreparedRun
from twin.pipeline.run_summary import RunSummary, Timing
from twin.signals.recorder import FLUSH_ROWS, TeeRecorder
from twin.signals.table import SignalTable

__all__ = [
    "Evaluated",
    "OutputsLog",
    "Simulation",
    "evaluate_run",
    "evaluate_runs",
    "run_into_folder",
    "run_point",
    "simulate",
    "summarize",
    "write_outputs",
]


@dataclass
class Simulation:
    """What the co-simulation hands on: the master's result, the kept columns of every
    recorded row, the wall time the sinks took while it ran, and its recorder (which holds a
    short run's rows for after the plots: :func:`simulate`'s ``hold_last_rows``)."""

    prepared: PreparedRun
    result: RunResult
    table: SignalTable
    write_s: float = 0.0
    recorder: TeeRecorder | None = None


#: what summary.json and the command's line say of a run that does not evaluate the error model
NOT_EVALUATED = "not evaluated: [errormodel] evaluate = false, the scenario is not the tester"


@dataclass
class Evaluated:
    """What the error model made of a run.

    ``table`` is the simulation's table with the error model's columns added and
    ``columns`` names those (in the order the files list them; none where only the numbers
    were asked for: :func:`evaluate_run`'s ``columns``); ``results`` are its numbers
    for the summary. When the model did not run (fewer than two rows, a column it needs
    missing), ``table`` is None and ``error`` says why where there was a reason.
    """

    table: SignalTable | None
    columns: tuple[str, ...] = ()
    results: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


def simulate(
    prepared: PreparedRun,
    sinks: Sequence[Sink] = (),
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
    *,
    keep: Collection[str] | None = None,
    hold_last_rows: bool = False,
    pool: SlotPool | None = None,
) -> Simulation:
    """Co-simulate the prepared run: rows stream to ``sinks`` (opened here, closed by
    :func:`write_outputs`), the ``keep`` columns stay in memory (default: what the run reads,
    :meth:`PreparedRun.keep`).

    With ``hold_last_rows`` the rows not yet handed to the sinks when the run ends are held
    for the caller (``simulation.recorder.flush()``, which :func:`write_outputs` makes once
    the plots are begun; see :class:`~twin.signals.recorder.TeeRecorder`); a run that raises
    hands them on before it does. ``controls`` steer it; a prepared run with a folder and a
    checkpoint interval saves the whole twin there (a resumed run continues from its
    checkpoint). An FMU failure does not raise: it ends the run with ``result.status ==
    "failed"`` and the rows up to it recorded. With a ``pool`` the FMU instances are reused
    from it and given back (:mod:`twin.fmu.pool`).
    """
    resume = prepared.resume
    keep = prepared.keep() if keep is None else keep
    recorder = TeeRecorder(
        sinks,
        keep=frozenset(keep).__contains__,
        resume=resume.recorder if resume else None,
        hold_last=hold_last_rows,
    )
    folder, scenario = prepared.folder, prepared.scenario
    if folder is not None and prepared.checkpoint_every_ns:

        def save(snapshot: dict[str, Any]) -> None:
            part = recorder.checkpoint()
            folder.save_checkpoint(Checkpoint(snapshot, part, scenario.name, scenario_fingerprint(scenario)))

        controls = controls.saving(prepared.checkpoint_every_ns, save)
    master = Master(
        prepared.plan,
        recorder,
        controls,
        loop=prepared.options.loop,
        resume=resume.master if resume else None,
        pool=pool,
    )
    try:
        result = master.run()
    except BaseException as exc:
        _hand_on(recorder, exc)
        raise
    return Simulation(prepared, result, recorder.table(), recorder.write_s, recorder)


def evaluate_run(
    simulation: Simulation, cfg: EvaluationConfig | None = None, *, columns: bool = True
) -> Evaluated:
    """The error model (``cfg``, default: the prepared run's) on the simulation's kept columns
    (adds its columns to that table), then what the run's reports add.

    ``columns=False``: only the numbers are wanted (a study's point, a Monte Carlo's sample,
    whose figures are the summary's): the table is left without the model's columns, unless a
    report of the run reads them."""
    cfg = cfg or simulation.prepared.evaluation
    table = simulation.table
    if not cfg.evaluate:  # not the tester (one FMU alone): said in the summary, not an error
        return Evaluated(None, results={"errormodel": NOT_EVALUATED})
    if len(table) < 2:
        return Evaluated(None)
    columns = columns or bool(simulation.prepared.reports)
    try:
        evaluation = evaluate(table, cfg, columns=columns)
    except ConfigError as exc:
        return Evaluated(None, error=str(exc))
    if not columns:
        return Evaluated(table, (), dict(evaluation.summary))
    names = tuple(s.name for s in evaluation_signals(with_true_wear=bool(cfg.true_wear)) if s.name in table)
    results = dict(evaluation.summary)
    for report in simulation.prepared.reports:
        report.add(results, table)
    return Evaluated(table, names, results)


def evaluate_runs(simulations: Sequence[Simulation]) -> list[Evaluated] | None:
    """What :func:`evaluate_run` makes of each simulation with ``columns=False``, the same
    numbers, the error model run over all of them at once
    (:func:`~twin.errormodel.evaluate.evaluate_many`: a Monte Carlo batch's samples, one time
    axis, one error model, no report); None where they are not such runs, or where any fails
    (evaluated one by one, each says its own failure)."""
    if not simulations:
        return None
    cfg = simulations[0].prepared.evaluation
    if not cfg.evaluate or any(
        s.prepared.reports or (s.prepared.evaluation is not cfg and s.prepared.evaluation != cfg)
        for s in simulations
    ):
        return None
    try:
        summaries = evaluate_many([s.table for s in simulations], cfg)
    except Exception:  # one by one, as evaluate_run tells each run's failure
        return None
    return [Evaluated(s.table, (), summary) for s, summary in zip(simulations, summaries, strict=True)]


def summarize(
    simulation: Simulation, evaluated: Evaluated, phases: Mapping[str, float] | None = None
) -> RunSummary:
    """The run's summary; its total time counts from the prepared run's start, ``phases``
    adds to the timing's phases (the error model's and the outputs' times)."""
    result, sc = simulation.result, simulation.prepared.scenario
    error = str(result.error) if result.error is not None else None
    if result.status == "interrupted":
        error = f"interrupted by {result.info.get('interrupted_by')}"
    end_s, start_s = result.end_ns / NS_PER_S, result.start_ns / NS_PER_S
    cosim_s = result.cosim_s - simulation.write_s
    # the recorder's write_s counts its sinks' opening (the recording's blueprint) and writing
    own = {"fmu_setup": result.setup_s, "stepping": cosim_s - result.setup_s}
    # the recorder times its own opening a little inside the master's timing of it: a run that
    # wrote nothing while it ran (its rows held for after the plots) would show -1e-5 s
    own |= {"outputs_open": result.open_s, "outputs_write": max(0.0, simulation.write_s - result.open_s)}
    timing = Timing(
        cosim_s=cosim_s,
        write_s=simulation.write_s,
        total_s=time.perf_counter() - simulation.prepared.started,
        macro_steps=result.macro_steps,
        fmu_steps=result.fmu_steps,
        realtime_factor=(end_s - start_s) / cosim_s if cosim_s > 0 else None,
        resumed_from_s=start_s,
        phases_s={k: round(v, 6) for k, v in {**own, **(phases or {})}.items()},
    )
    return RunSummary(
        scenario=sc.name,
        scenario_file=sc.source_path,
        status=result.status,
        seed=sc.seed,
        sim_end_s=end_s,
        timing=timing,
        error=error,
        errormodel_error=evaluated.error,
        results=evaluated.results,
    )


@dataclass
class OutputsLog:
    """What closing the outputs took (each file's seconds, by its name) and left out (the
    files an interrupted run did not write)."""

    timings: dict[str, float] = field(default_factory=dict)
    skipped: list[str] = field(default_factory=list)


def write_outputs(
    sinks: Sequence[Sink],
    outcome: Outcome,
    controls: RunControls,
    log: OutputsLog,
    held: TeeRecorder | None = None,
) -> None:
    """Close every sink, in order, with the run's outcome (each one's time into ``log``).

    The outcome's summary is made when the first sink asks for it (the summary sink, last),
    so the summary's total time counts the writing of every other file. Once
    ``controls.stop`` answers a signal's name, the sinks that only draw what the others hold
    (``skippable``: the plots, most of what comes after the co-simulation) are left out and
    their files' names added to ``log.skipped``: an interrupted run keeps its data, not its
    pictures. Every sink is asked first whether it begins its file now
    (:meth:`~twin.outputs.sink.Sink.begin`: the plots, drawn by their own process while the
    files before them are written); a begun one is still waited for after a stop, but after
    the data files that come behind it (a short run's recording), the last sink still last.
    The rows ``held`` back at the end of the run
    (:func:`simulate`'s ``hold_last_rows``) are handed to the sinks after that, before any
    closes (their time into the log as ``last_rows``).
    """
    # a sink whose file another process makes (the plots) begins it now, to be made while the
    # files before it are written; once begun it is waited for, stop or not
    begun = {
        id(sink) for sink in sinks if not (sink.skippable and controls.stopped()) and sink.begin(outcome)
    }
    if held is not None:
        t0 = time.perf_counter()
        held.flush()
        log.timings["last_rows"] = time.perf_counter() - t0
    pending = list(sinks)
    while pending:
        sink = pending.pop(0)
        if sink.skippable and id(sink) not in begun and controls.stopped():
            log.skipped.append(sink.path.name)
            continue
        if id(sink) in begun and controls.stopped():
            # stopped while a plot is drawn: the files of the run's data that would come after
            # it (a short run's recording) are written before it is waited for, the last sink
            # (summary.json) still last; a second signal's grace may not cover both
            # (twin.cli.interrupt)
            data = {id(s) for s in pending[:-1] if not s.skippable}
            if data:
                pending = [
                    *(s for s in pending if id(s) in data),
                    sink,
                    *(s for s in pending if id(s) not in data),
                ]
                continue
        t0 = time.perf_counter()
        sink.close(outcome)
        log.timings[sink.path.name] = time.perf_counter() - t0


def budget_columns(cfg: EvaluationConfig, prepared: PreparedRun | None = None) -> BudgetColumns:
    """What the plots draw for an error model configured as ``cfg`` (and, for a run, its
    swing-cycle counter and the wear limit of wear.png)."""
    limit = prepared.scenario.wear_limit_mm if prepared is not None else None
    cycles = prepared.plan.role_columns("swing_cycles") if prepared is not None else []
    # a replayed experiment's measured drift is drawn beside the prediction (never fitted)
    measured = [
        (float(m), getattr(r, "measured_by", ""))
        for r in (prepared.reports if prepared is not None else ())
        if (m := getattr(r, "measured_drift_m", None)) is not None
    ]
    return BudgetColumns(
        reading=cfg.reading,
        predicted="errormodel.e_z",
        # a factor switched off contributes zero: listed in the legend it would look evaluated
        parts={f.label: f.column for f in FACTORS if cfg.factor_on(f.name)},
        disabled=tuple(f.name for f in FACTORS if not cfg.factor_on(f.name)),
        measured_drift_m=measured[0][0] if measured else None,
        measured_by=measured[0][1] if measured else "",
        temperatures=dict(cfg.temperatures),
        compensated="errormodel.wear_compensated",
        true_wear=cfg.true_wear,
        cycles=cycles[0] if len(cycles) == 1 else None,
        wear_limit_m=limit * 1e-3 if limit is not None else None,
    )


def run_outputs(prepared: PreparedRun) -> RunOutputs:
    """What a run folder's outputs show of the prepared run."""
    cfg = prepared.evaluation
    return RunOutputs(
        name=prepared.scenario.name,
        late_signals=tuple(evaluation_signals(with_true_wear=bool(cfg.true_wear))),
        budget_view=("errormodel.e_z", *[f.column for f in FACTORS], "errormodel.reading_change"),
        plot=budget_columns(cfg, prepared),
        scene=tester_scene(prepared.plan.roles(SCENE_ROLES)),
        signals=prepared.record,
        mat="mat" in prepared.options.formats,
        long=_rows(prepared.scenario) > FLUSH_ROWS,
    )


def _rows(scenario: Scenario) -> int:
    """About how many rows the scenario records (its duration over its output interval)."""
    return (scenario.duration_ns - scenario.start_ns) // max(1, scenario.output_interval_ns) + 1


def run_into_folder(
    prepared: PreparedRun,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
) -> RunSummary:
    """Run the prepared run into its run folder; returns the summary written there.

    Raises :class:`RunError` after writing everything recorded up to a failure (an FMU's, a
    full disk's, an output's).
    """
    folder = prepared.folder
    if folder is None:
        raise ConfigError("the run was prepared without a run folder", source=prepared.scenario.source_path)
    sinks: list[Sink] = []
    simulation: Simulation | None = None
    try:
        if prepared.resume is None:
            folder.start(_meta(prepared))
        sinks = folder.run_sinks(run_outputs(prepared), prepared.resume, prepared.plots)
        with _fmi_logging(prepared, folder, controls) as logged:
            # the last rows are written once the plots are begun: see write_outputs
            simulation = simulate(prepared, sinks, logged, hold_last_rows=True)
        summary = _finish(simulation, sinks, controls)
    except OSError as exc:
        _fail(sinks, exc, simulation)
        if exc.errno in DISK_FULL_ERRNOS:
            raise _disk_full(folder, prepared, exc) from None
        if simulation is not None:
            raise _failed_writing(folder, prepared, exc) from exc
        raise
    except BaseException as exc:
        _fail(sinks, exc, simulation)
        if simulation is not None and isinstance(exc, Exception):
            raise _failed_writing(folder, prepared, exc) from exc
        raise
    if simulation.result.error is not None:
        raise RunError(f"{simulation.result.error} (everything recorded up to it is in {folder.path})")
    return summary


def _meta(prepared: PreparedRun) -> RunMeta:
    from pathlib import Path

    options = prepared.options
    return RunMeta(
        str(Path(prepared.scenario.source_path).resolve()),
        prepared.overrides,
        options.loop,
        prepared.checkpoint_every_ns,
        options.experiment.to_json(),
        prepared.record,
        tuple(options.formats),
        options.fmi_logging,
    )


@contextmanager
def _fmi_logging(prepared: PreparedRun, folder: RunFolder, controls: RunControls) -> Iterator[RunControls]:
    """``controls`` whose ``fmi_log`` writes the run folder's fmi.log (``--fmi-logging``; a
    resumed run's continues it); closed when the FMUs are freed, and its place said."""
    if not prepared.options.fmi_logging:
        yield controls
        return
    log = FmiLogFile(folder.file(FMI_LOG), append=prepared.resume is not None)
    try:
        yield dataclasses.replace(controls, fmi_log=log)
    finally:
        log.close()
    lost = f"; writing it failed: {log.error.strerror}" if log.error is not None else ""
    controls.echo(f"fmi log: {log.messages} messages of the FMUs in {log.path}{lost}")


def _finish(simulation: Simulation, sinks: Sequence[Sink], controls: RunControls) -> RunSummary:
    """Evaluate the simulation and close the sinks with its outcome: the summary written."""
    t0 = time.perf_counter()
    evaluated = evaluate_run(simulation)
    _give_back_free_pages()
    log = OutputsLog({"errormodel": time.perf_counter() - t0})
    summary = functools.cache(
        lambda: _late_stop(summarize(simulation, evaluated, log.timings), controls, log.skipped)
    )
    outcome = Outcome(evaluated.table, evaluated.columns, lambda: summary().to_dict())
    write_outputs(sinks, outcome, controls, log, held=simulation.recorder)
    return summary()


def _give_back_free_pages() -> None:
    """Return the C heap's free pages to the system (glibc's ``malloc_trim``; elsewhere nothing).

    The error model's numpy temporaries leave about 8 MB of free pages inside the heap, which
    glibc keeps for later. The outputs (Arrow, rerun) then load while the plot helper draws:
    that overlap is the default run's peak memory (issue 32), which the pages would raise."""
    trim = getattr(ctypes.CDLL(None), "malloc_trim", None)
    if trim is not None:
        trim.argtypes, trim.restype = [ctypes.c_size_t], ctypes.c_int
        trim(0)


def _late_stop(summary: RunSummary, controls: RunControls, skipped: Sequence[str]) -> RunSummary:
    """A run whose co-simulation completed but that a signal asked to stop afterwards (while
    the error model or the outputs were made) is "interrupted" too: the signal is named. An
    interrupted run's error also names the files left out for it."""
    if summary.status == "interrupted":
        why = summary.error or "interrupted"
    elif summary.status == "completed" and (caught := controls.stopped()) is not None:
        why = f"interrupted by {caught} after the co-simulation"
    else:
        return summary
    if skipped:
        why += f" (not written: {', '.join(skipped)})"
    return dataclasses.replace(summary, status="interrupted", error=why)


def _disk_full(folder: RunFolder, prepared: PreparedRun, exc: OSError) -> RunError:
    """The error of a run stopped by a full disk (or a file-size limit), after writing what
    can be written: the sinks have cut their files back to whole rows; summary.json says so.

    No space is reserved for that summary: it is about 150 bytes, and the sinks' cutting back
    (:func:`_fail`, before this) has just freed the part of a 256 kB slice that reached the
    disk, so it fits on a disk that filled up under a run; a file-size limit is per file and
    a small file stays under it. When it still does not fit, the error says so, and the
    summary of an earlier run is gone already (the run removed it when it started)."""
    where = exc.filename or "an output file"
    status = "failed: disk full"
    try:
        write_summary(
            folder.file(SUMMARY_JSON),
            {
                "scenario": prepared.scenario.name,
                "status": status,
                "error": f"{exc.strerror} while writing {where}",
            },
        )
        note = "summary.json says so"
    except OSError:
        note = "summary.json could not be written either"
    return RunError(
        f"disk full ({exc.strerror}) while writing {where}; every whole row recorded so far is in {folder.path}; {note}"
    )


def _failed_writing(folder: RunFolder, prepared: PreparedRun, exc: Exception) -> RunError:
    """The error of a run whose co-simulation ended but whose error model or outputs failed
    (a plot that cannot be drawn): what was written stays, and summary.json says the run
    failed and why, as it does when an FMU fails, so the folder is never left without one."""
    why = str(exc) if isinstance(exc, TwinError) else f"{type(exc).__name__}: {exc}"
    if folder.file(SUMMARY_JSON).exists():  # written last: the failure came after it
        return exc if isinstance(exc, TwinError) else RunError(why)
    try:
        write_summary(
            folder.file(SUMMARY_JSON), {"scenario": prepared.scenario.name, "status": "failed", "error": why}
        )
        note = "summary.json says so"
    except OSError as other:
        note = f"summary.json could not be written either ({other.strerror})"
    if isinstance(exc, ConfigError):  # bad input stays bad input (its exit code)
        return exc
    return RunError(f"{why}; everything recorded is in {folder.path}; {note}")


def _hand_on(recorder: TeeRecorder, error: BaseException) -> None:
    """The rows ``recorder`` still holds to its sinks before the run raises ``error``: everything
    recorded before an error is kept (a failure to write them is noted on ``error``, the run's
    own error being the one to report)."""
    try:
        recorder.flush()
    except Exception as other:
        error.add_note(f"the run's last rows could not be written either: {other}")


def _fail(sinks: Sequence[Sink], error: BaseException, simulation: Simulation | None = None) -> None:
    if simulation is not None and simulation.recorder is not None:
        _hand_on(simulation.recorder, error)  # the rows held for after the plots, if still held
    for sink in sinks:
        try:
            sink.fail(error)
        except Exception as other:  # the run's own error is the one to report
            error.add_note(f"{type(sink).__name__} could not release its file either: {other}")


def run_point(
    prepared: PreparedRun,
    controls: RunControls = RunControls(),  # noqa: B008 (frozen: one shared default is safe)
    pool: SlotPool | None = None,
) -> RunSummary:
    """Simulate and evaluate the prepared run in memory, no file written (a study's point).

    A failing FMU does not raise: the summary says ``"failed"`` and why, with the figures
    of the rows recorded up to the failure. With a ``pool`` the FMU instances of the points
    before are reused (:mod:`twin.fmu.pool`).
    """
    simulation = simulate(prepared, (), controls, pool=pool)
    return summarize(simulation, evaluate_run(simulation, columns=False))
