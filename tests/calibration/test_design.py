"""The next experiment `twin update` names (issue 31, point 3): its outcome's linear model
against full twin runs, the ranking, what each explanation alone would read, and a hand-made
posterior whose answer is known."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from twin.calibration import design as D
from twin.calibration import update as U
from twin.config.load import load_scenario, scenarios_dir
from twin.seeds import generator


@pytest.fixture(scope="module")
def paper(paper_emulator: dict) -> dict:
    """The paper's record updated with a short chain, and the next experiment it names."""
    e = paper_emulator
    record, scenario, prior, roles = e["record"], e["scenario"], e["prior"], e["roles"]
    run, nominal, emulator = e["run"], e["nominal"], e["emulator"]
    held = U.held_spread(record, scenario, nominal, run)
    chains, _ = U.sample(record, prior, emulator, held["sigma_mm"])
    found = D.next_experiment(record, prior, emulator, chains, roles)
    post = D.read_posterior(prior, emulator, chains, roles, record.seed)
    return {
        "record": record,
        "prior": prior,
        "emulator": emulator,
        "roles": roles,
        "post": post,
        "found": found,
    }


def _candidate(name: str) -> D.Candidate:
    return next(c for c in D.CANDIDATES if c.name == name)


def _run(name: str):
    cand = _candidate(name)
    return D.outcome_run(load_scenario(scenarios_dir() / "calibration" / f"{cand.key}.toml"), cand)


@pytest.mark.parametrize("which", ["best", "pole heating"])
def test_the_outcomes_linear_model_matches_full_twin_runs_at_posterior_draws(paper, which) -> None:
    found, post, names = paper["found"], paper["post"], paper["emulator"].names
    entry = found["best"] if which == "best" else next(c for c in found["candidates"] if c["name"] == which)
    run = _run(entry["name"])
    centre = post.theta.mean(axis=0)
    slope = np.array([entry["slope_mm_per_unit"].get(n, 0.0) for n in names])
    rows = generator(31, 3).choice(len(post.theta), size=4, replace=False)
    diffs = []
    for theta in post.theta[rows]:
        linear = entry["at_posterior_mean_mm"] + (theta - centre) @ slope
        diffs.append(linear - run(dict(zip(names, theta, strict=True))))
    moved = np.abs(post.theta[rows] - centre) @ np.abs(slope)
    # the reading's 0.1 um quantisation and the products of a part's coefficient, length and
    # rise factor (a few % of a draw's move) are what the line misses
    assert np.max(np.abs(diffs)) < 1e-4 + 0.05 * np.max(moved), (diffs, moved)
    # and the draws move the outcome by more than that: the check is not of a constant
    assert np.max(moved) > 1e-3, moved


def test_the_named_experiment_ranks_first_with_the_highest_information(paper) -> None:
    found = paper["found"]
    ranking = found["ranking"]
    assert [r["name"] for r in ranking] == [c["name"] for c in found["candidates"]]
    assert len(ranking) == len(D.CANDIDATES)
    info = [r["information_nats"] for r in ranking]
    assert info == sorted(info, reverse=True)
    assert found["name"] == ranking[0]["name"] == found["best"]["name"]
    assert info[0] > info[1] > 0.0


def test_the_probe_heating_bench_reads_the_probe_alone(paper) -> None:
    found = paper["found"]
    # the leading explanations of the paper's record include the probe's drift (the record
    # pins the probe's drift plus the parts' growth, not each)
    labels = [e["label"] for e in found["leading_explanations"]]
    assert "probe drift" in labels and len(labels) >= 2
    bench = next(c for c in found["candidates"] if c["name"] == "probe-heating bench")
    alone = bench["if_alone_mm"]
    # a bench without the tester: every part's growth alone reads the same (the prior's
    # probe), the probe's drift alone reads its drift over the body's 10 K
    others = [v for k, v in alone.items() if k != "probe drift"]
    assert np.ptp(others) < 2e-4, alone
    assert abs(alone["probe drift"] - others[0]) > 10 * bench["noise_mm"], alone
    assert set(bench["slope_mm_per_unit"]) == {
        "fmu.sensors.parameters.probe_zero_drift",
        "fmu.sensors.parameters.probe_span_drift",
    }


def test_the_named_pair_reads_apart_and_the_interval_holds_the_posterior_mean_run(paper) -> None:
    best = paper["found"]["best"]
    a, b = best["separates"]
    alone = best["if_alone_mm"]
    assert a != b and {a, b} <= set(alone)
    # what the name claims: the two explanations alone read outcomes (nearly) as far apart as
    # any other pair, far beyond the outcome's noise, and the record traded them off
    spread = max(alone.values()) - min(alone.values())
    assert abs(alone[a] - alone[b]) >= 0.9 * spread
    assert abs(alone[a] - alone[b]) > 10 * best["noise_mm"]
    leading = {e["label"]: e for e in paper["found"]["leading_explanations"]}
    assert leading[a]["correlation"][b] < 0.0
    lo, hi = best["predicted_mm"]["interval_90"]
    assert lo < best["at_posterior_mean_mm"] < hi
    assert lo < best["predicted_mm"]["median"] < hi
    # the interval is the posterior's, not the noise's: wider than 4 noise sigmas
    assert hi - lo > 4 * best["noise_mm"]
    line = D.report_line(paper["found"])
    assert line.startswith(f"next experiment: {best['name']} (separates {a} from {b}")
    assert f"{lo * 1e3:+.1f}, {hi * 1e3:+.1f}] um" in line


