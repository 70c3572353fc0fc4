"""The ``twin`` command: build the FMUs, run and validate scenarios.

Exit codes: 0 success, 2 bad input (one line per problem naming file and key, no
traceback), 1 a failure while running, 130/143 interrupted.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from twin import __version__, identify_cli, inspect_cli, ssp_cli
from twin.errors import ConfigError, TwinError
from twin.sweep.cli import add_sweep_parser  # cheap: dask and pandas load only when a sweep runs
from twin.validation import cli as heldout_cli  # cheap: dask loads only when it runs

if TYPE_CHECKING:
    from twin.config.spec import Scenario
    from twin.outputs.plot_process import PlotProcess
    from twin.pipeline import RunSummary
    from twin.validation.replay import RunUncertainty


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad arguments as one line and exit code 2."""

    def error(self, message: str) -> None:  # type: ignore[override]
        # the line starts "twin: " already: name the subcommand, not "twin" a second time
        raise ConfigError(message, source=self.prog.removeprefix("twin").strip() or None)

    def parse_known_args(
        self, args: Any = None, namespace: Any = None
    ) -> tuple[argparse.Namespace, list[str]]:  # type: ignore[override]
        """As argparse, and an empty argument is refused: the commands read a missing one as
        "the default", and ``--out ""`` once rewrote the committed coefficients file."""
        parsed, extras = super().parse_known_args(args, namespace)
        for action in self._actions:
            value = getattr(parsed, action.dest, None)
            values = value if isinstance(value, list) else [value]
            if any(isinstance(v, str) and not v.strip() for v in values):
                if action.option_strings:  # as output_folder says it: "twin: --out: is empty"
                    raise ConfigError("is empty", source=max(action.option_strings, key=len))
                command = self.prog.removeprefix("twin").strip() or None
                raise ConfigError(f"the {action.dest.replace('_', ' ')} is empty", source=command)
        return parsed, extras


def _cmd_build(args: argparse.Namespace) -> int:
    from twin.fmu.build import build_all

    out = Path(args.out) if args.out else None
    for model, path in build_all(out).items():
        print(f"{model}: {path}")
    return 0


def _scenario_path(name: str | None) -> Path:
    """The scenario a command names: a file, or the name of a shipped scenario (``sine-load``
    for ``scenarios/sine-load.toml``); none: the paper's experiment."""
    from twin.config.load import default_scenario_path, scenarios_dir
    from twin.config.reader import did_you_mean

    if not name:
        return default_scenario_path()
    path = Path(name)
    if path.exists() or path.suffix in (".toml", ".ssp") or len(path.parts) > 1:
        return path  # a file (a missing one is reported by the loader, naming it)
    shipped = {p.stem: p for p in sorted(scenarios_dir().glob("*.toml"))}
    if name in shipped:
        return shipped[name]
    raise ConfigError(
        f"no scenario file or shipped scenario named {name!r}{did_you_mean(name, shipped)} (`twin list` shows them)",
        source="scenario",
    )


def _load(args: argparse.Namespace):
    from twin.config.load import load_scenario

    return load_scenario(_scenario_path(args.scenario), args.set or [])


def _cmd_list(args: argparse.Namespace) -> int:
    """The shipped scenarios with their descriptions."""
    from twin.config.load import scenarios_dir
    from twin.config.reader import read_toml

    folder = scenarios_dir()
    groups = [
        ("scenarios", sorted(folder.glob("*.toml"))),
        ("calibration experiments", sorted((folder / "calibration").glob("*.toml"))),
    ]
    for title, paths in groups:
        rows = []
        for p in paths:
            desc = read_toml(p, str(p)).get("scenario", {})
            if isinstance(desc, dict) and "description" in desc:
                rows.append(
                    (p.stem if title == "scenarios" else f"calibration/{p.name}", str(desc["description"]))
                )
        if rows:
            print(f"{title} (in {folder if title == 'scenarios' else folder / 'calibration'}):")
            width = max(len(n) for n, _ in rows)
            for n, d in rows:
                print(f"  {n:<{width}}  {d}")
    return 0


