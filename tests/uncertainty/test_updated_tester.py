"""The updated tester file (issue 31): what ``twin update`` writes, what ``twin run``,
``twin compensate`` and ``twin identify`` take with ``--tester``; the shipped one, the paper's
tester updated from its record, is current and is what the default ``twin run`` runs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from tests.identified_files import assert_made_now
from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import read_toml_file
from twin.errors import ConfigError
from twin.fmu.build import source_hash
from twin.fmu.sources import model_names
from twin.uncertainty.updated import file_sha256, load_updated

SHIPPED = scenarios_dir() / "records" / "li2017-updated.toml"
PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"
MEASURED_MM = -0.021  # the paper's reading fell 4.805 -> 4.784 mm (the record the tester learnt)


def _small_tester(tmp_path: Path, *, values: str = "", posterior: str = "", tester: str = "") -> Path:
    path = tmp_path / "tester.toml"
    path.write_text(
        '[tester]\nname = "t"\n'
        + tester
        + '\n[values]\n"fmu.mechanics.parameters.alpha_detecting_frame" = 1.2e-5\n'
        + values
        + posterior
    )
    return path


def test_a_tester_file_with_problems_is_refused_all_at_once(tmp_path) -> None:
    path = _small_tester(
        tmp_path,
        values='"fmu.mechanics.parameters.alpha_long_pole" = "hot"\n"alpha" = 1.0\n',
        posterior='[posterior]\nnames = ["fmu.mechanics.parameters.alpha_base"]\ndraws = [[1.0, 2.0]]\n',
        tester='coefficients = "missing.toml"\ncolour = 3\n',
    )
    with pytest.raises(ConfigError) as info:
        load_updated(path)
    said = str(info.value)
    for key in (
        "tester.colour",
        "alpha_long_pole",
        'values."alpha"',
        "tester.coefficients",
        "posterior.names",
        "posterior.draws",
    ):
        assert key in said, (key, said)


def test_twin_run_refuses_a_bad_tester_in_one_line_and_exit_2(tmp_path, capsys) -> None:
    assert main(["run", "--tester", str(tmp_path / "nope.toml"), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tester" in err[0] and "nope.toml" in err[0], err
    # a tester of another twin: a parameter the paper's mechanics does not have
    other = _small_tester(tmp_path, values='"fmu.mechanics.parameters.alpha_gearbox" = 1e-5\n')
    assert main(["run", "--tester", str(other), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "alpha_gearbox" in err[0] and str(other) in err[0], err
    assert not (tmp_path / "r").exists()  # bad input runs nothing and makes no run folder


def test_the_shipped_tester_is_current_and_converged() -> None:
    tester = load_updated(SHIPPED)
    stamps = tester.stamps
    # made from the record, the prior file and the FMUs as they are now (else: twin update --write)
    record = (SHIPPED.parent / stamps["record"]).resolve()
    assert stamps["record_sha256"] == file_sha256(record)
    assert stamps["scenario_sha256"] == file_sha256(PAPER)  # the record's experiment
    prior = scenarios_dir() / "base" / "priors.toml"
    assert stamps["prior_sha256"] == file_sha256(prior)
    assert stamps["fmu_sources"] == {m: source_hash(m) for m in model_names()}
    # issue 31: R-hat <= 1.01 and ESS >= 400 for every parameter; none beyond 3 prior sigma
    d = stamps["diagnostics"]
    assert d["r_hat_max"] <= 1.01 and d["ess_min"] >= 400, d
    assert d["beyond_3_prior_sigma"] == []
    # enough posterior draws for the default run's 200 samples per predictive
    samples = load_scenario(PAPER).uncertainty["samples"]
    assert samples >= 200 and len(tester.draws) >= samples
    # its coefficients were identified on this tester (twin identify --tester): the same values
    assert tester.coefficients is not None
    identified = read_toml_file(tester.coefficients)["identified"]
    assert identified["overrides"] == tester.overrides(coefficients=False)


@pytest.mark.slow
def test_the_shipped_testers_coefficients_are_what_identify_makes_of_it_now(tmp_path) -> None:
    # the coefficients file the shipped tester names is what identify makes of it now
    tester = load_updated(SHIPPED)
    assert tester.coefficients is not None
    out = tmp_path / "identified.toml"
    assert main(["identify", "--tester", str(SHIPPED), "--out", str(out), "--quiet"]) == 0
    assert_made_now(out, tester.coefficients, f"twin identify --tester {SHIPPED} --out {tester.coefficients}")


@pytest.fixture(scope="module")
def default_run(tmp_path_factory) -> dict:
    """The default ``twin run``: the paper's experiment, its updated tester, both predictives."""
    out = tmp_path_factory.mktemp("default") / "run"
    assert main(["run", "--out", str(out), "--quiet"]) == 0
    return {"out": out, "summary": json.loads((out / "summary.json").read_text())}


