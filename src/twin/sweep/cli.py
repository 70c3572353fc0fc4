"""``twin sweep SPEC.toml [--out DIR] [--scheduler ADDRESS] [--workers N] [--resume] [--quiet]``.

Exit codes as the rest of ``twin``: 0 done (failed points are results, not errors), 2 bad
input (one line per problem, ``file: key: what``), 1 a failure of the sweep itself (the
scheduler lost), 130/143 interrupted (everything finished so far is in the table).
"""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from twin.errors import ConfigError, TwinError

_EXIT_ON_SIGNAL = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _positive(text: str) -> int:
    try:
        n = int(text)
    except ValueError:
        n = 0
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a positive number of workers, got {text!r}")
    return n


def add_sweep_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``sweep`` command to ``twin``'s subparsers."""
    p = subparsers.add_parser(
        "sweep", help="run a sweep, Monte Carlo or sensitivity analysis of a scenario on Dask"
    )
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
    p.add_argument(
        "--resume", action="store_true", help="complete the sweep in --out: run only the missing points"
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar, no messages")
    p.set_defaults(func=cmd_sweep)
    return p


def _progress_bar(quiet: bool) -> tuple[Callable[[int, int, int], None] | None, Callable[[], None]]:
    """A tqdm bar on a terminal (points done, failed, rate, ETA); nothing otherwise."""
    if quiet or not sys.stderr.isatty():
        return None, lambda: None
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

    return update, bar.close


def _stop_on_signals() -> Callable[[], str | None]:
    """SIGINT/SIGTERM set a flag the sweep reads after each point: an exception raised from
    the handler itself could land in a finalizer or a library's callback and be lost."""
    caught: dict[str, str] = {}

    def handler(signum: int, frame: object) -> None:
        caught.setdefault("name", signal.Signals(signum).name)

    for signum in _EXIT_ON_SIGNAL:
        signal.signal(signum, handler)
    return lambda: caught.get("name")


def cmd_sweep(args: argparse.Namespace) -> int:
    """Run the sweep the arguments describe; returns the exit code."""
    from twin.sweep.runner import SweepInterrupted, run_sweep
    from twin.sweep.spec import load_spec

    if args.scheduler is not None and args.workers is not None:
        raise ConfigError("applies to the local cluster only, not with --scheduler", source="--workers")
    spec = load_spec(args.spec)
    from twin.outputs.run_folder import output_folder

    out = output_folder(args.out, Path("sweeps") / spec.name)
    echo = (lambda _: None) if args.quiet else (lambda line: print(line, flush=True))
    update, close = _progress_bar(args.quiet)
    stop = _stop_on_signals()
    try:
        summary = run_sweep(
            spec,
            out,
            scheduler=args.scheduler,
            workers=args.workers,
            resume=args.resume,
            progress=update,
            echo=echo,
            stop=stop,
        )
    except SweepInterrupted as name:
        close()
        print(f"twin: sweep interrupted by {name}; the points that finished are in {out}", file=sys.stderr)
        return {s.name: code for s, code in _EXIT_ON_SIGNAL.items()}.get(str(name), 130)
    close()
    echo(_summary_line(summary, out))
    return 0


def _summary_line(summary: dict[str, Any], out: Path) -> str:
    t = summary["timing"]
    line = (
        f"sweep {summary['sweep']}: {summary['points']} points, {summary['ok']} ok, {summary['failed']} failed"
        f" ({t['points_run']} run in {t['elapsed_s']:.1f} s)"
    )
    main = summary.get("main_output")
    stats = summary["outputs"].get(main, {}) if main else {}
    if stats.get("n"):
        line += f"; {main}: median {stats['q50']:.4g}, 5-95 % [{stats['q05']:.4g}, {stats['q95']:.4g}]"
    return f"{line}; outputs: {out}"


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad arguments as one line and exit code 2 (as ``twin`` does)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise ConfigError(message, source=self.prog)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m twin.sweep``: the ``twin sweep`` command on its own."""
    parser = _Parser(prog="twin", description="Sweeps, Monte Carlo and sensitivity analysis of the twin.")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)
    add_sweep_parser(sub)
    try:
        args = parser.parse_args(["sweep", *(sys.argv[1:] if argv is None else argv)])
        return int(args.func(args))
    except TwinError as exc:
        for line in str(exc).splitlines():
            print(f"twin: {line}", file=sys.stderr)
        return exc.exit_code