def _progress_bar(quiet: bool):
    """A progress bar on a terminal (tqdm), nothing with --quiet or without a tty."""
    if quiet or not sys.stderr.isatty():
        return None, lambda: None
    import shutil

    from tqdm import tqdm

    # a pseudo-terminal may report 0 columns and rows, with which tqdm draws nothing
    size = shutil.get_terminal_size((80, 24))
    # the phases around the co-simulation say what is going on: loading (and, after a change
    # of their sources, building) the FMUs before the first step; the outputs after the last
    bar = tqdm(
        total=100,
        unit="%",
        desc="loading FMUs",
        leave=False,
        file=sys.stderr,
        ncols=size.columns or 80,
        nrows=size.lines or 24,
    )

    def update(now_ns: int, total_ns: int) -> None:
        bar.n = round(100 * now_ns / total_ns)
        desc = "writing outputs" if now_ns >= total_ns else "simulating"
        if bar.desc != desc:
            bar.set_description_str(desc, refresh=False)
        bar.refresh()

    return update, bar.close


_EXIT_ON_SIGNAL = {"SIGINT": 130, "SIGTERM": 143}


def _stop_on_signals():
    """SIGINT/SIGTERM ask the run to stop at the next batch: it flushes everything recorded,
    writes summary.json with "status": "interrupted" and the command exits with 130/143."""
    import signal

    caught: dict[str, str] = {}

    def handler(signum: int, frame: object) -> None:
        caught.setdefault("name", signal.Signals(signum).name)

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return lambda: caught.get("name")


def _supervised(quiet: bool, stage: Callable[..., RunSummary], stop: Callable[[], str | None]) -> RunSummary:
    """Call a run stage with a progress bar and ``stop`` (:func:`_stop_on_signals`) asking it
    to stop; a signal that comes after the co-simulation, while the error model and the
    outputs are made, ends the run as "interrupted" too (its summary says so)."""
    update, done = _progress_bar(quiet)
    try:
        return stage(progress=update, stop=stop)
    finally:
        done()


def _finish(summary: RunSummary, out: Path, quiet: bool, caught: str | None = None) -> int:
    import re

    if not quiet:
        print(summary.line())
        print(f"outputs: {out}")
    if summary.status == "interrupted":
        why = summary.error or "interrupted"
        print(f"twin: run {why}; everything recorded so far is in {out}", file=sys.stderr)
        name = re.search(r"\bby (SIG[A-Z]+)", why)
        return _EXIT_ON_SIGNAL.get(name.group(1) if name else "", 130)
    if caught is not None:  # after everything was written: the outputs are complete
        print(f"twin: interrupted by {caught}; the run's outputs are complete in {out}", file=sys.stderr)
        return _EXIT_ON_SIGNAL.get(caught, 130)
    return 0


def _checkpoint_every(text: str | None, step_ns: int) -> int | None:
    """--checkpoint-every as nanoseconds of simulated time, a multiple of the scenario's step."""
    if text is None:
        return None
    from twin.config.load import parse_duration

    try:
        every = parse_duration(text)
    except ValueError as exc:
        raise ConfigError(str(exc), source="--checkpoint-every") from None
    if every <= 0 or every % step_ns:
        raise ConfigError("must be a positive multiple of scenario.step", source="--checkpoint-every")
    return every


def _settle_the_run_process() -> None:
    """Settings for a process that runs the twin alone (``twin run`` from the console script or
    ``python -m twin``, not a program calling :func:`main`), made before rerun and pyarrow load
    (a setting the user has made in the environment stays theirs). Each measured with
    ``python benchmarks/bench_phases.py``; the run's outputs do not change.

    * pyarrow's buffers from the system allocator (``ARROW_DEFAULT_MEMORY_POOL=system``), and
      mimalloc, which rerun allocates with, handing freed memory back at once
      (``MIMALLOC_PURGE_DELAY=0``): both allocators otherwise keep the blocks a flush of rows
      freed for a while, and the next flush comes before they are given back. Peak of the MIL
      endurance run 166 -> 147 MB; its writing takes 0.04 s longer, the replay no longer.
    * pyarrow does not import pandas to ask whether rerun's lists are pandas objects
      (:func:`twin.outputs.rerun_rec.arrow_without_pandas_lookup`, made when the recording
      loads rerun: :func:`twin.outputs.recording_sink.settle_when_rerun_loads`): 0.17 s and 43 MB.
    * What is imported by now, and rerun's hundreds of modules when they load, lives as long as
      the process: it is frozen, so the garbage collector does not walk it in every full
      collection and at exit (0.04 s of the paper replay's 0.84 s).
    """
    import gc
    import os

    os.environ.setdefault("ARROW_DEFAULT_MEMORY_POOL", "system")
    os.environ.setdefault("MIMALLOC_PURGE_DELAY", "0")
    from twin.outputs.recording_sink import settle_when_rerun_loads

    settle_when_rerun_loads()
    gc.freeze()


