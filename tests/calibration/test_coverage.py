"""Coverage of twin update (issue 31 point 4), end to end on 5 virtual testers: drawn from the
whole prior, recorded in full twin runs (the paper's experiment, the probe's bench), updated,
predicting two unseen scenarios. CI-fast: the predicted scenarios are 2 h copies of day-night
and the MIL endurance's thermal run (the benchmark, benchmarks/coverage.py, runs them whole),
the sampler short and the held draws few; the rates of 5 testers are not judged here, only
that they are what the intervals and truths give."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from twin.calibration import coverage as C
from twin.calibration.bench import LINKS

SHORT = tuple(dataclasses.replace(p, overrides=(*p.overrides, "scenario.duration=2 h")) for p in C.PREDICTED)
SETTINGS = C.Settings(
    testers=5,
    seed=7,
    held=8,
    fit_runs=45,
    check_runs=3,
    sampler={"walkers": 80, "steps": 2000, "burn": 1000, "thin": 10},
    predicted=SHORT,
)


@pytest.fixture(scope="module")
def run() -> dict:
    machinery = C.setup(SETTINGS, lambda _: None)
    summary = C.run_coverage(SETTINGS, lambda _: None, machinery)
    return {"m": machinery, "summary": summary}


def test_every_interval_is_finite_and_ordered(run) -> None:
    rows = run["summary"]["testers"]
    assert len(rows) == 5
    for r in rows:
        assert set(r["predictions"]) == {"day-night", "mil-endurance-thermal"}
        for p in [*r["predictions"].values(), *r["parameters"].values()]:
            lo, hi = p["interval"]
            assert np.isfinite([lo, hi]).all() and lo < hi, p
            assert p["covered"] == (lo <= p["true"] <= hi)


def test_each_tester_is_its_own_full_runs(run) -> None:
    rows = run["summary"]["testers"]
    for name in ("day-night", "mil-endurance-thermal"):
        truths = [r["predictions"][name]["true"] for r in rows]
        assert len(set(truths)) == 5, (name, truths)  # each tester's own run, not a nominal
    measured = np.array([r["measured_mm"] for r in rows])
    true = np.array([r["true_paper_drift_mm"] for r in rows])
    # read as the paper's two readings to 1 um: whole microns, within 1 um of the drift
    assert np.allclose(measured * 1e3, np.round(measured * 1e3), atol=1e-9)
    assert np.all(np.abs(measured - true) < 1e-3)
    assert np.ptp(true) > 2e-3  # the prior's testers drift microns apart


def test_the_rates_are_the_counts_of_the_intervals(run) -> None:
    s = run["summary"]
    rates = s["rates"]
    rows = s["testers"]
    covered = sum(p["covered"] for r in rows for p in r["predictions"].values())
    assert rates["predictive"] == {"covered": covered, "of": 10, "rate": covered / 10}
    n = len(rows[0]["parameters"])
    assert n == len(run["m"].prior.names) > 30 and rates["parameters"]["of"] == 5 * n
    assert sum(g["of"] for g in rates["parameters_by_group"].values()) == 5 * n
    assert sum(g["covered"] for g in rates["parameters_by_group"].values()) == rates["parameters"]["covered"]
    for x in [rates["predictive"], rates["parameters"], *rates["parameters_by_group"].values()]:
        assert 0.0 <= x["rate"] <= 1.0


def test_the_emulators_match_full_runs_and_the_discrepancies_co_vary(run) -> None:
    s = run["summary"]
    for name, check in s["emulators"].items():
        assert check["max_um"] < 0.1, (name, check)
    corr = np.array(s["discrepancy"]["correlation"])
    assert corr.shape == (3, 3) and np.allclose(np.diag(corr), 1.0)
    assert all(x > 0 for x in s["discrepancy"]["sigma_mm"])


def test_a_tester_is_the_same_twice(run) -> None:
    m = run["m"]
    t = C.truth(m, SETTINGS, 3)
    again = C.truth(m, SETTINGS, 3)
    assert t == again
    a, b = C.update_tester(m, SETTINGS, t), C.update_tester(m, SETTINGS, again)
    assert a["predictions"] == b["predictions"] and a["parameters"] == b["parameters"]
    assert a["predictions"] == run["summary"]["testers"][3]["predictions"]
    # its bench knows its probe's drift: the drawn value within 4 standard errors
    for key in LINKS.values():
        value, se = t["links"][key]
        assert abs(value - t["values"][key]) < 4 * se, (key, value, se, t["values"][key])
