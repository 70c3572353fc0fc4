"""twin update (issue 31): the emulator against the twin's own runs, the update on the paper's
record with a few walkers and steps, its determinism and its refusals."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from twin.calibration import update as U
from twin.calibration.emulator import verify
from twin.cli import main
from twin.config.load import scenarios_dir
from twin.seeds import generator
from twin.uncertainty.updated import load_updated

RECORD = scenarios_dir() / "records" / "li2017.toml"


@pytest.fixture(scope="module")
def paper(paper_emulator: dict) -> dict:
    """The paper's record, its scenario, prior, forward runs and emulator (tests/calibration/conftest.py)."""
    return paper_emulator


def test_the_emulator_matches_full_twin_runs_at_prior_draws(paper) -> None:
    prior, emulator = paper["prior"], paper["emulator"]
    u = generator(31, 0).standard_normal((6, len(prior.rows)))
    check = verify(emulator, paper["run"], prior.theta(u))
    # the reading's own quantisation (0.1 um) jitters a drift by ~0.02 um: the floor
    assert check["max_um"] < 0.1, check
    # and the draws move the drift by microns, so the match is not the nominal's
    spread = np.ptp(emulator.drift(prior.theta(u)))
    assert spread > 2e-3, spread


def test_each_length_is_a_product_with_its_own_parts_coefficient_and_rise_factor(paper) -> None:
    terms = {tuple(t["product_of"]) for t in paper["emulator"].describe()}
    pole = (
        "fmu.mechanics.parameters.alpha_long_pole",
        "fmu.mechanics.parameters.l_pole_lower",
        "fmu.mechanics.parameters.rise_factor_long_pole",
    )
    assert pole in terms
    inset = [t for t in terms if "fmu.mechanics.parameters.l_base_inset" in t]
    assert inset == [
        (
            "fmu.mechanics.parameters.alpha_base",
            "fmu.mechanics.parameters.l_base_inset",
            "fmu.mechanics.parameters.rise_factor_base",
        )
    ]