def _cmd_run(args: argparse.Namespace) -> int:
    from twin.outputs.plot_process import PlotProcess

    # the plots' own process, started first: it imports matplotlib while this one checks,
    # builds, sets up and runs (twin.outputs.plot_process); stopped at once on bad input
    plots = PlotProcess.started()
    try:
        return _run(args, plots)
    finally:
        if plots is not None:
            plots.close()


def _run(args: argparse.Namespace, plots: PlotProcess | None) -> int:
    import functools
    import time

    from twin.errormodel.config import evaluation_config
    from twin.outputs.run_folder import RunFolder, output_folder
    from twin.pipeline import run
    from twin.validation.replay import MAX_SAMPLES, for_run

    start = time.perf_counter()
    # from here a Ctrl-C asks the command to stop; the run folder, once made, then holds
    # everything recorded and a summary saying "interrupted"
    stop = _stop_on_signals()
    scenario = _load(args)
    evaluation_config(scenario)  # the error model's checks, as twin validate makes them
    if args.uncertainty is not None and not 0 <= args.uncertainty <= MAX_SAMPLES:
        raise ConfigError(
            f"expected a number of samples in [0, {MAX_SAMPLES}], got {args.uncertainty}",
            source="--uncertainty",
        )
    path = _scenario_path(args.scenario)
    uncertainty = for_run(path, args.set or [], args.uncertainty)  # checked before the run
    out = output_folder(args.out, Path("runs") / scenario.name)  # checked before anything runs
    every = _checkpoint_every(args.checkpoint_every, scenario.step_ns)
    _build_fmus(scenario, stop)
    _check_fmus_accept(scenario)  # before the run folder is made: bad input runs nothing
    folder = RunFolder(out)
    folder.lock()  # for the command's whole life, Monte Carlo included: one process per folder
    try:
        _refuse_an_earlier_run(out, args.force)
        if args.own_process:
            _settle_the_run_process()
        stage = functools.partial(
            run,
            scenario,
            out,
            process_start=args.process_start or start,
            overrides=args.set or [],
            checkpoint_every_ns=every,
            plot_process=plots,
        )
        summary = _supervised(args.quiet, stage, stop)
        if plots is not None:
            plots.close()  # the plots are drawn: the helper ends before the Monte Carlo's workers start
        if uncertainty is not None and summary.status == "completed" and stop() is None:
            summary = _uncertainty(uncertainty, out, summary, args.quiet, stop)
        return _finish(summary, out, args.quiet, stop())
    finally:
        folder.unlock()


def _build_fmus(scenario: Scenario, stop: Callable[[], str | None]) -> None:
    """Build (or find in the cache) the scenario's FMUs before the run folder is touched, and
    end the command as interrupted (nothing written) if a signal came meanwhile: a Ctrl-C on a
    terminal reaches cmake too, and the build it broke is not a build error."""
    from twin.fmu import catalog

    try:
        for model in sorted({f.model for f in scenario.fmus}):
            catalog.fmu(model)
    except TwinError:
        if stop() is not None:
            raise KeyboardInterrupt from None
        raise
    if stop() is not None:
        raise KeyboardInterrupt


