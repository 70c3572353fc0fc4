"""The one prior file (scenarios/base/priors.toml): every entry sourced, each part's expansion
coefficient its own draw, lengths varied, the room's curve and the shares' rest; and the
variance shares of a Monte Carlo's figure (twin.uncertainty.shares)."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin.cli import main
from twin.config.load import default_scenario_path, load_scenario, scenarios_dir
from twin.pipeline.montecarlo import parse_uncertainty, sampler
from twin.uncertainty.shares import MIN_SAMPLES, REST, variance_shares
from twin.uncertainty.testers import Testers as Draws  # not a test class
from twin.uncertainty.testers import load_prior

PRIORS = scenarios_dir() / "base" / "priors.toml"
REPLAY = default_scenario_path()
#: the input groups a prior entry may name (the replay's variance shares sum over them)
GROUPS = {
    "alphas",
    "lengths",
    "point-vs-mean",
    "probe drift",
    "mounting and load",
    "thermal network",
    "room curve",
}
POLE, FRAME = "fmu.mechanics.parameters.alpha_long_pole", "fmu.mechanics.parameters.alpha_detecting_frame"


def raw() -> dict:
    return tomllib.loads(PRIORS.read_text(encoding="utf-8"))


def test_every_entry_names_its_source_and_group() -> None:
    table = raw()
    assert len(table["spread"]) >= 60
    for key, entry in table["spread"].items():
        assert len(entry.get("source", "")) > 20, key  # a reason, not a word
        assert entry.get("group") in GROUPS, key
    for section in ("room", *(f"rest.{k}" for k in table["rest"])):
        node = table
        for part in section.split(".", 1):
            node = node[part]
        assert len(node.get("source", "")) > 20, section


def test_every_part_has_its_own_coefficient_and_a_length_is_drawn() -> None:
    spread = raw()["spread"]
    parts = ["heel_block", "bearing_block", "spindle", "bearing_rings", "t_plate", "detecting_frame",
             "long_pole", "clamp", "base", "probe_body"]  # fmt: skip
    for part in parts:
        assert spread[f"fmu.mechanics.parameters.alpha_{part}"]["group"] == "alphas"
        assert spread[f"fmu.mechanics.parameters.rise_factor_{part}"]["group"] == "point-vs-mean"
    for hidden in ("l_base_inset", "l_probe_body"):  # nobody drew them: wide
        assert spread[f"fmu.mechanics.parameters.{hidden}"] == spread[
            f"fmu.mechanics.parameters.{hidden}"
        ] | {
            "dist": "lognormal",
            "sigma": 0.4,
        }


def test_pole_and_frame_are_drawn_independently() -> None:
    prior = load_prior(PRIORS, load_scenario(REPLAY))
    testers = Draws(prior.rows, 2017)
    draws = [testers.draw(i) for i in range(600)]
    pole, frame = np.array([d[POLE] for d in draws]), np.array([d[FRAME] for d in draws])
    assert abs(np.corrcoef(pole, frame)[0, 1]) < 0.15  # 3.7 standard errors of r = 0 at n = 600
    assert np.std(pole) == pytest.approx(0.04 * 11.7e-6, rel=0.15)
    lengths = np.array([d["fmu.mechanics.parameters.l_base_inset"] for d in draws])
    assert np.median(lengths) == pytest.approx(0.050, rel=0.1) and np.std(np.log(lengths)) == pytest.approx(
        0.4, rel=0.15
    )


def test_the_replays_samples_vary_lengths_and_keep_the_shares_summing_to_one() -> None:
    scenario = load_scenario(REPLAY)
    unc = parse_uncertainty(scenario)
    assert unc is not None and unc.samples >= 200  # the shipped prior predictive
    assert unc.room_shapes == tuple(raw()["room"]["shapes"]) and unc.room_drift_K == raw()["room"]["drift_K"]
    groups, make = sampler(unc, scenario)
    assert groups[POLE] == groups[FRAME] == "alphas" and groups["room.shape"] == "room curve"
    insets, frames = set(), set()
    for i in range(4):
        draw = make(i)
        mech, thermal = draw.scenario.fmu("mechanics").parameters, draw.scenario.fmu("thermal").parameters
        insets.add(mech["l_base_inset"].value)
        frames.add(mech["l_detecting_frame"].value)
        shares = [p.value for name, p in thermal.items() if name.startswith("hyd_share_")]
        assert sum(shares) == pytest.approx(1.0, abs=1e-12)  # the oil keeps the rest
        assert draw.inputs["fmu.mechanics.parameters.l_base_inset"] == mech["l_base_inset"].value
    assert len(insets) == len(frames) == 4


def test_the_probe_drift_prior_is_one_in_both_files() -> None:
    """The tester's probe drifts as the prior says, and the error model's prior on its
    identified zero drift is the same (it was 0.3 um/K in one file and 0.5 in the other)."""
    truth = raw()["spread"]["fmu.sensors.parameters.probe_zero_drift"]
    coefficients = tomllib.loads(
        (scenarios_dir() / "calibration" / "priors.toml").read_text(encoding="utf-8")
    )
    prior = coefficients["priors"]["probe_zero_drift"]
    assert truth["mean"] == prior["value"] == 0.0
    assert truth["sigma"] == prior["sigma"] == 0.5e-6


def test_variance_shares_find_an_additive_models_groups() -> None:
    """y = 2 a + b1 + b2 + noise: a's group explains 4/6.25, b's 2/6.25, the rest the noise.
    RBD-FAST's first-order indices are each known to a few hundredths (and run a little low on
    normal inputs at M = 4): the tolerances say so."""
    rng = np.random.default_rng(3)
    n = 1000
    a, b1, b2, c = rng.normal(size=(4, n))
    y = 2 * a + b1 + b2 + 0.5 * rng.normal(size=n)
    rows = [{"y": y[i], "a": a[i], "b1": b1[i], "b2": b2[i], "c": c[i]} for i in range(n)]
    out = variance_shares(rows, "y", {"a": "A", "b1": "B", "b2": "B", "c": "C"})
    shares = out["groups"]
    assert shares["A"] == pytest.approx(4 / 6.25, abs=0.08)
    assert shares["B"] == pytest.approx(2 / 6.25, abs=0.08)
    assert abs(shares["C"]) < 0.05
    assert sum(shares.values()) == pytest.approx(1.0)
    assert out["first_order_sum"] == pytest.approx(1 - 0.25 / 6.25, abs=0.1)
    few = variance_shares(rows[: MIN_SAMPLES - 1], "y", {"a": "A"})
    assert few["groups"] == {} and "why_none" in few


def test_the_run_reports_its_prior_predictive(tmp_path: Path) -> None:
    """The shape of drift_mm.prior on a short Monte Carlo (the shipped 200 samples run in the
    slow test of tests/validation/test_replay.py): too few samples for the shares, said so."""
    out = tmp_path / "run"
    assert main(["run", "--out", str(out), "--uncertainty", "12", "--quiet"]) == 0
    prior = json.loads((out / "summary.json").read_text(encoding="utf-8"))["drift_mm"]["prior"]
    assert prior["samples"] == 12 and prior["interval_90"][0] <= prior["median"] <= prior["interval_90"][1]
    assert 0.0 <= prior["quantile_of_measured"] <= 1.0
    assert prior["variance_shares"]["groups"] == {} and "why_none" in prior["variance_shares"]
    table = pd.read_csv(out / "uncertainty.csv")
    # the default run is the updated tester's: its 12 updated samples beside the 12 prior ones
    assert (table["predictive"] == "prior").sum() == 12 and (table["predictive"] == "updated").sum() == 12
    assert {POLE, FRAME, "room.shape", "fmu.mechanics.parameters.l_probe_body"} <= set(table)
    assert REST not in table


def test_the_replay_sweep_draws_the_same_prior() -> None:
    from twin.sweep.spec import load_spec

    spec = load_spec(scenarios_dir() / "sweeps" / "paper-replay-montecarlo.toml")
    prior = load_prior(PRIORS, spec.scenario)
    assert {r[0] for r in prior.rows} <= set(spec.names)
    assert POLE in spec.names and FRAME in spec.names and "input.thermal.t_room.rise" in spec.names


@pytest.mark.parametrize(
    ("minutes", "first", "last"), [(2, 0.0, 120.0), (4, 0.0, 240.0), (480, 0.0, 28800.0)]
)
def test_a_sample_room_spans_the_run_however_short(minutes: int, first: float, last: float) -> None:
    """The room of a Monte Carlo sample is a table over the run: a run shorter than the table's
    step kept one point (at its end) and every sample failed, its room driving nothing."""
    from twin.uncertainty.rooms import ROOM_STEP_S, sample_times

    scenario = load_scenario(REPLAY, [f'scenario.duration="{minutes} min"'])
    t = sample_times(scenario)
    assert t[0] == first and t[-1] == last and len(t) >= 2
    assert np.all(np.diff(t) <= ROOM_STEP_S)