def test_the_default_run_is_the_updated_tester_within_5_um_of_the_paper(default_run) -> None:
    drift = default_run["summary"]["drift_mm"]
    # acceptance: the updated twin's drift within 0.005 mm of the measured -0.021 mm (calibration:
    # the record it learnt from), and the error model within 0.005 mm of its virtual probe
    assert abs(drift["probe"] - MEASURED_MM) < 0.005, drift["probe"]
    assert abs(drift["predicted"] - drift["probe"]) < 0.005, (drift["predicted"], drift["probe"])
    # the tester's values are in run.json's overrides: a resumed run is the same tester
    run_json = json.loads((default_run["out"] / "run.json").read_text())
    assert set(load_updated(SHIPPED).overrides(load_scenario(PAPER))) <= set(run_json["overrides"])


def test_the_default_run_reports_the_prior_and_the_updated_prediction_side_by_side(default_run) -> None:
    drift = default_run["summary"]["drift_mm"]
    for which in ("prior", "updated"):
        entry = drift[which]
        lo, hi = entry["interval_90"]
        assert lo < entry["median"] < hi, entry
        assert entry["samples"] >= 200, entry
        assert 0.0 <= entry["quantile_of_measured"] <= 1.0
    # the prior misses the record (the twin before it); the update moved the prediction onto it
    assert drift["prior"]["quantile_of_measured"] < 0.05
    assert abs(drift["updated"]["median"] - MEASURED_MM) < abs(drift["prior"]["median"] - MEASURED_MM)
    assert drift["uncertainty"]["of"] == "updated"
    csv = (default_run["out"] / "uncertainty.csv").read_text().splitlines()
    assert csv[0].startswith("sample,predictive,")
    assert sum(",updated," in row for row in csv) == drift["updated"]["samples"]


