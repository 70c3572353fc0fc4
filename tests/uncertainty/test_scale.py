"""A tester's draws map through SALib's inverse CDFs to the last bit without importing SALib
(twin.uncertainty.testers.scale): checked against SALib's scale_samples itself."""

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
from twin.uncertainty.testers import load_prior, scale

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


def test_default_run_draws_bit_identical() -> None:
    """Every row the default run draws (the prior file around the replay, with the calibrated
    parameters' lognormal standard errors): the same bits as SALib."""
    scenario = load_scenario(default_scenario_path())
    rows = merge_rows(list(load_prior(PRIORS, scenario).rows), calibrated_rows(scenario))
    assert {r[1] for r in rows} == {"norm", "lognorm", "unif"}  # what the prior file uses
    unit = _unit(500, len(rows), 7)
    ours = scale(unit, rows)
    assert ours.tobytes() == _salib(unit, rows).tobytes()
    # a tester's values as the Monte Carlo draws them: its own stream, then SALib's map
    draws = Draws(tuple(rows), 2017)
    streams = np.vstack([generator(2017, Key.TESTER, i).random((1, len(rows))) for i in range(50)])
    expected = _salib(streams, rows)
    for drawn, want in zip(draws.draw_many(range(50)), expected, strict=True):
        assert list(drawn.values()) == want.tolist()


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
def test_each_own_distribution_bit_identical(row: tuple) -> None:
    unit = _unit(2000, 1, 3)
    assert scale(unit, [row]).tobytes() == _salib(unit, [row]).tobytes()


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
        "print(*(m in sys.modules for m in ('SALib', 'pandas', 'scipy.stats')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["False", "False", "False"]
