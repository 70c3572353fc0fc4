"""What every command shares: the parser that refuses in one line, the signals that ask a run
to stop, the progress bar, and the exit code of a run's outcome."""

from __future__ import annotations

import argparse
import re
import signal
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from twin.cli import interrupt
from twin.cli.interrupt import EXIT_ON_SIGNAL
from twin.errors import ConfigError

__all__ = [
    "EXIT_ON_SIGNAL",
    "Parser",
    "add_experiment",
    "experiment",
    "finish",
    "mark_study",
    "progress_bar",
    "stop_on_signals",
]


class Parser(argparse.ArgumentParser):
    """argparse that reports bad arguments as one line and exit code 2, and refuses an empty
    argument (the commands read a missing one as "the default", and ``--out ""`` once
    rewrote the committed coefficients file)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        # the line starts "twin: " already: name the subcommand, not "twin" a second time
        raise ConfigError(message, source=self.prog.removeprefix("twin").strip() or None)

    def parse_known_args(
        self, args: Any = None, namespace: Any = None
    ) -> tuple[argparse.Namespace, list[str]]:  # type: ignore[override]
        parsed, extras = super().parse_known_args(args, namespace)
        for action in self._actions:
            value = getattr(parsed, action.dest, None)
            values = value if isinstance(value, list) else [value]
            if any(isinstance(v, str) and not v.strip() for v in values):
                if action.option_strings:
                    raise ConfigError("is empty", source=max(action.option_strings, key=len))
                command = self.prog.removeprefix("twin").strip() or None
                raise ConfigError(f"the {action.dest.replace('_', ' ')} is empty", source=command)
        return parsed, extras


def flag(p: argparse.ArgumentParser, name: str, help: str) -> None:
    """A true-or-false option ``name`` (``--force``, ``--quiet``)."""
    p.add_argument(name, action="store_true", help=help)


def optional(p: argparse.ArgumentParser, name: str, help: str) -> None:
    """A positional argument that may be left out."""
    p.add_argument(name, nargs="?", help=help)


def add_set(p: argparse.ArgumentParser) -> None:
    """The ``--set KEY=VALUE`` option of a command that loads a scenario."""
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE", help="override a scenario value by its dotted key"
    )


#: the updated tester ``twin run`` runs when it names no scenario: the paper's tester, updated
#: from its record by ``twin update --write`` (relative to the scenarios folder)
DEFAULT_TESTER = "records/li2017-updated.toml"
#: what ``--tester`` takes for no tester: the twin before any record
NO_TESTER = "none"


def add_tester(p: argparse.ArgumentParser, what: str) -> None:
    """The ``--tester FILE`` option: an updated tester file written by ``twin update``."""
    p.add_argument(
        "--tester", metavar="FILE", help=f"an updated tester file (twin update's tester.toml): {what}"
    )


def tester_path(value: str | None, default: bool) -> Path | None:
    """The tester file ``--tester`` names; ``default``: the paper's updated tester when none is
    named (``none``: the twin before any record)."""
    if value == NO_TESTER:
        return None
    if value is None:
        if not default:
            return None
        from twin.config.load import scenarios_dir

        return scenarios_dir() / DEFAULT_TESTER
    return Path(value)


def add_experiment(p: argparse.ArgumentParser) -> None:
    """The experiment's options, as fmpy's ``simulate`` names them: times (seconds, or a
    duration with its unit) and an input file."""
    times = (
        ("--start-time", "when the run begins: the FMUs' start time and the master's first tick"),
        ("--stop-time", "when the run ends (sets scenario.duration: the scenario's clock starts at 0)"),
        ("--step-size", "the master's step (scenario.step); an FMU without a period steps at it"),
        ("--output-interval", "how often a row is recorded (scenario.output_interval)"),
    )
    for name, text in times:
        p.add_argument(name, metavar="TIME", help=f"{text}; seconds or a duration, e.g. 10 or '10 min'")
    p.add_argument(
        "--input-file",
        metavar="CSV",
        help="a CSV (time, then columns named instance.variable) whose columns drive those inputs",
    )


def experiment(args: argparse.Namespace) -> Any:
    """The :class:`~twin.config.experiment.Experiment` the options of :func:`add_experiment` give."""
    from twin.config.experiment import Experiment

    return Experiment(
        start=args.start_time,
        stop=args.stop_time,
        step=args.step_size,
        output_interval=args.output_interval,
        input_file=args.input_file,
    )


def stop_on_signals() -> Callable[[], str | None]:
    """SIGINT and SIGTERM ask the run to stop at its next batch (it keeps everything recorded
    and says "interrupted"); the function returned names the signal that came, if one did. A
    flag, not an exception: raised from a handler, it could land in a library's callback.

    In a process of its own the watcher of :mod:`twin.cli.interrupt` receives them already;
    called from a program, the command's handlers are put in place here."""
    if not interrupt.installed():

        def handler(signum: int, frame: object) -> None:
            interrupt.record(signum)

        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
    return interrupt.caught


def mark_study(out: Path, summary: dict[str, Any]) -> None:
    """Write the summary of a study (a sweep, a held-out validation) that the signal's watcher
    ends (:mod:`twin.cli.interrupt`): one that says "interrupted" is never replaced, nor a
    folder made."""
    from twin.outputs.summary import write_summary

    path = out / "summary.json"
    if out.is_dir() and not (path.is_file() and '"interrupted"' in path.read_text(encoding="utf-8")):
        write_summary(path, summary)


@contextmanager
def progress_bar(quiet: bool) -> Iterator[Callable[[int, int], None] | None]:
    """A progress bar on a terminal (tqdm) for a run's co-simulation and outputs; nothing with
    ``quiet`` or without a terminal. Yields the run's progress callback."""
    if quiet or not sys.stderr.isatty():
        yield None
        return
    import shutil

    from tqdm import tqdm

    # a pseudo-terminal may report 0 columns and rows, with which tqdm draws nothing
    size = shutil.get_terminal_size((80, 24))
    bar = tqdm(total=100, unit="%", desc="loading FMUs", leave=False, file=sys.stderr,
               ncols=size.columns or 80, nrows=size.lines or 24)  # fmt: skip

    def update(now_ns: int, total_ns: int) -> None:
        bar.n = round(100 * now_ns / total_ns)
        desc = "writing outputs" if now_ns >= total_ns else "simulating"
        if bar.desc != desc:
            bar.set_description_str(desc, refresh=False)
        bar.refresh()

    try:
        yield update
    finally:
        bar.close()


def finish(summary: Any, out: Path, quiet: bool, caught: str | None = None) -> int:
    """Print a run's summary line and say where its outputs are; the exit code of its outcome
    (130/143 for a run a signal stopped)."""
    if not quiet:
        print(summary.line())
        print(f"outputs: {out}")
    if summary.status == "interrupted":
        why = summary.error or "interrupted"
        interrupt.say(f"twin: run {why}; everything recorded so far is in {out}")
        name = re.search(r"\bby (SIG[A-Z]+)", why)
        return EXIT_ON_SIGNAL.get(name.group(1) if name else "", 130)
    if caught is not None:  # after everything was written: the outputs are complete
        interrupt.say(f"twin: interrupted by {caught}; the run's outputs are complete in {out}")
        return EXIT_ON_SIGNAL.get(caught, 130)
    return 0