def test_compensate_takes_the_tester_s_coefficients(default_run, tmp_path, capsys) -> None:
    record = tmp_path / "lab.csv"
    shutil.copy(default_run["out"] / "signals.csv", record)
    assert main(["compensate", str(record), "--tester", str(SHIPPED), "--out", str(tmp_path / "c")]) == 0
    summary = json.loads((tmp_path / "c" / "summary.json").read_text())
    assert Path(summary["coefficients"]) == load_updated(SHIPPED).coefficients
    assert "default coefficients" not in capsys.readouterr().err
    # its own coefficients compensate the updated tester's reading to within 5 um of no wear
    assert abs(summary["wear_mm"]["compensated"]) < 0.005, summary["wear_mm"]
    # a LAB.toml that names coefficients too: two answers to one question, refused
    lab = tmp_path / "LAB.toml"
    lab.write_text('[errormodel]\ncoefficients = "x.toml"\n')
    assert (
        main(
            [
                "compensate",
                str(record),
                "--tester",
                str(SHIPPED),
                "--config",
                str(lab),
                "--out",
                str(tmp_path / "d"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "errormodel.coefficients" in err[0] and "--tester" in err[0], err


def test_compensate_and_identify_refuse_what_a_tester_cannot_give(tmp_path, capsys) -> None:
    bare = _small_tester(tmp_path)
    csv = tmp_path / "lab.csv"
    csv.write_text("time,x\n0,1\n")
    assert main(["compensate", str(csv), "--tester", str(bare), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tester.coefficients" in err[0] and "twin identify --tester" in err[0], err
    assert main(["identify", "--tester", str(bare), "--records", str(tmp_path), "--config", str(csv)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--tester" in err[0], err


@pytest.mark.parametrize(
    ("values", "posterior", "said"),
    [
        # a value the mechanics refuses: said of the tester file, not of the shipped scenario
        (
            '"fmu.mechanics.parameters.alpha_base" = 1e300\n',
            "",
            'values."fmu.mechanics.parameters.alpha_base"',
        ),
        # a posterior draw the mechanics refuses: else every updated sample fails, exit 0
        (
            "",
            '[posterior]\nnames = ["fmu.mechanics.parameters.alpha_detecting_frame"]\n'
            "draws = [[1.2e-5], [1e300]]\n",
            "posterior.draws",
        ),
    ],
)
def test_a_tester_value_or_draw_out_of_range_is_refused_of_the_tester_file(
    values, posterior, said, tmp_path, capsys
) -> None:
    path = _small_tester(tmp_path, values=values, posterior=posterior)
    assert main(["run", "--tester", str(path), "--uncertainty", "2", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {path}: {said}") and "physical range" in err[0], err
    assert not (tmp_path / "r").exists()


def test_a_tester_with_nothing_the_scenario_has_is_refused(tmp_path, capsys) -> None:
    # a tester of instances the scenario lacks (a misspelt instance, one FMU run alone under its
    # own name) would run the nominal twin as if it were the tester
    path = tmp_path / "tester.toml"
    path.write_text('[tester]\nname = "t"\n[values]\n"fmu.mechanic.parameters.alpha_base" = 1.2e-5\n')
    assert main(["run", "--tester", str(path), "--uncertainty", "0", "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{path}: values: none is of an FMU instance" in err[0], err
    assert not (tmp_path / "r").exists()


def test_the_prior_predictive_stays_when_every_updated_sample_failed() -> None:
    from twin.pipeline import montecarlo

    ok = {"status": "ok", "error": "", "room_shape": "ramp"}
    rows = [
        {**ok, "sample": 0, "predictive": "prior", "drift_mm.probe": 0.010, "drift_mm.predicted": 0.010},
        {**ok, "sample": 1, "predictive": "prior", "drift_mm.probe": 0.012, "drift_mm.predicted": 0.012},
        {"sample": 0, "predictive": "updated", "room_shape": "", "status": "failed", "error": "refused"},
    ]
    mc = {"rows": rows, "groups": {}, "inputs": [], "wall_s": 1.0, "workers": 1, "tester": "t.toml"}
    summary = montecarlo.add_to_summary({"drift_mm": {"probe": -0.018}}, mc)
    drift = summary["drift_mm"]
    assert drift["prior"]["samples"] == 2 and "updated" not in drift
    assert drift["uncertainty"] == {"samples": 0, "failed": 1}  # one failed, not all three rows
    said = montecarlo.line(summary)
    assert said is not None and "no sample of the run's own twin ran (1 failed" in said, said
    assert "prior predictive" in said, said


def test_fewer_posterior_draws_than_samples_are_counted_per_predictive() -> None:
    from twin.pipeline import montecarlo

    ok = {"status": "ok", "error": "", "room_shape": "ramp"}
    rows = [
        {**ok, "sample": i, "predictive": which, "drift_mm.probe": x, "drift_mm.predicted": x}
        for i, which, x in ((0, "prior", 0.010), (1, "prior", 0.012), (0, "updated", -0.02))
    ]
    mc = {"rows": rows, "groups": {}, "inputs": [], "wall_s": 1.0, "workers": 1, "tester": "t.toml"}
    said = montecarlo.line(montecarlo.add_to_summary({"drift_mm": {"probe": -0.018}}, mc))
    # the tester had one draw for two samples: not "1 samples per predictive"
    assert said is not None and "(2 prior and 1 updated samples," in said, said


def test_identify_says_a_bad_tester_value_of_the_tester_file(tmp_path, capsys) -> None:
    # not of the first calibration experiment it would fail in
    path = _small_tester(tmp_path, values='"fmu.mechanics.parameters.alpha_gearbox" = 1e-5\n')
    assert main(["identify", "--tester", str(path), "--out", str(tmp_path / "c.toml"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {path}: ") and "alpha_gearbox" in err[0], err
    assert not (tmp_path / "c.toml").exists()


def test_posterior_draws_must_be_numbers_not_strings_or_booleans(tmp_path) -> None:
    key = "fmu.mechanics.parameters.alpha_detecting_frame"
    path = _small_tester(
        tmp_path, posterior=f'[posterior]\nnames = ["{key}"]\ndraws = [["1.2e-5"], [true]]\n'
    )
    with pytest.raises(ConfigError) as info:
        load_updated(path)  # numpy alone would read them as 1.2e-5 and 1.0
    assert "posterior.draws" in str(info.value)


def test_a_record_or_scenario_given_as_the_tester_gets_one_line(tmp_path, capsys) -> None:
    for wrong in (scenarios_dir() / "records" / "li2017.toml", PAPER):
        assert main(["run", "--tester", str(wrong), "--out", str(tmp_path / "r")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "not an updated tester file" in err[0] and str(wrong) in err[0], err
    assert main(["update", str(SHIPPED), "--out", str(tmp_path / "u")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a record file" in err[0], err
    assert not (tmp_path / "r").exists() and not (tmp_path / "u").exists()