def _uncertainty(
    uncertainty: RunUncertainty, out: Path, summary: RunSummary, quiet: bool, stop: Callable[[], str | None]
) -> RunSummary:
    """The replay's Monte Carlo after its run; a Ctrl-C ends it after its finished samples,
    and summary.json then says "interrupted" (the run's own outputs are complete)."""
    import dataclasses
    import json

    from twin.outputs.run_folder import SUMMARY_JSON
    from twin.outputs.summary import write_summary
    from twin.validation.replay import finish_run

    caught = finish_run(uncertainty, out, (lambda _: None) if quiet else print, stop)
    if caught is None:
        return summary
    why = f"interrupted by {caught} during the uncertainty's Monte Carlo (the run's own outputs are complete)"
    data = json.loads((out / SUMMARY_JSON).read_text(encoding="utf-8"))
    data.update(status="interrupted", error=why)
    write_summary(out / SUMMARY_JSON, data)
    return dataclasses.replace(summary, status="interrupted", error=why)


def _refuse_an_earlier_run(out: Path, force: bool) -> None:
    """A run folder holding an earlier run's outputs is replaced only with ``--force`` (then
    the run removes them first, so none stays beside the new ones)."""
    from twin.outputs.run_folder import RUN_OUTPUTS

    if force or not out.is_dir():
        return
    earlier = sorted(n for n in RUN_OUTPUTS if (out / n).exists())
    if earlier:
        raise ConfigError(
            f"{out} holds an earlier run ({', '.join(earlier[:3])}{', ...' if len(earlier) > 3 else ''}): "
            "--force replaces it, or name another --out",
            source="--out",
        )


def _refuse_another_commands_outputs(out: Path, force: bool) -> None:
    """compensate writes into its own earlier output folder as it is (its files replace
    theirs), but over a run's, a sweep's or a held-out test's outputs (run.json, or a
    summary.json that is not a compensation's) only with ``--force``: their summary.json and
    errormodel.csv would be lost without a word."""
    import json

    from twin.outputs.run_folder import RUN_FILE, SUMMARY_JSON

    if force or not out.is_dir():
        return
    found = [RUN_FILE] if (out / RUN_FILE).exists() else []
    summary = out / SUMMARY_JSON
    if summary.exists():
        try:
            # a compensation's summary has input_rows; a run's, a sweep's or a test's has none
            own = "input_rows" in json.loads(summary.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, ValueError, TypeError):
            own = False  # unreadable: not known to be a compensation's, so not overwritten
        if not own:
            found.append(SUMMARY_JSON)
    if found:
        raise ConfigError(
            f"{out} holds another command's outputs ({', '.join(found)}): --force writes over "
            "them, or name another --out",
            source="--out",
        )


def _cmd_resume(args: argparse.Namespace) -> int:
    import functools
    import time

    from twin.outputs.run_folder import RunFolder, output_folder
    from twin.pipeline import resume_run

    start = time.perf_counter()
    stop = _stop_on_signals()
    out = output_folder(args.run_dir, Path(), option="resume")  # a folder it can write in
    if not out.is_dir():
        raise ConfigError("no such folder (no run.json): not a run folder", source=str(out))
    folder = RunFolder(out)
    folder.lock()  # before its checkpoint is read: no other process may write there meanwhile
    try:
        stage = functools.partial(resume_run, out, process_start=start)
        summary = _supervised(args.quiet, stage, stop)
        return _finish(summary, out, args.quiet, stop())
    finally:
        folder.unlock()


def _cmd_validate(args: argparse.Namespace) -> int:
    from twin.errormodel.config import evaluation_config
    from twin.validation.replay import for_run

    # the checks twin run makes before it runs: the scenario, its error model (with the
    # columns it reads), its [uncertainty] table
    scenario = _load(args)
    evaluation_config(scenario)
    for_run(_scenario_path(args.scenario), args.set or [], None)
    _check_fmus_accept(scenario)
    print(
        f"{scenario.source_path}: ok ({scenario.name}: {len(scenario.fmus)} FMUs, "
        f"{len(scenario.connections)} connections, {len(scenario.profiles)} profiles, {len(scenario.events)} events)"
    )
    return 0


