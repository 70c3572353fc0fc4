"""The paper replay's uncertainty: its inputs, its figures, and the honest outcome."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin.cli import main
from twin.config.load import default_scenario_path, load_scenario
from twin.config.profiles import profile_function
from twin.errors import ConfigError
from twin.paper import DRIFT_M, FEM_PARTS_M
from twin.pipeline.montecarlo import parse_uncertainty, sampler
from twin.uncertainty.rooms import ROOM_SHAPES
from twin.validation.paper_report import fem_components

REPLAY = default_scenario_path()


def test_samples_take_each_room_shape_in_turn_reaching_the_papers_rise() -> None:
    scenario = load_scenario(REPLAY)
    unc = parse_uncertainty(scenario)
    assert unc is not None and unc.samples > 0
    names, make = sampler(unc, scenario)
    assert names["fmu.sensors.parameters.probe_zero_drift"] == "probe drift"
    assert not any(".hydraulic." in n or ".oscillation." in n for n in names)  # the replay has neither
    end = 480 * 60.0
    seen, rooms, seeds = [], [], set()
    for i in range(2 * len(ROOM_SHAPES)):
        scenario, shape, _ = make(i)
        seen.append(shape)
        seeds.add(scenario.seed)
        room = next(p for p in scenario.profiles if p.target == "thermal.t_room")
        f = profile_function(room)
        start, final = f(np.array([0.0, end]))
        assert start == pytest.approx(293.15) and final - start == pytest.approx(8.9)  # the paper's rise
        rooms.append(f(np.linspace(0.0, end, 97)))
    assert seen == [*ROOM_SHAPES, *ROOM_SHAPES]
    assert len(seeds) == len(seen)
    # the same shape in samples i and i + 3 differs by the slow drift, at most 1 K
    for i in range(len(ROOM_SHAPES)):
        gap = np.max(np.abs(rooms[i] - rooms[i + len(ROOM_SHAPES)]))
        assert 0.0 < gap <= 2.0


def test_probe_zero_drift_is_centred_on_zero_not_on_the_committed_value() -> None:
    scenario = load_scenario(REPLAY)
    unc = parse_uncertainty(scenario, samples=64)
    _, make = sampler(unc, scenario)
    drifts = [make(i)[0].fmu("sensors").parameters["probe_zero_drift"].value for i in range(64)]
    assert abs(np.mean(drifts)) < 0.5e-6 * 3 / 8  # 3 standard errors of a mean of 64 draws
    assert 0.35e-6 < np.std(drifts) < 0.65e-6  # sigma 0.5 um/K (scenarios/base/priors.toml)
    assert min(drifts) < 0 < max(drifts)


def test_bad_uncertainty_table_is_refused_before_the_run(tmp_path: Path) -> None:
    bad = tmp_path / "replay.toml"
    bad.write_text(f'extends = "{REPLAY}"\n[uncertainty]\nroom_drift_K = -1.0\n', encoding="utf-8")
    with pytest.raises(ConfigError, match="room_drift_K"):
        parse_uncertainty(load_scenario(bad))
    assert main(["run", str(bad), "--out", str(tmp_path / "run")]) == 2
    assert not (tmp_path / "run").exists()


def test_fem_components_are_the_papers_beside_the_twins_thermal_parts() -> None:
    twin = {"bearing_block": -0.019, "t_plate": 0.0031, "detecting_frame": -0.0411, "long_pole": 0.0398}
    fem = fem_components({"thermal_parts_mm": twin, "drift_mm": {"probe": -0.02}}, ())
    assert set(fem) == set(FEM_PARTS_M)
    for part, m in FEM_PARTS_M.items():
        assert fem[part]["paper"] == pytest.approx(m * 1e3)
        assert fem[part]["twin"] == twin[part]
        assert fem[part]["derived"] == (part == "bearing_block")
        assert "twin_interval_90" not in fem[part]  # no Monte Carlo, no interval


@pytest.mark.slow
def test_twin_run_of_the_replay_gives_the_interval_and_the_honest_outcome(tmp_path: Path) -> None:
    """The paper's experiment on the twin before any record (``--tester none``; the README's
    main command runs the updated tester: tests/uncertainty/test_updated_tester.py), with the
    scenario's own [uncertainty] (200 samples): the prior predictive of scenarios/base/priors.toml.

    The outcome asserted is the one computed on the FMUs of this commit (issue 12 point 7), not
    a target: the paper's -0.021 mm lies OUTSIDE the 90 % interval [-0.0054, +0.0211] mm (none
    of 200 samples below it). When the physics or the prior changes, rerun and state the new
    outcome here; the quantile is reported, never a goal.
    """
    assert main(["run", "--tester", "none", "--out", str(tmp_path / "run"), "--quiet"]) == 0
    s = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    d = s["drift_mm"]
    lo, hi = d["interval_90"]
    assert d["samples"] == 200 and lo < d["uncertainty"]["median"] < hi and d["sigma"] > 0
    inside = lo <= DRIFT_M * 1e3 <= hi
    assert d["uncertainty"]["paper_measured_inside_interval_90"] == inside
    assert inside is OUTCOME_INSIDE
    prior = d["prior"]
    assert prior["samples"] == 200 and prior["interval_90"] == [lo, hi] and lo < prior["median"] < hi
    assert (
        prior["quantile_of_measured"] == d["uncertainty"]["paper_measured_quantile"] == pytest.approx(0 / 200)
    )
    shares = prior["variance_shares"]["groups"]
    assert {"alphas", "lengths", "point-vs-mean", "probe drift", "thermal network", "room curve"} <= set(
        shares
    )
    assert sum(shares.values()) == pytest.approx(1.0)  # the rest closes it: noise, interactions
    assert 0.8 < prior["variance_shares"]["first_order_sum"] < 1.2  # what the groups explain
    table = pd.read_csv(tmp_path / "run" / "uncertainty.csv")
    assert len(table) == 200 and "fmu.mechanics.parameters.l_base_inset" in table  # every drawn input
    assert set(s["paper"]["fem_components_mm"]) == set(FEM_PARTS_M)


#: the computed outcome on this commit's FMUs (see the slow test's text)
OUTCOME_INSIDE = False


def test_calibrated_standard_errors_replace_the_handbook_spreads() -> None:
    """Where the thermal network's parameter file gives a standard error (the calibration's),
    the Monte Carlo draws from it (lognormal, its relative sigma) instead of the facts-6 spread."""
    from twin.uncertainty.spreads import calibrated_rows, merge_rows
    from twin.uncertainty.testers import load_testers

    scenario = load_scenario(REPLAY)
    calibrated = {r[0]: r for r in calibrated_rows(scenario)}
    base_room = scenario.fmu("thermal").parameters["g_base_room"]
    assert base_room.std_error is not None  # li2017-thermal-network.toml gives one
    assert calibrated["fmu.thermal.parameters.g_base_room"] == (
        "fmu.thermal.parameters.g_base_room",
        "lognorm",
        [pytest.approx(np.log(base_room.value)), pytest.approx(base_room.std_error / base_room.value)],
    )
    unc = parse_uncertainty(scenario)
    rows = {r[0]: r for r in merge_rows(load_testers(unc.spreads, scenario), list(calibrated.values()))}
    assert rows["fmu.thermal.parameters.g_base_room"] == calibrated["fmu.thermal.parameters.g_base_room"]
    assert rows["fmu.thermal.parameters.g_pole_lower_room"][1:] == (
        "lognorm",
        [pytest.approx(np.log(scenario.fmu("thermal").parameters["g_pole_lower_room"].value)), 0.3],
    )  # not calibrated: the prior file's kept
