"""``twin resume RUN_DIR``: continue a killed or interrupted run from its last checkpoint."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from twin.cli.common import finish, flag, progress_bar, stop_on_signals

NAME = "resume"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="continue a killed or interrupted run from its last checkpoint")
    p.add_argument("run_dir", help="the run folder (holds run.json and checkpoint.npz)")
    flag(p, "--quiet", "no progress bar, no summary line")
    return p


def command(args: argparse.Namespace) -> int:
    from twin.cli import interrupt
    from twin.cli.run import watch_folder
    from twin.pipeline import RunControls, RunOptions, prepare_resume, run
    from twin.validation import reports

    started = time.perf_counter()
    stop = stop_on_signals()
    out = Path(args.run_dir)
    with prepare_resume(out, RunOptions(reports=reports, started=started)) as prepared:
        watch_folder(out, prepared.uncertainty is not None, prepared.scenario.name)
        with interrupt.cooperative(), progress_bar(args.quiet) as update:
            summary = run(prepared, RunControls(stop=stop, progress=update))
            return finish(summary, out, args.quiet, stop())
