"""``twin compensate CSV|RUN_DIR [--config LAB.toml]``: the error model on a lab's record or a
run's signals (``--template DIR`` writes a commented LAB.toml and an example lab.csv)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from twin.cli.common import add_tester, flag, optional
from twin.errors import ConfigError

NAME = "compensate"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="run the error model on a CSV of measurements (a lab's or a run's)")
    optional(
        p,
        "csv",
        "CSV with a time column and named columns (SI unless LAB.toml gives their units), or a run "
        "folder (its own error model)",
    )
    p.add_argument(
        "--template", metavar="DIR", help="write a commented LAB.toml and an example lab.csv into DIR"
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="[errormodel] column map and coefficients (default: the twin's names)",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        help="output folder (default: beside the input: <csv stem>-compensated next to a CSV, "
        "<run folder>-compensated next to a run folder)",
    )
    add_tester(p, "the error model takes its coefficients (identified on it by twin identify --tester)")
    flag(p, "--force", "write into an --out folder that holds another command's outputs (a run's, a sweep's)")
    return p


def command(args: argparse.Namespace) -> int:
    from twin.pipeline import compensation

    if args.template is not None:
        for path in compensation.write_template(Path(args.template)):
            print(f"written: {path}")
        print(
            f"try: twin compensate {Path(args.template) / 'lab.csv'} --config {Path(args.template) / 'LAB.toml'}"
        )
        return 0
    if args.csv is None:
        raise ConfigError("name a CSV or a run folder (or --template DIR)", source="compensate")
    job = compensation.job(
        Path(args.csv),
        Path(args.config) if args.config else None,
        Path(args.out) if args.out else None,
        args.force,
    )
    lab = job.config_path if args.tester is None else _tester_lab(job, Path(args.tester))
    summary = compensation.compensate(job.csv, lab, job.out, job.config)
    flagged = summary["input_rows"]["flagged"]
    if flagged:
        first = summary["input_rows"]["first_flagged"][0]
        print(
            f"twin: {job.csv}: {flagged} row(s) flagged and left out, the rest computed (first: {first}); "
            f"every one in {job.out / summary['input_rows']['flagged_rows']}",
            file=sys.stderr,
        )
    if summary["coefficients"] == compensation.DEFAULT_COEFFICIENTS:
        print(
            f"twin: {job.csv}: compensated with the twin's default coefficients, not your tester's: "
            "name its own in LAB.toml ([errormodel] coefficients, written by twin identify)",
            file=sys.stderr,
        )
    parts = summary["error_parts_mm"]
    print(
        f"{job.csv}: predicted error over the record {parts['total']:+.4f} mm "
        f"(thermal {parts['thermal']:+.4f}), compensated wear {summary['wear_mm']['compensated']:+.4f} mm; "
        f"outputs: {job.out}"
    )
    return 0


def _tester_lab(job: Any, tester: Path) -> Any:
    """LAB.toml read with the updated tester's coefficients (a run folder brings its own)."""
    from twin.pipeline.compensation import lab_config
    from twin.uncertainty.updated import load_updated

    if job.config is not None:
        raise ConfigError("a run folder brings its own error model: leave out --tester", source="--tester")
    updated = load_updated(tester)
    if updated.coefficients is None:
        raise ConfigError(
            "names no coefficients: identify them on it (twin identify --tester FILE --out C.toml) "
            "and name C.toml in its [tester] coefficients",
            source=str(tester),
            key="tester.coefficients",
        )
    return lab_config(job.config_path, updated.coefficients)
