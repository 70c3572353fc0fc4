"""``twin identify``: fit the error model's coefficients to calibration experiments run on the twin."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.cli.common import add_set, add_tester, flag
from twin.errors import ConfigError

NAME = "identify"
#: where the coefficients go without --out: the current folder (a file of the user's)
DEFAULT_OUT = "identified.toml"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME, help="fit the error model's coefficients to calibration experiments run on the twin"
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        help=(
            "coefficients file to write (default: identified.toml in the current folder; the "
            "committed scenarios/calibration/identified.toml is only written when named here)"
        ),
    )
    add_set(p)
    add_tester(p, "the calibration experiments run on it (its values as --set, before yours)")
    p.add_argument(
        "--priors", metavar="TOML", help="priors file (default: scenarios/calibration/priors.toml)"
    )
    p.add_argument(
        "--records",
        metavar="DIR",
        help=(
            "a lab's own records of the calibration experiments, one CSV per experiment named as its "
            "scenario (thermal-soak.csv, ...), fitted instead of runs on the twin (needs --config)"
        ),
    )
    p.add_argument(
        "--config", metavar="TOML", help="LAB.toml naming the records' columns and units (with --records)"
    )
    flag(p, "--quiet", "print only the file written")
    return p


def command(args: argparse.Namespace) -> int:
    from twin.calibration.identify import HEADER, identify, lab_records, report_lines
    from twin.errormodel.coefficients import load_priors
    from twin.outputs.run_folder import check_output_file

    # the file is checked before the experiments run (they take seconds, a sweep's minutes);
    # the default is never the committed coefficients, which every scenario reads: a trial
    # identify must not change them (the maintainer names that file with --out to renew it)
    out = check_output_file(Path(args.out) if args.out is not None else Path(DEFAULT_OUT), "--out", ".toml")
    priors = load_priors(Path(args.priors)) if args.priors else None
    records = None
    if args.tester is not None and args.records is not None:
        raise ConfigError("a lab's records are its tester's own: leave out --tester", source="--tester")
    if args.records is not None or args.config is not None:
        if args.records is None or args.config is None:
            missing = "--config" if args.config is None else "--records"
            raise ConfigError(f"a lab's records need {missing} too", source=missing)
        if args.set:
            raise ConfigError(
                "--set changes the twin's experiments; a lab's records are its own", source="--set"
            )
        records = lab_records(Path(args.records), Path(args.config))
    overrides = list(args.set or [])
    if args.tester is not None:
        from twin.config.load import load_scenario, scenarios_dir
        from twin.uncertainty.updated import load_updated

        tester = load_updated(Path(args.tester), coefficients=False)  # what this writes
        # its values checked against the whole tester the calibration experiments are parts of:
        # a problem is said of the tester file, not of the experiment it would first fail in
        tester.check_against(load_scenario(scenarios_dir() / "base" / "tester-system.toml"))
        overrides = [*tester.overrides(coefficients=False), *overrides]
    coefficients = identify(overrides, priors=priors, records=records)
    out.parent.mkdir(parents=True, exist_ok=True)
    coefficients.write(out, header=HEADER)
    if not args.quiet:
        print("\n".join(report_lines(coefficients)))
    print(f"coefficients written to {out}")
    return 0
