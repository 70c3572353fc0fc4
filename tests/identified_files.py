"""A committed coefficients file checked against what ``twin identify`` makes of it now.

The stamps (the FMUs' sources, the experiments' scenario hashes, the overrides) must be the
same to the character: a changed FMU or calibration experiment that was not regenerated fails.
Each coefficient must lie within a thousandth of its standard error of the committed one.
That is above what the solver's stopping tolerance leaves: two exact ways of solving the same
fit (b3423d4) gave values up to 6e-5 of a standard error apart. It leaves room for the last bits
in which another CPU's BLAS kernels may differ, and is far below anything that changes what
the error model predicts. The fits must have the same parameters, experiments, samples and rank;
their float diagnostics follow from the same fit and are not compared (a rank-deficient fit's
condition number divides by singular values that are rounding noise).
"""

from __future__ import annotations

import math
from pathlib import Path

from twin.errormodel.coefficients import read_toml_file

#: how far (in standard errors) a coefficient may lie from the committed one
SE_TOLERANCE = 1e-3
#: what a fit must keep exactly
FIT_KEYS = ("parameters", "experiments", "samples", "rank", "informative_directions")


def assert_made_now(made: Path, committed: Path, how: str) -> None:
    """Assert that ``made`` (identify's file now) is ``committed``, as above; ``how``, the
    command that regenerates it, is named in the failure."""
    new, old = read_toml_file(made), read_toml_file(committed)
    stale = f"{committed} is stale: {how}"
    assert new["identified"] == old["identified"], stale
    assert list(new["coefficients"]) == list(old["coefficients"]), stale
    for name, was in old["coefficients"].items():
        now = new["coefficients"][name]
        numbers = {"value": 0.0, "std_error": 0.0}
        assert now | numbers == was | numbers, (name, stale)  # unit, experiment, prior, meaning
        se = was["std_error"]
        assert math.isclose(now["value"], was["value"], rel_tol=0.0, abs_tol=SE_TOLERANCE * se), (
            name,
            now["value"],
            was["value"],
            stale,
        )
        assert math.isclose(now["std_error"], se, rel_tol=SE_TOLERANCE), (name, now["std_error"], se, stale)
    assert list(new["fit"]) == list(old["fit"]), stale
    for name, was in old["fit"].items():
        assert {k: new["fit"][name].get(k) for k in FIT_KEYS} == {k: was.get(k) for k in FIT_KEYS}, (
            name,
            stale,
        )
