"""The variance shares' first-order indices are SALib's RBD-FAST numbers to the last bit,
computed without importing SALib's module (twin.uncertainty.shares.first_order)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from SALib.analyze import rbd_fast

from twin.uncertainty.shares import HARMONICS, MIN_SAMPLES, first_order, variance_shares


def _salib_s1(x: np.ndarray, y: np.ndarray, harmonics: int = HARMONICS) -> list[float]:
    k = x.shape[1]
    problem = {"num_vars": k, "names": [f"x{i}" for i in range(k)], "bounds": [[0.0, 1.0]] * k}
    return [float(s) for s in rbd_fast.analyze(problem, x, y, M=harmonics, num_resamples=2, seed=0)["S1"]]


@pytest.mark.parametrize("n", [200, 201, 400, 37, 1000])
def test_same_bits_as_salib(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(10):
        x = np.column_stack(
            [rng.normal(size=n), rng.lognormal(size=n), rng.uniform(size=n), rng.integers(0, 3, n)]
        ).astype(float)
        y = 2.0 * x[:, 0] + np.sin(x[:, 1]) + x[:, 3] + 0.3 * rng.normal(size=n)
        for harmonics in (HARMONICS, 10):
            ours = [first_order(x[:, i], y, harmonics) for i in range(x.shape[1])]
            assert ours == _salib_s1(x, y, harmonics)


def test_shares_as_before() -> None:
    """variance_shares' groups sum SALib's own indices (as before: SALib called directly)."""
    rng = np.random.default_rng(5)
    names = ["a", "b", "c", "d"]
    groups = {"a": "g1", "b": "g1", "c": "g2", "d": "g3"}
    x = rng.normal(size=(MIN_SAMPLES, 4))
    y = x @ np.array([3.0, 1.0, 2.0, 0.5]) + rng.normal(size=MIN_SAMPLES)
    rows = [{**dict(zip(names, r, strict=True)), "f": float(v)} for r, v in zip(x, y, strict=True)]
    s1 = _salib_s1(x, y)
    out = variance_shares(rows, "f", groups)
    assert out["by_input"] == dict(zip(names, s1, strict=True))
    assert out["groups"]["g1"] == s1[0] + s1[1]
    assert out["first_order_sum"] == s1[0] + s1[1] + s1[2] + s1[3]


def test_no_salib_import() -> None:
    code = (
        "import sys\nimport numpy as np\nfrom twin.uncertainty.shares import first_order\n"
        "x = np.random.default_rng(0).normal(size=(200, 2))\nfirst_order(x[:, 0], x.sum(axis=1))\n"
        "print(*(m in sys.modules for m in ('SALib', 'pandas', 'scipy')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False"] * 3