def _check_fmus_accept(scenario: Scenario) -> None:
    """The FMUs' own checks of their parameters (twin validate, and twin run before its run
    folder is made): each FMU instantiated and initialized, none stepped (3-10 ms; the run's
    own set-up is then the faster for the libraries loaded). A refusal is bad input: one line
    naming the instance's parameters and the FMU's reason."""
    from twin.cosim.instances import check_initialization
    from twin.cosim.plan import make_plan
    from twin.errors import FMUError

    try:
        check_initialization(make_plan(scenario))
    except FMUError as exc:
        raise ConfigError(
            f"the FMU refuses them in {exc.call}: {exc.detail}",
            source=scenario.source_path,
            key=f"fmu.{exc.instance}.parameters",
        ) from None


def _cmd_compensate(args: argparse.Namespace) -> int:
    from twin.outputs.run_folder import output_folder
    from twin.pipeline import compensate
    from twin.pipeline.compensation import run_folder_config, write_template

    if args.template is not None:
        for path in write_template(Path(args.template)):
            print(f"written: {path}")
        print(
            f"try: twin compensate {Path(args.template) / 'lab.csv'} --config {Path(args.template) / 'LAB.toml'}"
        )
        return 0
    if args.csv is None:
        raise ConfigError("name a CSV or a run folder (or --template DIR)", source="compensate")
    csv, config = Path(args.csv), None
    if csv.is_dir():  # a run folder: its signals.csv with its own run's error model
        if args.config:
            raise ConfigError(
                "a run folder brings its own error model: leave out --config", source="--config"
            )
        run_dir = csv
        csv, config = run_folder_config(run_dir)
        out = output_folder(args.out, run_dir.with_name(run_dir.name + "-compensated"))
    else:
        out = output_folder(args.out, csv.with_name(csv.stem + "-compensated"))
    _refuse_another_commands_outputs(out, args.force)
    summary = compensate(csv, Path(args.config) if args.config else None, out, config)
    flagged = summary["input_rows"]["flagged"]
    if flagged:
        first = summary["input_rows"]["first_flagged"][0]
        print(
            f"twin: {csv}: {flagged} row(s) flagged and left out, the rest computed (first: {first}); "
            f"every one in {out / summary['input_rows']['flagged_rows']}",
            file=sys.stderr,
        )
    parts = summary["error_parts_mm"]
    print(
        f"{csv}: predicted error over the record {parts['total']:+.4f} mm "
        f"(thermal {parts['thermal']:+.4f}); outputs: {out}"
    )
    return 0


def _cmd_geometry(args: argparse.Namespace) -> int:
    from twin.config.load import scenarios_dir
    from twin.geometry import write_derived_files

    folder = Path(args.scenarios) if args.scenarios else scenarios_dir()
    for path in write_derived_files(folder):
        print(f"derived parameters written to {path}")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from twin.calibrate import calibrate_file
    from twin.outputs.run_folder import check_output_file

    # checked before the fits (seconds): a parameter file .toml, its report beside it as .json
    out = check_output_file(Path(args.out), "--out", ".toml") if args.out is not None else None
    path = calibrate_file(Path(args.scenario) if args.scenario else None, out, write=args.write)
    print(f"calibrated thermal network written to {path}")
    return 0


