"""``twin update [RECORD]``: the twin's uncertain parameters updated from a lab's record
(:mod:`twin.calibration.update`); the paper's record by default."""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Any

from twin.cli.common import flag, optional
from twin.errors import ConfigError

NAME = "update"
DEFAULT_FILE = "records/li2017.toml"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(NAME, help="update the twin's uncertain parameters from a record (Bayesian, emcee)")
    optional(p, "record", f"record file (default: scenarios/{DEFAULT_FILE}, the paper's)")
    p.add_argument("--out", metavar="DIR", help="output folder (default: runs/update-<record>)")
    p.add_argument(
        "--prior",
        metavar="TOML",
        help="the prior file the update starts from (default: the record's [record] prior; the paper's: "
        "scenarios/base/priors.toml)",
    )
    p.add_argument("--seed", type=int, metavar="N", help="the sampler's seed (default: the record's)")
    p.add_argument("--walkers", type=int, metavar="N", help="emcee walkers (default: the record's)")
    p.add_argument("--steps", type=int, metavar="N", help="steps per walker (default: the record's)")
    p.add_argument("--burn", type=int, metavar="N", help="steps discarded (default: the record's)")
    flag(
        p,
        "--write",
        "also write the updated tester file where the record's [tester] file says (the paper's: "
        "the repository's scenarios/records/li2017-updated.toml, the tester `twin run` runs by "
        "default; it needs the editable install `pip install -e .`)",
    )
    flag(p, "--quiet", "print only the last line")
    return p


def command(args: argparse.Namespace) -> int:
    """Run the update; exit code 0 (a goal missed is a figure, not an error)."""
    from twin.calibration.update import check_out, load_record, report_lines, run_update
    from twin.config.load import check_not_installed_copy, scenarios_dir
    from twin.outputs.run_folder import check_output_folder

    for option in ("seed", "walkers", "steps", "burn"):
        value = getattr(args, option)
        if value is not None and value < 0:
            raise ConfigError(f"expected a number >= 0, got {value}", source=f"--{option}")
    path = Path(args.record) if args.record else scenarios_dir() / DEFAULT_FILE
    if not path.is_file():
        raise ConfigError("no such record file", source=str(path))
    overrides = {k: getattr(args, k) for k in ("walkers", "steps", "burn") if getattr(args, k) is not None}
    record = load_record(path, seed=args.seed, sampler=overrides)
    if args.prior is not None:
        if not Path(args.prior).is_file():
            raise ConfigError("no such prior file", source=f"--prior {args.prior}")
        record = dataclasses.replace(record, prior=Path(args.prior).resolve())
    if args.write and record.tester_file is not None:  # before the update's minute
        check_not_installed_copy(record.tester_file, "--write")
    out = Path(args.out) if args.out is not None else Path("runs") / f"update-{record.name}"
    check_output_folder(out, "--out")
    check_out(out)
    echo = (lambda _: None) if args.quiet else print
    summary = run_update(record, out, echo, write=args.write)
    for line in report_lines(summary):
        echo(line)
    print(f"update: {record.name}, outputs in {out} (the updated tester: {out / 'tester.toml'})")
    return 0