def test_each_explanation_alone_carries_the_shift_and_the_others_sit_at_their_prior(paper) -> None:
    post, emulator, prior = paper["post"], paper["emulator"], paper["prior"]
    prior_mean = post.prior_contrib.mean(axis=0)
    shift = np.sum(post.contrib.mean(axis=0) - prior_mean)
    assert abs(shift) > 5e-3  # the record moved the drift by microns: the hypotheses differ
    for k in range(len(post.leading)):
        theta = D.alone(prior, emulator, post, k)
        c = D.contributions(emulator, theta[None, :], post.leading)[0]
        want = prior_mean.copy()
        want[k] += shift
        np.testing.assert_allclose(c, want, atol=1e-6)


def test_the_explanations_are_the_parts_and_the_probe(paper) -> None:
    found = D.explanations(paper["emulator"], paper["roles"])
    by_label = {e.label: e for e in found}
    terms = paper["emulator"].terms
    names = paper["emulator"].names
    probe = {names[i].split(".")[-1] for t in by_label["probe drift"].terms for i in terms[t][1]}
    assert probe == {"probe_zero_drift", "probe_span_drift"}
    pole = {names[i].split(".")[-1] for t in by_label["long pole growth"].terms for i in terms[t][1]}
    assert {"l_pole_lower", "l_pole_heel", "l_pole_base", "alpha_long_pole"} <= pole
    # every term in exactly one explanation
    assert sorted(t for e in found for t in e.terms) == list(range(len(terms)))


def test_an_experiment_that_reads_what_the_record_read_is_not_chosen() -> None:
    """Two explanations a and b; the record pinned a + b (their posterior trades them off);
    one candidate reads a + b again, the other reads a alone. The second must win, although
    the first responds to both as strongly."""
    rng = np.random.default_rng(7)
    n = 20000
    total = 0.02 + 0.0005 * rng.standard_normal(n)  # a + b: pinned by the record
    a = 0.01 + 0.005 * rng.standard_normal(n)
    contrib = np.column_stack([a, total - a])
    noise = 0.0004 * rng.standard_normal((2, n))
    draws = {"record again": contrib.sum(axis=1) + noise[0], "a alone": contrib[:, 0] + noise[1]}
    order = D.rank(draws, contrib)
    assert [name for name, _ in order] == ["a alone", "record again"]
    info = dict(order)
    # a alone: var 25 against noise 0.16 -> about 0.5 ln(157); the record again: var 0.25 / 0.16
    assert info["a alone"] == pytest.approx(0.5 * np.log(1 + 0.005**2 / 0.0004**2), rel=0.05)
    assert info["record again"] == pytest.approx(0.5 * np.log(1 + 0.0005**2 / 0.0004**2), rel=0.1)
    corr = {"a": {"b": -0.1, "c": -0.6}, "b": {"a": -0.1, "c": -0.2}, "c": {"a": -0.6, "b": -0.2}}
    # the farthest apart wins over a pair the record traded off more ...
    assert D.separated({"a": 0.0, "b": 0.002, "c": -0.01}, corr) == ["b", "c"]
    # ... and among pairs read (nearly) as far apart, the one it traded off most
    assert D.separated({"a": 0.0, "b": 0.0005, "c": -0.01}, corr) == ["a", "c"]
    assert D.separated({"a": -0.01, "b": 0.0, "c": 0.0}, corr) == ["a", "c"]


def test_twin_update_writes_the_next_experiment_and_says_it_last(paper, tmp_path) -> None:
    # the hook in run_update: a chain too short to trust, the next experiment all the same
    record = dataclasses.replace(paper["record"], steps=400, burn=100, thin=1)
    summary = U.run_update(record, tmp_path / "out", lambda _: None, paper["emulator"])
    written = json.loads((tmp_path / "out" / "summary.json").read_text())["next_experiment"]
    assert written["name"] == summary["next_experiment"]["name"]
    assert written["ranking"][0]["name"] == written["best"]["name"]
    assert {c["name"] for c in written["candidates"]} == {c.name for c in D.CANDIDATES}
    lines = U.report_lines(summary)
    assert lines[-1] == D.report_line(summary["next_experiment"])
    assert lines[-1].startswith(f"next experiment: {written['name']} (separates ")