def test_the_update_moves_the_drift_toward_the_record_and_leaves_what_it_does_not_inform(
    paper, tmp_path
) -> None:
    summary = U.run_update(paper["record"], tmp_path / "out", lambda _: None, paper["emulator"])
    drift, measured = summary["drift_mm"], summary["measured_drift_mm"]
    assert drift["prior"]["quantile_of_measured"] < 0.01
    # the updated twin's drift is within 5 um of the measured -21 um, from a prior 29 um away
    assert abs(drift["updated"]["median"] - measured) < 0.005
    assert abs(drift["prior"]["median"] - measured) > 0.02
    assert abs(drift["updated"]["with_discrepancy"]["median"] - measured) < 0.001
    # the spindle's coefficient and rise factor do not move the drift: prior in, prior out
    for name in ("alpha_spindle", "rise_factor_spindle"):
        p = summary["parameters"][f"fmu.mechanics.parameters.{name}"]
        assert abs(p["shift_prior_sigma"]) < 0.3, (name, p)
        assert 0.8 < p["posterior"]["sd"] / p["prior"]["sd"] < 1.2, (name, p)
    # the rises come from the held, calibrated network: reported beside the record's, within
    # the calibration's own misfit (0.22 K on the bearing block)
    rises = summary["rises_K"]
    assert set(rises["twin"]) == set(rises["measured"]) and rises["largest_difference_K"] < 0.3, rises
    written = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert written["prior"] == str(paper["record"].prior)
    assert written["drift_mm"]["updated"]["samples"] == summary["drift_mm"]["updated"]["samples"]
    for name in ("samples.parquet", "corner.png", "predictive.png"):
        assert (tmp_path / "out" / name).stat().st_size > 1000
    assert (tmp_path / "out" / "predictive.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the updated tester file: the posterior means as its values, its draws from the chains
    tester = load_updated(tmp_path / "out" / "tester.toml")
    for name, value in tester.values.items():
        assert value == pytest.approx(summary["parameters"][name]["posterior"]["mean"], rel=1e-12)
    assert tester.draws.shape == (U.TESTER_DRAWS, len(paper["prior"].rows))
    lo, hi = summary["parameters"]["fmu.sensors.parameters.probe_zero_drift"]["posterior"]["interval_90"]
    column = tester.draws[:, tester.names.index("fmu.sensors.parameters.probe_zero_drift")]
    assert 0.8 < np.mean((column >= lo) & (column <= hi)) < 1.0
    assert tester.stamps["diagnostics"]["r_hat_max"] == summary["diagnostics"]["r_hat_max"]


def test_the_same_seed_gives_the_same_samples(paper) -> None:
    record = dataclasses.replace(paper["record"], steps=200, burn=100, thin=1)
    a, _ = U.sample(record, paper["prior"], paper["emulator"], 0.0025)
    b, _ = U.sample(record, paper["prior"], paper["emulator"], 0.0025)
    c, _ = U.sample(
        dataclasses.replace(record, seed=record.seed + 1), paper["prior"], paper["emulator"], 0.0025
    )
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != c.tobytes()


@pytest.mark.parametrize(
    ("edit", "word"),
    [
        (("measured_mm = -0.021", 'measured_mm = "a lot"'), "drift.measured_mm"),
        (('scale = "held inputs"', "scale = 0.003"), "discrepancy.scale"),
        (('groups = ["alphas"', 'groups = ["colours"'), "update.groups"),
        (("burn = 20000", "burn = 130000"), "sampler.burn"),
        (("t_plate = 6.3", 't_plate = "warm"'), "rises.t_plate"),
        (("steps = 120000", "steps = 120000\nwalker = 3"), "sampler.walker"),
        (('file = "li2017-updated.toml"', 'file = "../../elsewhere.toml"'), "tester.file"),
        # the default output folder is runs/update-<name>: a path there would leave runs/
        (('name = "li2017"', 'name = "../../../escaped"'), "record.name"),
        # --write replaces the tester file: never the record itself (bad.toml)
        (('file = "li2017-updated.toml"', 'file = "bad.toml"'), "tester.file"),
    ],
)
def test_a_bad_record_gets_one_line_naming_its_key_and_exit_2(edit, word, tmp_path, capsys) -> None:
    text = RECORD.read_text().replace(*edit)
    text = text.replace('"../', f'"{RECORD.parent.parent}/')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    assert main(["update", str(bad), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("twin: ") and word in lines[0], err
    assert not (tmp_path / "out").exists()


def test_write_without_a_tester_file_is_refused_before_the_update_runs(tmp_path, capsys) -> None:
    text = RECORD.read_text().replace('"../', f'"{RECORD.parent.parent}/')
    start, end = text.index("[tester]"), text.index("[sampler]")
    bad = tmp_path / "bad.toml"
    bad.write_text(text[:start] + text[end:])
    assert main(["update", str(bad), "--write", "--out", str(tmp_path / "out")]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and "tester.file" in lines[0] and "--write" in lines[0], lines
    assert not (tmp_path / "out").exists()  # nothing ran: the paper's update takes minutes


def test_a_missing_prior_file_is_refused_in_one_line(tmp_path, capsys) -> None:
    assert main(["update", "--prior", str(tmp_path / "none.toml"), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--prior" in err[0] and "none.toml" in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_missing_record_or_a_negative_count_is_refused_in_one_line(tmp_path, capsys) -> None:
    assert main(["update", str(tmp_path / "none.toml")]) == 2
    assert main(["update", "--steps", "-1"]) == 2
    assert main(["update", "--walkers", "3"]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and "none.toml" in lines[0], lines
    assert "--steps" in lines[1] and "--walkers" in lines[2] and ">= 8" in lines[2], lines


def test_the_output_folder_is_refused_when_a_link_or_another_command_s(tmp_path, capsys) -> None:
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "link").symlink_to(elsewhere)
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text("{}")
    (run / "summary.json").write_text('{"scenario": "sine-load"}')
    for out, said in ((tmp_path / "link", "symbolic link"), (run, "another command's outputs")):
        assert main(["update", "--out", str(out)]) == 2
        lines = capsys.readouterr().err.strip().splitlines()
        assert len(lines) == 1 and said in lines[0], lines
    assert list(elsewhere.iterdir()) == []  # nothing written through the link
    assert (run / "summary.json").read_text() == '{"scenario": "sine-load"}'
