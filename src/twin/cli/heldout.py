"""``twin heldout [FILE]``: the error model judged on testers as built that it was not
identified on, beside the group's MLR + AR baseline (:mod:`twin.validation.heldout`)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.cli import interrupt
from twin.cli.common import flag, mark_study, optional, stop_on_signals
from twin.errors import ConfigError

NAME = "heldout"
DEFAULT_FILE = "validation/heldout.toml"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME,
        help="identify testers as built on the calibration runs, judge the error model on held-out scenarios",
    )
    optional(p, "file", f"held-out file (default: scenarios/{DEFAULT_FILE})")
    p.add_argument("--testers", type=int, metavar="N", help="number of testers (default: the file's)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: sweeps/heldout)")
    p.add_argument(
        "--scheduler", metavar="ADDR", help="an existing Dask scheduler (default: a local cluster)"
    )
    p.add_argument("--workers", type=int, metavar="N", help="local cluster size (default: one per core)")
    flag(p, "--resume", "run only the testers the output folder lacks")
    flag(p, "--quiet", "print only the last line")
    return p


def command(args: argparse.Namespace) -> int:
    """Run the held-out validation; exit code 0 (goals missed are figures, not errors)."""
    from twin.config.load import scenarios_dir
    from twin.outputs.run_folder import check_output_folder
    from twin.pipeline import RunControls
    from twin.pipeline.cluster import StudyOptions
    from twin.validation.heldout import interrupted, load_heldout, report_lines, run_heldout

    if args.testers is not None and args.testers < 1:
        raise ConfigError("expected at least one tester", source="--testers")
    if args.workers is not None and args.workers < 1:
        raise ConfigError("expected at least one worker", source="--workers")
    cfg = load_heldout(Path(args.file) if args.file else scenarios_dir() / DEFAULT_FILE, testers=args.testers)
    out = Path(args.out) if args.out is not None else Path("sweeps") / "heldout"
    check_output_folder(out, "--out")
    echo = (lambda _: None) if args.quiet else print
    controls = RunControls(stop=stop_on_signals(), echo=echo)
    interrupt.on_hard_exit(lambda name: mark_study(out, interrupted(cfg, name)), where=str(out))
    with interrupt.cooperative():
        summary = run_heldout(cfg, out, controls, StudyOptions(args.scheduler, args.workers, args.resume))
        if summary.get("status") == "interrupted":
            interrupt.say(f"twin: heldout {summary['error']}; the testers that finished are in {out}")
            return interrupt.exit_code()
    for line in report_lines(summary):
        echo(line)
    print(f"heldout: {summary['testers']} testers, outputs in {out}")
    return 0
