"""``twin identify``: the command that fits the error model's coefficients on the twin.

``cli.py`` wires it in with ``add_parser(sub)``; the work is done by
:func:`twin.errormodel.identify.identify`, this module only reads the arguments, writes the
coefficients file and prints what the fits found.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from twin.errormodel.coefficients import Coefficients

HEADER = """Coefficients of the error model, identified by `twin identify` from the calibration
experiments in scenarios/calibration/ (DAQ channels only; priors from priors.toml).
Made by a program: rerun `twin identify` to reproduce, do not edit by hand.
Each coefficient: value, one standard error, unit, the experiment it came from and the prior
that entered its fit; each fit: rank and condition numbers, residual and correlation."""


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Add the ``identify`` command to the ``twin`` command's subparsers."""
    p = subparsers.add_parser(
        "identify",
        help="fit the error model's coefficients to calibration experiments run on the twin",
    )
    p.add_argument(
        "--out",
        metavar="FILE",
        help="coefficients file to write (default: scenarios/calibration/identified.toml)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="override a value of every calibration experiment (the tester as built), e.g. "
        "fmu.mechanics.parameters.alpha_steel=1.2e-5",
    )
    p.add_argument(
        "--priors", metavar="TOML", help="priors file (default: scenarios/calibration/priors.toml)"
    )
    p.add_argument("--quiet", action="store_true", help="print only the file written")
    p.set_defaults(func=command)
    return p


def command(args: argparse.Namespace) -> int:
    """Run the experiments, fit, write the file; exit code 0."""
    from twin.errormodel.coefficients import default_path, load_priors
    from twin.errormodel.identify import identify
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


def report_lines(c: Coefficients) -> list[str]:
    """One line per fit and per coefficient, for the terminal."""
    lines = []
    for name, fit in c.fits.items():
        residuals = ", ".join(
            f"{e} {n} samples, residual {r * 1e6:.3f} um"
            for e, n, r in zip(fit.experiments, fit.samples, fit.residual_rms, strict=True)
        )
        lines.append(
            f"{name}: {residuals}; rank {fit.rank} of {len(fit.parameters)}, "
            f"{fit.informative_directions} beyond the priors, condition "
            f"{fit.condition_number_identifiable:.3g} (with priors {fit.condition_number_regularised:.3g})"
        )
    for name, x in c.coefficients.items():
        prior = f" (prior {x.prior.value:.4g} +- {x.prior.sigma:.2g})" if x.prior and x.prior.sigma else ""
        lines.append(f"  {name} = {x.value:.6g} +- {x.std_error:.2g} {x.unit} [{x.experiment}]{prior}")
    return lines
