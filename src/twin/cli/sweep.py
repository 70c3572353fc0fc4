"""``twin sweep SPEC.toml [--out DIR] [--scheduler ADDRESS | --scheduler-file FILE] [--workers N] [--resume] [--quiet]``:
a sweep, Monte Carlo or sensitivity analysis of a scenario on Dask.

Exit codes as the rest of ``twin``: 0 done (failed points are results, not errors), 2 bad
input (one line per problem, ``file: key: what``), 1 a failure of the sweep itself (the
scheduler lost), 130/143 interrupted (everything finished so far is in the table).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from twin.cli import interrupt
from twin.cli.common import EXIT_ON_SIGNAL, flag, mark_study, stop_on_signals
from twin.errors import ConfigError

NAME = "sweep"


def _positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive number of workers, got {text!r}")
    return n


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="run a sweep, Monte Carlo or sensitivity analysis of a scenario on Dask")
    p.add_argument("spec", help="sweep file (TOML): a base scenario and a design (see scenarios/sweeps/)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: sweeps/<sweep name>)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="an existing Dask scheduler (tcp://host:8786); default: a local cluster",
    )
    p.add_argument(
        "--scheduler-file",
        metavar="FILE",
        help="an existing Dask scheduler by its scheduler file (dask scheduler --scheduler-file FILE)",
    )
    p.add_argument(
        "--workers", type=_positive, metavar="N", help="workers of the local cluster (default: one per core)"
    )
    flag(p, "--resume", "complete the sweep in --out: run only the missing points")
    flag(p, "--quiet", "no progress bar or lines, no messages")
    return p


#: seconds between two progress lines without a terminal
LINE_EVERY_S = 10.0


def _progress_lines() -> Callable[[int, int, int], None]:
    """Without a terminal (a batch job's log, a pipe): a plain line on stderr every
    :data:`LINE_EVERY_S` and at the last point (done of total, failed, rate, time left)."""
    import time

    state = {"start": 0.0, "first": 0, "last": 0.0}

    def update(done: int, n_failed: int, total: int) -> None:
        now = time.monotonic()
        if not state["start"]:
            state.update(start=now, first=done - 1, last=now)
        if now - state["last"] < LINE_EVERY_S and done < total:
            return
        state["last"] = now
        rate = (done - state["first"]) / max(now - state["start"], 1e-9)
        left = f", about {(total - done) / rate:.0f} s left" if rate > 0 and done < total else ""
        print(
            f"points: {done}/{total} done, {n_failed} failed, {rate:.1f} points/s{left}",
            file=sys.stderr,
            flush=True,
        )

    return update


@contextmanager
def _progress_bar(quiet: bool) -> Iterator[Callable[[int, int, int], None] | None]:
    """A tqdm bar on a terminal (points done, failed, rate, ETA), plain lines otherwise
    (:func:`_progress_lines`); nothing with ``--quiet``."""
    if quiet:
        yield None
        return
    if not sys.stderr.isatty():
        yield _progress_lines()
        return
    import shutil

    from tqdm import tqdm

    # a pseudo-terminal may report 0 columns and rows, with which tqdm draws nothing
    size = shutil.get_terminal_size((80, 24))
    bar = tqdm(
        total=0, unit="pt", desc="points", file=sys.stderr, ncols=size.columns or 80, nrows=size.lines or 24
    )
    first = [True]

    def update(done: int, n_failed: int, total: int) -> None:
        if first.pop() if first else False:
            # the clock starts with the first point, not with the cluster; points finished
            # before (--resume) do not count into the rate
            bar.reset(total=total)
            bar.initial = done - 1
        bar.n = done
        bar.set_postfix(failed=n_failed, refresh=False)
        bar.refresh()

    try:
        yield update
    finally:
        bar.close()


def command(args: argparse.Namespace) -> int:
    from twin.outputs.run_folder import check_output_folder
    from twin.pipeline import RunControls
    from twin.pipeline.cluster import StudyOptions
    from twin.sweep.runner import SweepInterrupted, run_sweep, summary_line
    from twin.sweep.spec import load_spec

    if (args.scheduler or args.scheduler_file) is not None and args.workers is not None:
        raise ConfigError("applies to the local cluster only, not with --scheduler", source="--workers")
    scheduler = _scheduler(args)
    spec = load_spec(args.spec)
    out = Path(args.out) if args.out is not None else Path("sweeps") / spec.name
    check_output_folder(out, "--out")
    controls = RunControls(stop=stop_on_signals(), echo=(lambda _: None) if args.quiet else _print)
    stopped = {"sweep": spec.name, "status": "interrupted"}
    interrupt.on_hard_exit(
        lambda name: mark_study(out, stopped | {"error": f"interrupted by {name}"}), str(out)
    )
    with interrupt.cooperative(), _progress_bar(args.quiet) as update:
        options = StudyOptions(scheduler, args.workers, args.resume, update)
        try:
            summary = run_sweep(spec, out, controls, options)
        except SweepInterrupted as name:
            interrupt.say(f"twin: sweep interrupted by {name}; the points that finished are in {out}")
            return EXIT_ON_SIGNAL.get(str(name), 130)
    controls.echo(summary_line(summary, out))
    return 0


def _scheduler(args: argparse.Namespace) -> str | None:
    """The existing scheduler's address, checked at once: its form, then that a Dask
    scheduler answers there (within the connect and answer timeouts), before any Client."""
    from twin.pipeline.cluster import check_scheduler, read_scheduler_file

    if args.scheduler is not None and args.scheduler_file is not None:
        raise ConfigError("give one of --scheduler and --scheduler-file, not both", source="--scheduler-file")
    if args.scheduler_file is not None:
        return check_scheduler(
            read_scheduler_file(args.scheduler_file), f"--scheduler-file {args.scheduler_file}"
        )
    return None if args.scheduler is None else check_scheduler(args.scheduler)


def _print(line: str) -> None:
    print(line, flush=True)
