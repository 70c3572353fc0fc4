"""``twin run [SCENARIO]``: a scenario into its run folder, with its uncertainty (default: the
paper's 480 min thermal experiment, run by the paper's tester as ``twin update`` learnt it from
that experiment's record: the prior predictive and the updated prediction side by side);
``twin run X.fmu``: one FMU alone; ``--tester FILE``: an updated tester.

The experiment's options follow fmpy's ``simulate`` and cosim-cli's ``run``: ``--start-time``,
``--stop-time``, ``--step-size``, ``--output-interval``, ``--input-file``, ``--fmi-logging``;
``--record`` is fmpy's ``--output-variables``; ``--format mat`` adds signals.mat."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from twin.cli.common import (
    add_experiment,
    add_set,
    add_tester,
    experiment,
    finish,
    flag,
    optional,
    progress_bar,
    stop_on_signals,
    tester_path,
)

#: the signal files ``--format`` names (twin.pipeline.prepare.FORMATS; not imported here: the
#: parser is built before the package loads)
FORMATS = ("csv", "mat")

NAME = "run"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="run a scenario (default: the paper's 480 min thermal experiment)")
    optional(
        p,
        "scenario",
        "scenario TOML file, an SSP archive (.ssp), one FMU (.fmu) run alone, or a shipped "
        "scenario's name, e.g. sine-load (default: li2017-thermal-experiment)",
    )
    p.add_argument("--out", metavar="DIR", help="run folder (default: runs/<scenario name>)")
    flag(p, "--force", "replace the outputs of an earlier run in the run folder")
    add_set(p)
    add_tester(
        p,
        "its values and coefficients set, its posterior's updated prediction beside the prior "
        "predictive (default without a scenario: scenarios/records/li2017-updated.toml, the paper's "
        "tester updated from its record; 'none': the twin before any record)",
    )
    flag(p, "--quiet", "no progress bar, no summary line")
    p.add_argument(
        "--uncertainty",
        type=int,
        metavar="N",
        help="Monte Carlo samples of the prediction's uncertainty (default: the scenario's "
        "[uncertainty] samples; 0: none)",
    )
    p.add_argument(
        "--checkpoint-every",
        metavar="DURATION",
        help="save the whole twin every DURATION of simulated time (e.g. '1 h')",
    )
    add_experiment(p)
    p.add_argument(
        "--record",
        nargs="+",
        action="extend",
        metavar="VAR",
        help="the columns signals.csv holds, named instance.variable (variable alone for one FMU); "
        "default: every Real output of every FMU, then each input a profile or an event drives "
        "(a connected input is its source's output, recorded there)",
    )
    p.add_argument(
        "--format",
        action="append",
        choices=FORMATS,
        help="also write the signals as signals.mat (MATLAB, scipy.io) beside signals.csv",
    )
    flag(p, "--fmi-logging", "the FMUs' own log messages (debug logging on) into the run folder's fmi.log")
    p.set_defaults(process_start=None)
    return p


def command(args: argparse.Namespace) -> int:
    from twin.cli import interrupt, process

    if args.own_process:
        process.before_numpy()
    started = args.process_start or time.perf_counter()
    # the plot helper first: its imports (matplotlib) overlap this process's own from here
    plots = _plot_helper()
    try:
        from twin.pipeline import RunControls, prepare, run
        from twin.validation import reports

        # from here a Ctrl-C asks the command to stop; the run folder, once made, then holds
        # everything recorded and a summary saying "interrupted"
        stop = stop_on_signals()
        options = _options(args, reports, started)
    except BaseException:
        if plots is not None:
            plots.close()
        raise
    # prepare owns the helper from here (closes it on a failure; the prepared run, after)
    with prepare(args.scenario, args.set or [], options, RunControls(stop=stop), plots) as prepared:
        assert prepared.folder is not None
        folder = prepared.folder.path
        # first thing once the folder exists: a signal from here on leaves it a summary saying
        # "interrupted" (the process's tuning below took long enough for a Ctrl-C to land in
        # between and leave the folder without one)
        watch_folder(folder, prepared.uncertainty is not None, prepared.scenario.name)
        if args.own_process:
            process.settle()
        if prepared.tester is not None and prepared.tester.coefficients is None:
            print(
                f"twin: {prepared.tester.path}: names no coefficients: the error model uses the "
                "scenario's (the nominal twin's), not this tester's (twin identify --tester)",
                file=sys.stderr,
            )
        with interrupt.cooperative(), progress_bar(args.quiet) as update:
            summary = run(prepared, RunControls(stop=stop, progress=update, echo=_echo(args.quiet)))
            return finish(summary, folder, args.quiet, stop())


def _plot_helper() -> Any:
    """The run's plot helper, started (:class:`twin.outputs.plot_process.PlotProcess`), or None
    where the machine has one core; imported without numpy, which the helper loads itself."""
    from twin.outputs.plot_process import PlotProcess

    return PlotProcess.started()


def _options(args: argparse.Namespace, reports: Any, started: float) -> Any:
    """The run's options (:class:`twin.pipeline.RunOptions`) from the command line."""
    from twin.pipeline import RunOptions

    return RunOptions(
        folder=True,
        out=Path(args.out) if args.out is not None else None,
        force=args.force,
        checkpoint_every=args.checkpoint_every,
        samples=args.uncertainty,
        reports=reports,
        started=started,
        experiment=experiment(args),
        record=tuple(args.record) if args.record is not None else None,
        formats=tuple(dict.fromkeys(args.format or ())),
        fmi_logging=args.fmi_logging,
        tester=tester_path(args.tester, default=args.scenario is None),
    )


def watch_folder(folder: Path, monte_carlo: bool, scenario: str) -> None:
    """If the signal's watcher has to end the run itself (a stretch that did not stop in
    time, :mod:`twin.cli.interrupt`), the run folder's summary says "interrupted" and the one
    line says why."""
    from twin.cli import interrupt
    from twin.pipeline.run import mark_interrupted

    def hard_exit(name: str) -> str | None:
        why = mark_interrupted(folder, name, monte_carlo, scenario)
        return f"twin: run {why}; everything recorded so far is in {folder}" if why else None

    interrupt.on_hard_exit(hard_exit, where=str(folder))


def _echo(quiet: bool) -> Any:
    def echo(line: str) -> None:
        if not quiet:
            print(line, file=sys.stdout, flush=True)

    return echo


__all__ = ["add_parser", "command", "watch_folder"]
