"""``twin sweep SPEC.toml [--out DIR] [--scheduler ADDRESS] [--workers N] [--resume] [--quiet]``:
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
        "--workers", type=_positive, metavar="N", help="workers of the local cluster (default: one per core)"
    )
    flag(p, "--resume", "complete the sweep in --out: run only the missing points")
    flag(p, "--quiet", "no progress bar, no messages")
    return p


@contextmanager
def _progress_bar(quiet: bool) -> Iterator[Callable[[int, int, int], None] | None]:
    """A tqdm bar on a terminal (points done, failed, rate, ETA); nothing otherwise."""
    if quiet or not sys.stderr.isatty():
        yield None
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

    if args.scheduler is not None and args.workers is not None:
        raise ConfigError("applies to the local cluster only, not with --scheduler", source="--workers")
    spec = load_spec(args.spec)
    out = Path(args.out) if args.out is not None else Path("sweeps") / spec.name
    check_output_folder(out, "--out")
    controls = RunControls(stop=stop_on_signals(), echo=(lambda _: None) if args.quiet else _print)
    stopped = {"sweep": spec.name, "status": "interrupted"}
    interrupt.on_hard_exit(
        lambda name: mark_study(out, stopped | {"error": f"interrupted by {name}"}), str(out)
    )
    with interrupt.cooperative(), _progress_bar(args.quiet) as update:
        options = StudyOptions(args.scheduler, args.workers, args.resume, update)
        try:
            summary = run_sweep(spec, out, controls, options)
        except SweepInterrupted as name:
            interrupt.say(f"twin: sweep interrupted by {name}; the points that finished are in {out}")
            return EXIT_ON_SIGNAL.get(str(name), 130)
    controls.echo(summary_line(summary, out))
    return 0


def _print(line: str) -> None:
    print(line, flush=True)
