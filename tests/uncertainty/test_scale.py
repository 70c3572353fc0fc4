"""A tester's draws map through SALib's inverse CDFs without importing SALib or scipy
(twin.uncertainty.testers.scale): checked against SALib's scale_samples itself, a uniform's to
the last bit, a normal's and a lognormal's within 1e-14 of it, relative (the standard library's
normal quantile in place of scipy's ndtri)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from SALib.util import scale_samples

from twin.config.load import default_scenario_path, load_scenario, scenarios_dir
from twin.seeds import Key, generator
from twin.uncertainty.spreads import calibrated_rows, merge_rows, problem
from twin.uncertainty.testers import Testers as Draws  # not a test class
from twin.uncertainty.testers import load_prior, normal_quantile, scale

PRIORS = scenarios_dir() / "base" / "priors.toml"


def _unit(n: int, k: int, seed: int) -> np.ndarray:
    """Unit draws with the ends a generator can give (0, the smallest steps above 0 and below 1)
    among uniform ones."""
    unit = np.random.default_rng(seed).random((n, k))
    unit[0, :] = 0.0
    unit[1, :] = 2.0**-53
    unit[2, :] = 1.0 - 2.0**-53
    unit[3, :] = 1e-300
    return unit


def _salib(unit: np.ndarray, rows: list) -> np.ndarray:
    return np.asarray(scale_samples(unit.copy(), problem(rows)))


#: how far (relative) a value may lie from SALib's: the normal quantiles (AS 241 and Cephes'
#: rational approximations, both near full double precision) differ by up to 7 units in the
#: last place over 200,000 draws; a lognormal's exponent (-11 for 1.7e-5) turns a last-place
#: flip of it into 16-28 of the value's, 2e-15 to 4e-15 relative (seen)
RELATIVE = 1e-14


def _close(ours: np.ndarray, salib: np.ndarray) -> None:
    """The same infinities and NaNs, and every finite value within :data:`RELATIVE` of SALib's."""
    finite = np.isfinite(salib)
    assert np.array_equal(np.isnan(ours), np.isnan(salib))
    assert np.array_equal(ours[~finite & ~np.isnan(salib)], salib[~finite & ~np.isnan(salib)])
    assert np.all(np.abs(ours[finite] - salib[finite]) <= RELATIVE * np.abs(salib[finite]))


def test_default_run_draws_as_salib() -> None:
    """Every row the default run draws (the prior file around the replay, with the calibrated
    parameters' lognormal standard errors): SALib's values, within 1e-14 of them (relative;
    a uniform's to the last bit)."""
    scenario = load_scenario(default_scenario_path())
    rows = merge_rows(list(load_prior(PRIORS, scenario).rows), calibrated_rows(scenario))
    assert {r[1] for r in rows} == {"norm", "lognorm", "unif"}  # what the prior file uses
    unit = _unit(500, len(rows), 7)
    ours, salib = scale(unit, rows), _salib(unit, rows)
    _close(ours, salib)
    uniform = [i for i, r in enumerate(rows) if r[1] == "unif"]
    assert uniform and ours[:, uniform].tobytes() == salib[:, uniform].tobytes()
    # a tester's values as the Monte Carlo draws them: its own stream, then SALib's map
    draws = Draws(tuple(rows), 2017)
    streams = np.vstack([generator(2017, Key.TESTER, i).random((1, len(rows))) for i in range(50)])
    expected = _salib(streams, rows)
    drawn = np.array([list(d.values()) for d in draws.draw_many(range(50))])
    _close(drawn, expected)
    assert drawn.tobytes() == scale(streams, rows).tobytes()


@pytest.mark.parametrize(
    "row",
    [
        ("n", "norm", [3.0, 0.25]),
        ("n0", "norm", [0.0, 5e-7]),
        ("l", "lognorm", [np.log(1.7e-5), 0.04]),
        ("u", "unif", [-0.005, 0.005]),
        ("u2", "unif", [1e-3, 7.5]),
    ],
)
def test_each_own_distribution_as_salib(row: tuple) -> None:
    unit = _unit(2000, 1, 3)
    ours, salib = scale(unit, [row]), _salib(unit, [row])
    _close(ours, salib)
    if row[1] == "unif":
        assert ours.tobytes() == salib.tobytes()


def test_normal_quantile_ends() -> None:
    """ndtri's values where a quantile has no finite value: 0 and 1 give the infinities, NaN
    stays NaN; the middle is 0."""
    q = np.array([0.0, 1.0, np.nan, 0.5, -0.5, 1.5])
    assert normal_quantile(q).tolist()[:2] == [-np.inf, np.inf]
    assert np.isnan(normal_quantile(q)[2])
    assert normal_quantile(q).tolist()[3:] == [0.0, -np.inf, np.inf]


def test_other_distributions_go_to_salib() -> None:
    """A row SALib maps with scipy.stats' other distributions: the whole draw is SALib's."""
    rows = [
        ("n", "norm", [0.0, 1.0]),
        ("t", "triang", [0.0, 2.0, 0.3]),
        ("lu", "logunif", [1e-3, 1.0]),
        ("tn", "truncnorm", [-1.0, 2.0, 0.5, 1.0]),
    ]
    unit = _unit(300, len(rows), 5)
    assert scale(unit, rows).tobytes() == _salib(unit, rows).tobytes()


def test_drawing_does_not_import_salib() -> None:
    code = (
        "import sys\nfrom twin.config.load import default_scenario_path, load_scenario, scenarios_dir\n"
        "from twin.uncertainty.testers import Testers, load_prior\n"
        "s = load_scenario(default_scenario_path())\n"
        "t = Testers(load_prior(scenarios_dir() / 'base' / 'priors.toml', s).rows, 1)\n"
        "t.draw_many(range(3))\n"
        "print(*(m in sys.modules for m in ('SALib', 'pandas', 'scipy')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False", "False"]
