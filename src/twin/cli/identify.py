"""``twin identify``: fit the error model's coefficients to calibration experiments run on the twin."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.cli.common import add_set, flag

NAME = "identify"


def add_parser(sub: Any) -> argparse.ArgumentParser:
    p = sub.add_parser(
        NAME, help="fit the error model's coefficients to calibration experiments run on the twin"
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        help="coefficients file to write (default: scenarios/calibration/identified.toml)",
    )
    add_set(p)
    p.add_argument(
        "--priors", metavar="TOML", help="priors file (default: scenarios/calibration/priors.toml)"
    )
    flag(p, "--quiet", "print only the file written")
    return p


def command(args: argparse.Namespace) -> int:
    from twin.calibration.identify import HEADER, identify, report_lines
    from twin.errormodel.coefficients import default_path, load_priors
    from twin.outputs.run_folder import check_output_file

    # the file is checked before the experiments run (they take seconds, a sweep's minutes)
    out = check_output_file(Path(args.out), "--out", ".toml") if args.out is not None else default_path()
    priors = load_priors(Path(args.priors)) if args.priors else None
    coefficients = identify(args.set or [], priors=priors)
    out.parent.mkdir(parents=True, exist_ok=True)
    coefficients.write(out, header=HEADER)
    if not args.quiet:
        print("\n".join(report_lines(coefficients)))
    print(f"coefficients written to {out}")
    return 0