def make_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="twin", description="Co-simulation digital twin of a spherical plain bearing tester."
    )
    parser.add_argument("--version", action="version", version=f"twin {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    p = sub.add_parser("build", help="build every FMU in fmus/ (into the cache, or --out DIR)")
    p.add_argument("--out", metavar="DIR", help="write the .fmu files here instead of the cache")
    p.set_defaults(func=_cmd_build)

    p = sub.add_parser(
        "list", help="the shipped scenarios and calibration experiments, with their descriptions"
    )
    p.set_defaults(func=_cmd_list)

    p = sub.add_parser("run", help="run a scenario (default: the paper's 480 min thermal experiment)")
    p.add_argument(
        "scenario",
        nargs="?",
        help="scenario TOML file, an SSP archive (.ssp), or a shipped scenario's name, e.g. sine-load "
        "(default: li2017-thermal-experiment)",
    )
    p.add_argument("--out", metavar="DIR", help="run folder (default: runs/<scenario name>)")
    p.add_argument(
        "--force", action="store_true", help="replace the outputs of an earlier run in the run folder"
    )
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="override a scenario value by its dotted key"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary line")
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
    p.set_defaults(func=_cmd_run, process_start=None)

    p = sub.add_parser("resume", help="continue a killed or interrupted run from its last checkpoint")
    p.add_argument("run_dir", help="the run folder (holds run.json and checkpoint.npz)")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary line")
    p.set_defaults(func=_cmd_resume)

    p = sub.add_parser("validate", help="check a scenario without running it")
    p.add_argument("scenario", help="scenario TOML file, SSP archive (.ssp) or shipped scenario's name")
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="override a scenario value by its dotted key"
    )
    p.set_defaults(func=_cmd_validate)

    p = sub.add_parser("compensate", help="run the error model on a CSV of measurements (a lab's or a run's)")
    p.add_argument(
        "csv",
        nargs="?",
        help="CSV with a time column (s) and named columns in SI units, or a run folder (its own error model)",
    )
    p.add_argument(
        "--template", metavar="DIR", help="write a commented LAB.toml and an example lab.csv into DIR"
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="[errormodel] column map and coefficients (default: the twin's names)",
    )
    p.add_argument("--out", metavar="DIR", help="output folder (default: <csv stem>-compensated)")
    p.add_argument(
        "--force",
        action="store_true",
        help="write into an --out folder that holds another command's outputs (a run's, a sweep's)",
    )
    p.set_defaults(func=_cmd_compensate)

    p = sub.add_parser(
        "geometry",
        help="derive the FMUs' lengths, capacities and conductances from base/tester-geometry.toml",
    )
    p.add_argument("--scenarios", metavar="DIR", help="scenarios folder (default: the shipped one)")
    p.set_defaults(func=_cmd_geometry)

    p = sub.add_parser("calibrate", help="fit the thermal network to the paper's measured temperature rises")
    p.add_argument(
        "scenario", nargs="?", help="scenario whose thermal network is calibrated (default: the paper's)"
    )
    p.add_argument(
        "--out", metavar="FILE", help="parameter file to write (default: runs/calibrate/<name>.toml)"
    )
    p.add_argument(
        "--write",
        action="store_true",
        help="replace the calibration file the scenario includes (the committed one)",
    )
    p.set_defaults(func=_cmd_calibrate)
    identify_cli.add_parser(sub)
    inspect_cli.add_parser(sub)
    ssp_cli.add_parser(sub)
    add_sweep_parser(sub)
    heldout_cli.add_parser(sub)
    return parser


def main(argv: Sequence[str] | None = None, *, own_process: bool = False) -> int:
    """The ``twin`` command on ``argv`` (default: ``sys.argv[1:]``); its exit code.

    ``own_process`` says the process is the command's alone (the console script and
    ``python -m twin``): ``twin run`` then settles it for the run (:func:`_settle_the_run_process`).
    A program that calls this function itself keeps its process as it was."""
    parser = make_parser()
    try:
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        args.own_process = own_process
        return int(args.func(args))
    except BrokenPipeError:
        # the reader went away (`twin inspect X | head`): nothing left to say, and no traceback
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 0
    except KeyboardInterrupt:
        # Ctrl-C before a run's own handler is in place (imports, the FMU build) or after it
        # (the replay's Monte Carlo): nothing half-written is left behind by either
        print("twin: interrupted", file=sys.stderr)
        return 130
    except TwinError as exc:
        for line in str(exc).splitlines():  # several problems: one line each
            print(f"twin: {line}", file=sys.stderr)
        return exc.exit_code
    except OSError as exc:
        # a file the command had to write or read failed it (a full disk while the Monte
        # Carlo writes uncertainty.csv, a folder removed under a run): one line, exit 1
        print(f"twin: {_os_error(exc)}", file=sys.stderr)
        return 1


def _os_error(exc: OSError) -> str:
    from twin.outputs.run_folder import DISK_FULL_ERRNOS

    if exc.errno in DISK_FULL_ERRNOS:
        return f"disk full ({exc.strerror}) while writing {exc.filename or 'an output file'}"
    return f"{exc.filename}: {exc.strerror}" if exc.filename else str(exc)


if __name__ == "__main__":
    sys.exit(main(own_process=True))
