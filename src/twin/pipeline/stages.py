"""The stages of a run, each callable alone, and :func:`run` that composes them.

::

    load_scenario ─> simulate ─────────> evaluate_run ─> summarize ─> write_outputs
    (twin.config)    (the master plans    (the error      RunSummary   (close every sink
                      and steps; rows     model on the                  with the outcome)
                      stream to sinks)    kept columns)

A run folder's sinks (:mod:`twin.outputs.run_folder`) are opened by :func:`simulate` and
receive the rows while the co-simulation goes, so a killed run keeps what it recorded;
:func:`write_outputs` closes them with the run's outcome. :func:`run_point` is a run without
a folder (a sweep's point): simulate, evaluate, summarize, all in memory.

A run that fails part way (an FMU error) still evaluates and writes everything recorded
up to the failure, with a summary saying ``"status": "failed"`` and why; :func:`run` then
raises :class:`~twin.errors.RunError`.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin.config.spec import NS_PER_S, Scenario
from twin.cosim.master import Loop, Master, RunResult
from twin.errormodel.config import evaluation_config, input_columns
from twin.errormodel.evaluate import evaluate, evaluation_signals
from twin.errormodel.factors import FACTORS
from twin.errormodel.settings import EvaluationConfig
from twin.errors import ConfigError, RunError, TwinError
from twin.fmu.pool import SlotPool
from twin.outputs.plots import BudgetColumns
from twin.outputs.run_folder import (
    DISK_FULL_ERRNOS,
    RUN_FILE,
    SUMMARY_JSON,
    Checkpoint,
    RunFolder,
    RunMeta,
    scenario_fingerprint,
)
from twin.outputs.scene3d import tester_scene
from twin.outputs.sink import Outcome, Sink
from twin.paper import DRIFT_M, PAPER_SCENARIO, TEMPERATURE_RISE_K
from twin.pipeline.run_summary import RunSummary, Timing
from twin.signals.recorder import TeeRecorder
from twin.signals.table import SignalTable

if TYPE_CHECKING:
    from twin.outputs.plot_process import PlotProcess


@dataclass
class Simulation:
    """What the co-simulation hands on: the master's result, the kept columns of every
    recorded row, the wall time the sinks took while it ran, and its recorder (which holds a
    short run's rows for after the plots: :func:`simulate`'s ``hold_last_rows``)."""

    scenario: Scenario
    result: RunResult
    table: SignalTable
    write_s: float = 0.0
    recorder: TeeRecorder | None = None


@dataclass
class Evaluated:
    """What the error model made of a run.

    ``table`` is the simulation's table with the error model's columns added and
    ``columns`` names those (in the order the files list them); ``results`` are its numbers
    for the summary. When the model did not run (fewer than two rows, a column it needs
    missing), ``table`` is None and ``error`` says why where there was a reason.
    """

    table: SignalTable | None
    columns: tuple[str, ...] = ()
    results: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


def simulate(
    scenario: Scenario,
    *,
    sinks: Sequence[Sink] = (),
    keep: Collection[str] | None = None,
    progress: Callable[[int, int], None] | None = None,
    loop: Loop = "fast",
    stop: Callable[[], str | None] | None = None,
    checkpoint_every_ns: int | None = None,
    on_checkpoint: Callable[[Checkpoint], None] | None = None,
    resume: Checkpoint | None = None,
    pool: SlotPool | None = None,
    hold_last_rows: bool = False,
) -> Simulation:
    """Co-simulate ``scenario``: rows stream to ``sinks`` (opened here, closed by
    :func:`write_outputs`), the ``keep`` columns stay in memory (default: those the
    scenario's error model reads).

    With ``hold_last_rows`` the rows not yet handed to the sinks when the run ends are held
    for the caller (``simulation.recorder.flush()``, which :func:`write_outputs` makes once
    the plots are sent; see :class:`~twin.signals.recorder.TeeRecorder`); a run that raises
    hands them on before it does.

    ``stop`` is polled between batches (a signal name ends the run as "interrupted").
    With ``checkpoint_every_ns``, ``on_checkpoint`` receives the whole twin at that
    interval; ``resume`` continues from such a checkpoint. An FMU failure does not raise: it
    ends the run with ``result.status == "failed"`` and the rows up to it recorded. With a
    ``pool`` the FMU instances are reused from it and given back (:mod:`twin.fmu.pool`).
    """
    if keep is None:
        keep = set(input_columns(evaluation_config(scenario))) | truth_columns(scenario)
    recorder = TeeRecorder(
        sinks,
        keep=frozenset(keep).__contains__,
        resume=resume.recorder if resume else None,
        hold_last=hold_last_rows,
    )

    def save(snapshot: dict[str, Any]) -> None:
        assert on_checkpoint is not None
        on_checkpoint(
            Checkpoint(snapshot, recorder.checkpoint(), scenario.name, scenario_fingerprint(scenario))
        )

    master = Master(
        scenario,
        progress=progress,
        loop=loop,
        recorder=recorder,
        stop=stop,
        checkpoint_every_ns=checkpoint_every_ns,
        on_checkpoint=save if checkpoint_every_ns and on_checkpoint else None,
        resume=resume.master if resume else None,
        pool=pool,
    )
    try:
        result = master.run()
    except BaseException as exc:
        _hand_on(recorder, exc)
        raise
    return Simulation(scenario, result, recorder.table(), recorder.write_s, recorder)


def evaluate_run(simulation: Simulation, cfg: EvaluationConfig) -> Evaluated:
    """The error model on the simulation's kept columns (adds its columns to that table)."""
    table = simulation.table
    if len(table) < 2:
        return Evaluated(None)
    try:
        evaluation = evaluate(table, cfg)
    except ConfigError as exc:
        return Evaluated(None, error=str(exc))
    columns = tuple(s.name for s in evaluation_signals(with_true_wear=bool(cfg.true_wear)) if s.name in table)
    results = dict(evaluation.summary)
    if simulation.scenario.name == PAPER_SCENARIO:
        # the paper's measured values beside the twin's, to read one against the other
        results["drift_mm"]["paper_measured"] = DRIFT_M * 1e3
        results["temperature_rise_C_paper"] = dict(TEMPERATURE_RISE_K)
    truth = truth_thermal_parts(simulation)
    if truth:
        results["thermal_parts_mm_truth"] = truth
    return Evaluated(table, columns, results)


#: the paper's FEM parts as sums of FixtureMechanics' outputs, with their sign in the probe's
#: reading (branch 1 +, the frame -, pole and clamp + as they push the contact face down)
TRUTH_PARTS: dict[str, tuple[tuple[str, float], ...]] = {
    "bearing_block": (("dz_bearing_block", 1.0),),
    "t_plate": (("dz_spindle", 1.0), ("dz_bearing", 1.0), ("dz_t_plate", 1.0)),
    "detecting_frame": (("dz_detecting_frame", -1.0),),
    "long_pole": (("dz_long_pole", 1.0), ("dz_clamp", 1.0)),
}


def truth_columns(scenario: Scenario) -> set[str]:
    """The FixtureMechanics outputs :func:`truth_thermal_parts` reads (kept in memory)."""
    names = [f.name for f in scenario.fmus if f.model == "FixtureMechanics"]
    return {f"{n}.{v}" for n in names for terms in TRUTH_PARTS.values() for v, _ in terms}


def truth_thermal_parts(simulation: Simulation) -> dict[str, float]:
    """The tester's own (true, noise-free) displacement of each FEM part over the run, mm: what
    the twin sets beside the paper's FEM results. Not the error model's: it reads the FMU."""
    names = [f.name for f in simulation.scenario.fmus if f.model == "FixtureMechanics"]
    table = simulation.table
    if len(names) != 1 or len(table) < 2:
        return {}
    out: dict[str, float] = {}
    for part, terms in TRUTH_PARTS.items():
        cols = [(f"{names[0]}.{v}", sign) for v, sign in terms]
        if all(c in table for c, _ in cols):
            out[part] = sum(sign * float(table[c][-1] - table[c][0]) for c, sign in cols) * 1e3
    return out


def summarize(
    simulation: Simulation,
    evaluated: Evaluated,
    *,
    process_start: float,
    phases: Mapping[str, float] | None = None,
) -> RunSummary:
    """The run's summary; ``process_start`` (``time.perf_counter()``) starts its total time;
    ``phases`` adds to the timing's phases (the error model's and the outputs' times)."""
    result, sc = simulation.result, simulation.scenario
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
        total_s=time.perf_counter() - process_start,
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


def write_outputs(
    sinks: Sequence[Sink],
    evaluated: Evaluated,
    summary: Callable[[], Mapping[str, Any]],
    *,
    stop: Callable[[], str | None] | None = None,
    skipped: list[str] | None = None,
    timings: dict[str, float] | None = None,
    held: TeeRecorder | None = None,
) -> None:
    """Close every sink, in order, with the run's outcome (each one's time into ``timings``,
    by its file's name, when given).

    ``summary`` is called once, when the first sink asks for it (the summary sink, last),
    so the summary's total time counts the writing of every other file. Once ``stop``
    answers a signal's name, the sinks that only draw what the others hold (``skippable``:
    the plots, most of what comes after the co-simulation) are left out and their
    files' names added to ``skipped``: an interrupted run keeps its data, not its pictures.
    Every sink is asked first whether it begins its file now (:meth:`~twin.outputs.sink.Sink.begin`:
    the plots, drawn by their own process while the files before them are written). The
    rows ``held`` back at the end of the run (:func:`simulate`'s ``hold_last_rows``) are
    handed to the sinks after that, before any closes (their time into ``timings`` as
    ``last_rows``).
    """
    outcome = Outcome(evaluated.table, evaluated.columns, summary)

    def stopped() -> bool:
        return stop is not None and stop() is not None

    # a sink whose file another process makes (the plots) begins it now, to be made while the
    # files before it are written; once begun it is waited for, stop or not
    begun = {id(sink) for sink in sinks if not (sink.skippable and stopped()) and sink.begin(outcome)}
    if held is not None:
        t0 = time.perf_counter()
        held.flush()
        if timings is not None:
            timings["last_rows"] = time.perf_counter() - t0
    for sink in sinks:
        if sink.skippable and id(sink) not in begun and stopped():
            if skipped is not None:
                skipped.append(sink.path.name)
            continue
        t0 = time.perf_counter()
        sink.close(outcome)
        if timings is not None:
            timings[sink.path.name] = time.perf_counter() - t0


def cycles_column(scenario: Scenario) -> str | None:
    """The swing-cycle counter of the scenario's oscillation drive (wear.png's axis), if one."""
    names = [f.name for f in scenario.fmus if f.model == "OscillationDrive"]
    return f"{names[0]}.cycles" if len(names) == 1 else None


def budget_columns(cfg: EvaluationConfig, scenario: Scenario | None = None) -> BudgetColumns:
    """What the plots draw for an error model configured as ``cfg`` (and, for a run, its
    ``scenario``: the cycle counter and the wear limit of wear.png)."""
    limit = scenario.wear_limit_mm if scenario is not None else None
    return BudgetColumns(
        reading=cfg.reading,
        predicted="errormodel.e_z",
        parts={f.label: f.column for f in FACTORS},
        temperatures=dict(cfg.temperatures),
        compensated="errormodel.wear_compensated",
        true_wear=cfg.true_wear,
        cycles=cycles_column(scenario) if scenario is not None else None,
        wear_limit_m=limit * 1e-3 if limit is not None else None,
    )


def run(
    scenario: Scenario,
    out_dir: Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    process_start: float | None = None,
    loop: Loop = "fast",
    overrides: Sequence[str] = (),
    stop: Callable[[], str | None] | None = None,
    checkpoint_every_ns: int | None = None,
    resume: Checkpoint | None = None,
    plot_process: PlotProcess | None = None,
) -> RunSummary:
    """Run ``scenario`` into the run folder ``out_dir``; returns the summary written there.

    Raises before the run starts (a bad error-model configuration), or :class:`RunError`
    after writing everything recorded up to a failure. ``stop``, ``checkpoint_every_ns``
    and ``resume`` as for :func:`simulate` (checkpoints go to the folder's checkpoint file);
    ``plot_process`` draws the plots (:mod:`twin.outputs.plot_process`; in process when None).
    """
    process_start = process_start or time.perf_counter()
    cfg = evaluation_config(scenario)  # checked before anything runs
    folder = RunFolder(out_dir)
    folder.lock()  # before anything in the folder changes: a second process is refused
    try:
        return _run_locked(
            scenario,
            folder,
            cfg,
            progress,
            process_start,
            loop,
            overrides,
            stop,
            checkpoint_every_ns,
            resume,
            plot_process,
        )
    finally:
        folder.unlock()


def _run_locked(
    scenario: Scenario,
    folder: RunFolder,
    cfg: EvaluationConfig,
    progress: Callable[[int, int], None] | None,
    process_start: float,
    loop: Loop,
    overrides: Sequence[str],
    stop: Callable[[], str | None] | None,
    checkpoint_every_ns: int | None,
    resume: Checkpoint | None,
    plot_process: PlotProcess | None = None,
) -> RunSummary:
    out_dir = folder.path
    sinks: list[Sink] = []
    simulation: Simulation | None = None
    try:
        if resume is None:
            meta = RunMeta(
                str(Path(scenario.source_path).resolve()), tuple(overrides), loop, checkpoint_every_ns
            )
            folder.start(meta)
        sinks = folder.run_sinks(
            name=scenario.name,
            late_signals=evaluation_signals(with_true_wear=bool(cfg.true_wear)),
            budget_view=["errormodel.e_z", *[f.column for f in FACTORS], "errormodel.reading_change"],
            plot=budget_columns(cfg, scenario),
            resume=resume,
            scene=tester_scene(scenario),
            plot_process=plot_process,
        )
        simulation = simulate(
            scenario,
            sinks=sinks,
            # the cycle counter too: wear.png's axis
            keep=set(input_columns(cfg)) | truth_columns(scenario) | {cycles_column(scenario)} - {None},
            progress=progress,
            loop=loop,
            stop=stop,
            checkpoint_every_ns=checkpoint_every_ns,
            on_checkpoint=folder.save_checkpoint,
            resume=resume,
            # the last rows are written once the plots are sent: see write_outputs
            hold_last_rows=True,
        )
        t0 = time.perf_counter()
        evaluated = evaluate_run(simulation, cfg)
        phases = {"errormodel": time.perf_counter() - t0}
        skipped: list[str] = []
        summary = functools.cache(
            lambda: _late_stop(
                summarize(simulation, evaluated, process_start=process_start, phases=phases), stop, skipped
            )
        )
        write_outputs(
            sinks,
            evaluated,
            lambda: summary().to_dict(),
            stop=stop,
            skipped=skipped,
            timings=phases,
            held=simulation.recorder,
        )
    except OSError as exc:
        _fail(sinks, exc, simulation)
        if exc.errno in DISK_FULL_ERRNOS:
            raise _disk_full(folder, scenario, exc) from None
        if simulation is not None:
            raise _failed_writing(folder, scenario, exc) from exc
        raise
    except BaseException as exc:
        _fail(sinks, exc, simulation)
        if simulation is not None and isinstance(exc, Exception):
            raise _failed_writing(folder, scenario, exc) from exc
        raise
    if simulation.result.error is not None:
        raise RunError(f"{simulation.result.error} (everything recorded up to it is in {out_dir})")
    return summary()


def _late_stop(
    summary: RunSummary, stop: Callable[[], str | None] | None, skipped: Sequence[str]
) -> RunSummary:
    """A run whose co-simulation completed but that a signal asked to stop afterwards (while
    the error model or the outputs were made) is "interrupted" too: the signal is named. An
    interrupted run's error also names the files left out for it."""
    if summary.status == "interrupted":
        why = summary.error or "interrupted"
    elif summary.status == "completed" and stop is not None and (caught := stop()) is not None:
        why = f"interrupted by {caught} after the co-simulation"
    else:
        return summary
    if skipped:
        why += f" (not written: {', '.join(skipped)})"
    return dataclasses.replace(summary, status="interrupted", error=why)


def _disk_full(folder: RunFolder, scenario: Scenario, exc: OSError) -> RunError:
    """The error of a run stopped by a full disk (or a file-size limit), after writing what
    can be written: the sinks have cut their files back to whole rows; summary.json says so.

    No space is reserved for that summary: it is about 150 bytes, and the sinks' cutting back
    (:func:`_fail`, before this) has just freed the part of a 256 kB slice that reached the
    disk, so it fits on a disk that filled up under a run; a file-size limit is per file and
    a small file stays under it. When it still does not fit, the error says so, and the
    summary of an earlier run is gone already (the run removed it when it started)."""
    from twin.outputs.summary import write_summary

    where = exc.filename or "an output file"
    status = "failed: disk full"
    try:
        write_summary(
            folder.file(SUMMARY_JSON),
            {"scenario": scenario.name, "status": status, "error": f"{exc.strerror} while writing {where}"},
        )
        note = "summary.json says so"
    except OSError:
        note = "summary.json could not be written either"
    return RunError(
        f"disk full ({exc.strerror}) while writing {where}; every whole row recorded so far is in {folder.path}; {note}"
    )


def _failed_writing(folder: RunFolder, scenario: Scenario, exc: Exception) -> RunError:
    """The error of a run whose co-simulation ended but whose error model or outputs failed
    (a plot that cannot be drawn): what was written stays, and summary.json says the run
    failed and why, as it does when an FMU fails, so the folder is never left without one."""
    from twin.outputs.summary import write_summary

    why = str(exc) if isinstance(exc, TwinError) else f"{type(exc).__name__}: {exc}"
    if folder.file(SUMMARY_JSON).exists():  # written last: the failure came after it
        return exc if isinstance(exc, TwinError) else RunError(why)
    try:
        write_summary(
            folder.file(SUMMARY_JSON), {"scenario": scenario.name, "status": "failed", "error": why}
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
    scenario: Scenario,
    *,
    loop: Loop = "fast",
    progress: Callable[[int, int], None] | None = None,
    stop: Callable[[], str | None] | None = None,
    pool: SlotPool | None = None,
) -> RunSummary:
    """Simulate and evaluate ``scenario`` in memory, no file written (a sweep's point).

    A failing FMU does not raise: the summary says ``"failed"`` and why, with the figures
    of the rows recorded up to the failure. A bad scenario raises :class:`ConfigError`. With
    a ``pool`` the FMU instances of the points before are reused (:mod:`twin.fmu.pool`).
    """
    start = time.perf_counter()
    cfg = evaluation_config(scenario)
    simulation = simulate(
        scenario,
        keep=set(input_columns(cfg)) | truth_columns(scenario),
        loop=loop,
        progress=progress,
        stop=stop,
        pool=pool,
    )
    return summarize(simulation, evaluate_run(simulation, cfg), process_start=start)


def _check_checkpoint_every(every_ns: int | None, step_ns: int, run_json: Path) -> None:
    """run.json's ``checkpoint_every_ns`` as ``twin run`` writes it: null (no checkpoints) or
    a positive multiple of the scenario's step. Anything else (0, -1, 1, half a step) would
    turn the resumed run's checkpoints off without a word (checkpoint_ticks has no tick for
    it), so a second kill would lose everything after this checkpoint."""
    if every_ns is not None and (every_ns <= 0 or every_ns % step_ns):
        raise ConfigError(
            f"must be null or a positive multiple of scenario.step ({step_ns} ns), got {every_ns}",
            source=str(run_json),
            key="checkpoint_every_ns",
        )


def resume_run(
    run_dir: Path,
    *,
    progress: Callable[[int, int], None] | None = None,
    stop: Callable[[], str | None] | None = None,
    process_start: float | None = None,
) -> RunSummary:
    """Continue a killed or interrupted run from its last checkpoint."""
    from twin.config.load import load_scenario

    folder = RunFolder(run_dir)
    meta = folder.resumable()
    scenario = load_scenario(meta.scenario, list(meta.overrides))
    _check_checkpoint_every(meta.checkpoint_every_ns, scenario.step_ns, folder.file(RUN_FILE))
    return run(
        scenario,
        run_dir,
        progress=progress,
        process_start=process_start,
        loop=meta.loop,  # type: ignore[arg-type]
        overrides=meta.overrides,
        stop=stop,
        checkpoint_every_ns=meta.checkpoint_every_ns,
        resume=folder.load_checkpoint(scenario.name, scenario_fingerprint(scenario)),
    )
