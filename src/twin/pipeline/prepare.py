"""The one place where input becomes a checked run: :func:`prepare` -> :class:`PreparedRun`.

Everything a run could refuse is found here, before anything runs and before any file is
touched (bad input runs nothing and makes no run folder)::

    source, --set ──load──> Scenario ──make_plan──> Plan (made once, handed to the master)
                               │
                               ├─ [errormodel]  checked into its EvaluationConfig once, the
                               │                columns it reads checked against the plan
                               ├─ --tester      an updated tester's values and coefficients set
                               │                as overrides (twin update; kept in run.json)
                               ├─ [uncertainty] the run's Monte Carlo, checked
                               ├─ [reference]   the measured experiment it replays (reports)
                               ├─ the checkpoint interval, a multiple of the step
                               ├─ the FMUs built (cache) and initialized once: what they refuse
                               │  of their parameters is bad input
                               └─ the run folder checked, an earlier run refused without
                                  force, the folder locked (once) for the command's life

``twin validate`` is :func:`prepare` without a folder; ``twin run`` is :func:`prepare` then
:func:`twin.pipeline.stages.run`; ``twin resume`` is :func:`prepare_resume` then the same run;
a study's points (sweeps, the Monte Carlo, held-out testers) are prepared without a folder and
without the FMUs' check (a point the FMUs refuse is a failed point, not bad input).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from twin.config.durations import parse_duration
from twin.config.experiment import Experiment
from twin.config.load import find_scenario, load_scenario
from twin.config.spec import Scenario
from twin.cosim.checkpoint import check_snapshot
from twin.cosim.controls import RunControls
from twin.cosim.instances import check_initialization
from twin.cosim.loops import LoopError
from twin.cosim.plan import Plan, make_plan
from twin.cosim.stepping import Loop, check_loop
from twin.errormodel.config import check_recorded_columns, evaluation_config
from twin.errormodel.settings import EvaluationConfig
from twin.errors import ConfigError, ConfigErrors, FMUError, TwinError, did_you_mean
from twin.fmu import catalog
from twin.outputs.plot_process import PlotProcess
from twin.outputs.run_folder import (
    CHECKPOINT_FILE,
    RUN_FILE,
    RUN_OUTPUTS,
    Checkpoint,
    RunFolder,
    check_output_folder,
    scenario_fingerprint,
)
from twin.outputs.sink import ClosesOnExit
from twin.pipeline.montecarlo import Uncertainty, parse_uncertainty
from twin.pipeline.report import Report, Reports
from twin.uncertainty.updated import UpdatedTester, load_updated

__all__ = [
    "FORMATS",
    "PreparedRun",
    "RunOptions",
    "check_formats",
    "prepare",
    "prepare_resume",
    "prepare_scenario",
    "record_columns",
]


@dataclass(frozen=True)
class RunOptions:
    """How a run is asked for (the command line's choices, or a study's).

    ``folder``: whether the run writes a run folder (``out``: which one, by default
    ``runs/<scenario name>``; ``force``: replacing an earlier run's files); without one the
    run stays in memory. ``checkpoint_every``: how often the whole twin is saved (a duration).
    ``samples``: Monte Carlo samples of the prediction's uncertainty (None: the scenario's
    ``[uncertainty] samples``; 0: none). ``check_fmus``: the FMUs built and initialized once
    before the run (what they refuse is bad input). ``reports``: what a measured experiment
    the scenario replays adds to its summary (:mod:`twin.pipeline.report`). ``started``: when
    the command began (``time.perf_counter()``; the summary's total time counts from it).

    What a co-simulation engineer sets as in fmpy and cosim-cli: ``experiment``, the times
    and input file of the run (:class:`~twin.config.experiment.Experiment`: ``--start-time``,
    ``--stop-time``, ``--step-size``, ``--output-interval``, ``--input-file``; applied to a
    scenario loaded from a file); ``record``, the columns signals.csv holds
    (``instance.variable``, or ``variable`` alone for a scenario of one FMU; None: every
    recorded column); ``formats``, the signal files besides signals.csv (``"mat"``:
    signals.mat); ``fmi_logging``, the FMUs' own log messages into the run folder's fmi.log.
    ``tester``: an updated tester file (``twin update``, :mod:`twin.uncertainty.updated`) whose
    values the run sets, whose coefficients the error model takes, and whose posterior draws
    the uncertainty's updated prediction runs (beside the prior predictive).
    """

    folder: bool = False
    out: Path | None = None
    force: bool = False
    checkpoint_every: str | None = None
    samples: int | None = None
    loop: Loop = "fast"
    check_fmus: bool = True
    reports: Reports | None = None
    started: float | None = None
    experiment: Experiment = field(default_factory=Experiment)
    record: tuple[str, ...] | None = None
    formats: tuple[str, ...] = ()
    fmi_logging: bool = False
    tester: Path | None = None


@dataclass
class PreparedRun(ClosesOnExit):
    """A checked run, ready to go: what :func:`twin.pipeline.stages.run` takes.

    Holds the run folder's lock (when it has a folder) until :meth:`close`; use it as a
    context manager.
    """

    scenario: Scenario
    plan: Plan
    evaluation: EvaluationConfig
    options: RunOptions
    overrides: tuple[str, ...] = ()
    folder: RunFolder | None = None
    checkpoint_every_ns: int | None = None
    uncertainty: Uncertainty | None = None
    reports: tuple[Report, ...] = ()
    resume: Checkpoint | None = None
    plots: PlotProcess | None = None
    started: float = field(default_factory=time.perf_counter)
    #: the columns signals.csv holds, resolved (``options.record``; None: every recorded column)
    record: tuple[str, ...] | None = None
    #: the updated tester the run is of (``options.tester``) and the scenario before its
    #: values were set: what the prior predictive draws around
    tester: UpdatedTester | None = None
    prior_scenario: Scenario | None = None

    def keep(self) -> set[str]:
        """The columns a run keeps in memory: those the error model reads, the reports', and
        the swing-cycle counter (the axis of the wear plot)."""
        from twin.errormodel.config import input_columns

        keep = set(input_columns(self.evaluation)) | set(self.plan.role_columns("swing_cycles"))
        for report in self.reports:
            keep |= report.columns(self.plan)
        return keep

    def close(self) -> None:
        """Release the run folder and stop a plot helper that drew nothing (idempotent)."""
        if self.plots is not None:
            self.plots.close()
            self.plots = None
        if self.folder is not None:
            self.folder.unlock()


def prepare(
    source: str | Path | Scenario | None,
    overrides: Sequence[str] = (),
    options: RunOptions = RunOptions(),
    controls: RunControls = RunControls(),  # noqa: B008
    plots: PlotProcess | None = None,
) -> PreparedRun:
    """Turn ``source`` (a scenario file, an SSP archive, a shipped scenario's name, None for
    the paper's experiment, or a scenario value) and ``overrides`` (``--set KEY=VALUE``) into
    a checked run (see the module). ``controls.stop`` is asked after the FMUs' build: a signal
    during it ends the command as interrupted, with nothing written.

    A run with a folder draws its plots by a helper process, started here (it imports
    matplotlib meanwhile), or ``plots``, one the caller started earlier (``twin run`` starts it
    before it imports the twin): the prepared run owns it from here, and closes it."""
    started = options.started if options.started is not None else time.perf_counter()
    if plots is None and options.folder:
        plots = PlotProcess.started()  # imports matplotlib meanwhile
    try:
        prepared = _prepare(source, overrides, options, controls, plots)
    except BaseException as exc:
        if plots is not None:
            plots.close()
        if isinstance(exc, ConfigError) and isinstance(source, (str, Path)) and str(source).endswith(".ssp"):
            from twin.config.ssp import discard_unpacked

            discard_unpacked(Path(source))  # refused (its FMUs refuse their parameters): no copy stays
        raise
    prepared.started = started
    return prepared


def prepare_scenario(
    scenario: Scenario, evaluation: EvaluationConfig | None = None, like: Plan | None = None
) -> PreparedRun:
    """A study's point: ``scenario`` in memory, no folder, no FMU check (a point the FMUs
    refuse fails as a point); ``evaluation`` reuses the error model's configuration of the
    study's base scenario (a point changes no ``[errormodel]``); ``like``, another point's
    plan, gives its structure to this point's when they share it (:func:`make_plan`)."""
    plan = make_plan(scenario, like)
    if evaluation is None:
        evaluation = evaluation_config(scenario)
        check_recorded_columns(scenario, plan.column_names())
    return PreparedRun(scenario, plan, evaluation, RunOptions(check_fmus=False))


def _prepare(
    source: str | Path | Scenario | None,
    overrides: Sequence[str],
    options: RunOptions,
    controls: RunControls,
    plots: PlotProcess | None,
) -> PreparedRun:
    tester, prior_scenario = None, None
    if options.tester is not None:
        if isinstance(source, Scenario):
            raise ConfigError("a scenario value takes no tester file", source="--tester")
        tester = load_updated(options.tester)
        # the twin before the record: what the prior predictive draws around
        prior_scenario = load_scenario(find_scenario(source), overrides, options.experiment)
        tester.check_against(prior_scenario)
        # the tester's values go in as overrides before the command line's own, so run.json
        # keeps them (a resumed run is the same tester) and a --set still has the last word
        overrides = [*tester.overrides(prior_scenario), *overrides]
    scenario = (
        source
        if isinstance(source, Scenario)
        else load_scenario(find_scenario(source), overrides, options.experiment)
    )
    plan = make_plan(scenario)
    evaluation = evaluation_config(scenario)
    check_recorded_columns(scenario, plan.column_names())
    record = record_columns(options.record, plan)
    check_formats(options.formats, scenario)
    uncertainty = parse_uncertainty(scenario, options.samples)
    reports = options.reports(scenario) if options.reports is not None else ()
    every = _checkpoint_every(options.checkpoint_every, scenario.step_ns)
    check_loop(options.loop)
    out = (options.out or Path("runs") / scenario.name) if options.folder else None
    if out is not None:
        check_output_folder(out, "--out")
    if options.check_fmus:
        _fmus_accept(scenario, plan, controls)
    folder = _take_folder(out, options.force) if out is not None else None
    return PreparedRun(
        scenario,
        plan,
        evaluation,
        options,
        tuple(overrides),
        folder,
        every,
        uncertainty,
        tuple(reports),
        plots=plots,
        record=record,
        tester=tester,
        prior_scenario=prior_scenario,
    )


def prepare_resume(
    run_dir: Path,
    options: RunOptions = RunOptions(),
) -> PreparedRun:
    """A killed or interrupted run, ready to continue from its last checkpoint: its folder
    locked before the checkpoint is read, its scenario loaded as ``run.json`` says it was
    started, and every value of the checkpoint checked against that scenario as it is now.
    A run that completed is refused (nothing to resume), as is a crafted checkpoint (exit 2,
    one line naming checkpoint.npz and its key); nothing of the folder changes here, and
    signals.csv is cut back only once every FMU has taken its saved state."""
    check_output_folder(run_dir, "resume")  # a folder it can write in
    if not run_dir.is_dir():
        raise ConfigError("no such folder (no run.json): not a run folder", source=str(run_dir))
    folder = RunFolder(run_dir)
    folder.lock()  # before its checkpoint is read: no other process may write there meanwhile
    try:
        meta = folder.resumable()
        folder.refuse_completed()
        experiment = Experiment.from_json(meta.experiment, str(folder.file(RUN_FILE)))
        scenario = _resumed_scenario(meta.scenario, meta.overrides, experiment, folder.file(RUN_FILE))
        plan = make_plan(scenario)
        evaluation = evaluation_config(scenario)
        every = meta.checkpoint_every_ns
        if every is not None and (every <= 0 or every % scenario.step_ns):
            raise ConfigError(
                f"must be null or a positive multiple of scenario.step ({scenario.step_ns} ns), got {every}",
                source=str(folder.file(RUN_FILE)),
                key="checkpoint_every_ns",
            )
        options = RunOptions(
            folder=True,
            out=run_dir,
            loop=meta.loop,
            check_fmus=False,
            reports=options.reports,
            started=options.started,
            experiment=experiment,
            record=meta.record,
            formats=meta.formats,
            fmi_logging=meta.fmi_logging,
        )
        reports = options.reports(scenario) if options.reports is not None else ()
        record = record_columns(meta.record, plan)
        prepared = PreparedRun(
            scenario,
            plan,
            evaluation,
            options,
            meta.overrides,
            folder,
            every,
            None,
            tuple(reports),
            record=record,
        )
        # every value of the checkpoint checked against this plan before the folder changes
        keep = prepared.keep()
        kept = sum(1 for c in plan.columns if c.meta.name in keep)
        prepared.resume = folder.load_checkpoint(scenario.name, scenario_fingerprint(scenario), kept)
        check_snapshot(plan, prepared.resume.master, str(folder.file(CHECKPOINT_FILE)))
    except BaseException:
        folder.unlock()
        raise
    return prepared


def _resumed_scenario(
    path: str, overrides: Sequence[str], experiment: Experiment, run_file: Path
) -> Scenario:
    """The scenario a resumed run was started with. Its overrides come from run.json, not the
    command line: when the file loads without them and not with them, the problems are said
    of run.json's overrides (a crafted or stale run.json), not of a ``--set`` never typed."""
    try:
        return load_scenario(Path(path), list(overrides), experiment)
    except ConfigError as exc:
        if not overrides:
            raise
        try:
            load_scenario(Path(path), [], experiment)
        except ConfigError:
            raise exc from None  # the scenario itself has problems: said of it
        problems = getattr(exc, "problems", [exc])
        said = [
            ConfigError(e.message or str(e), source=f"{run_file}: overrides of {path}", key=e.key)
            for e in problems
        ]
        raise (said[0] if len(said) == 1 else ConfigErrors(said)) from None


#: the signal files a run may write besides signals.csv (``--format``)
FORMATS = ("csv", "mat")


def record_columns(names: Sequence[str] | None, plan: Plan) -> tuple[str, ...] | None:
    """The columns ``--record`` names, as signals.csv's columns (``variable`` alone stands for
    ``instance.variable`` in a scenario of one FMU; ``time`` is always the first column):
    every name one the run records, else one line each, with a close match."""
    if names is None:
        return None
    recorded = [c.meta.name for c in plan.columns]
    lone = plan.instances[0].name if len(plan.instances) == 1 else None
    out: list[str] = []
    problems: list[ConfigError] = []
    for name in names:
        column = f"{lone}.{name}" if lone is not None and "." not in name else name
        if name == "time" or column in out:
            continue
        if column in recorded:
            out.append(column)
            continue
        problems.append(ConfigError(_not_recorded(column, plan, recorded), source="--record"))
    if problems:
        raise problems[0] if len(problems) == 1 else ConfigErrors(problems)
    return tuple(out)


def _not_recorded(column: str, plan: Plan, recorded: Sequence[str]) -> str:
    """Why the run records no column ``column``, with a close match."""
    instance, _, variable = column.partition(".")
    inst = next((i for i in plan.instances if i.name == instance), None)
    var = catalog.variables(inst.model).get(variable) if inst is not None else None
    hint = did_you_mean(column, recorded)
    if var is not None:
        what = f"a {var.causality} ({var.type})" if var.causality != "input" else "an input nothing drives"
        return f"{column!r} is {what}: signals.csv holds the Real outputs and the driven inputs{hint}"
    if inst is None and len(plan.instances) > 1:
        known = ", ".join(i.name for i in plan.instances)
        return f"no column {column!r}{hint} (columns are 'instance.variable' of: {known})"
    return f"no column {column!r}{hint}"


def check_formats(formats: Sequence[str], scenario: Scenario) -> None:
    """The signal files asked for are ones the twin writes, and a MAT file can hold the
    instances' names."""
    for name in formats:
        if name not in FORMATS:
            raise ConfigError(
                f"unknown format {name!r}{did_you_mean(name, FORMATS)} (one of: {', '.join(FORMATS)})",
                source="--format",
            )
    if "mat" in formats:
        from twin.outputs.mat import mat_problem

        why = mat_problem(f.name for f in scenario.fmus)
        if why is not None:
            raise ConfigError(why, source="--format")


def _checkpoint_every(text: str | None, step_ns: int) -> int | None:
    """``--checkpoint-every`` as nanoseconds of simulated time, a multiple of the scenario's step."""
    if text is None:
        return None
    try:
        every = parse_duration(text)
    except ValueError as exc:
        raise ConfigError(str(exc), source="--checkpoint-every") from None
    if every <= 0 or every % step_ns:
        raise ConfigError("must be a positive multiple of scenario.step", source="--checkpoint-every")
    return every


def _fmus_accept(scenario: Scenario, plan: Plan, controls: RunControls) -> None:
    """Build (or find in the cache) the scenario's FMUs, then instantiate and initialize each
    once (none stepped): what they refuse of their parameters is bad input, one line naming
    the instance's parameters and the FMU's reason. A signal during the build (a Ctrl-C on a
    terminal reaches cmake too) ends the command as interrupted: the build it broke is not a
    build error."""
    try:
        for model in sorted({f.model for f in scenario.fmus}):
            catalog.fmu(model)
    except TwinError:
        if controls.stopped() is not None:
            raise KeyboardInterrupt from None
        raise
    if controls.stopped() is not None:
        raise KeyboardInterrupt
    try:
        check_initialization(plan)
    except FMUError as exc:
        if exc.call == "fmi2SetupExperiment":  # an FMU that cannot begin at scenario.start
            raise ConfigError(
                f"FMU {exc.instance!r} refuses to begin at {exc.time_s:g} s: {exc.detail}",
                source=scenario.source_path,
                key="scenario.start",
            ) from None
        raise ConfigError(
            f"the FMU refuses them in {exc.call}: {exc.detail}",
            source=scenario.source_path,
            key=f"fmu.{exc.instance}.parameters",
        ) from None
    except LoopError as exc:  # the connections make a loop with no consistent initial values
        raise ConfigError(str(exc), source=scenario.source_path, key="connections") from None


def _take_folder(out: Path, force: bool) -> RunFolder:
    """The run folder, locked for the command's whole life (Monte Carlo included: one process
    per folder); one holding an earlier run's outputs is replaced only with ``force``."""
    folder = RunFolder(out)
    folder.lock()
    try:
        earlier = sorted(n for n in RUN_OUTPUTS if (out / n).exists())
        if earlier and not force:
            more = ", ..." if len(earlier) > 3 else ""
            raise ConfigError(
                f"{out} holds an earlier run ({', '.join(earlier[:3])}{more}): --force replaces it, or name another --out",
                source="--out",
            )
    except BaseException:
        folder.unlock()
        raise
    return folder
