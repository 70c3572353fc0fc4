"""The held-out validation, small: 5 testers x 1 short held-out scenario on Dask.

What it checks: the table's shape and the summary's figures against the table, that the
result does not depend on the number of workers or of testers, that each tester's
coefficients are what ``twin identify`` finds on that tester's calibration runs (not the
drawn FMU values, not the committed file), and bad input.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from twin.calibration.identify import identify
from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import default_path, load_coefficients
from twin.errormodel.identify import EXPERIMENTS
from twin.errormodel.sources import CREEP_COEFFICIENTS, ThermalCoefficients
from twin.errors import ConfigError
from twin.pipeline import RunControls
from twin.pipeline.cluster import StudyOptions
from twin.seeds import Key, scenario_seed
from twin.uncertainty.testers import Testers as Draws  # not a test class
from twin.uncertainty.testers import instance_of, load_testers
from twin.validation.heldout import load_heldout, run_heldout

TESTERS = 5
SCENARIOS = scenarios_dir()


IDENTIFICATION_GOALS = "probe_drift_r = 0.9\nprobe_drift_bias_um_per_K = 0.1\nnegative_alpha_l = 0\n"


def write_heldout(path: Path, testers: int = TESTERS, extra: str = "", goals: str = "") -> Path:
    path.write_text(
        f"""
[heldout]
spreads = "{SCENARIOS / "base" / "priors.toml"}"
testers = {testers}
seed = 12
calibration = "{SCENARIOS / "calibration"}"
room_drift_K = 1.0
{extra}
[[scenario]]
name = "sine-load-short"
file = "{SCENARIOS / "sine-load.toml"}"
set = ['scenario.duration = "20 min"']

[goals]
median_removed_pct = 90.0
p10_removed_pct = 80.0
thermal_only_max_um = 2.0
{goals}""",
        encoding="utf-8",
    )
    return path


@pytest.fixture(scope="module")
def five(tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, pd.DataFrame]:
    tmp = tmp_path_factory.mktemp("heldout")
    cfg = load_heldout(write_heldout(tmp / "heldout.toml"))
    summary = run_heldout(cfg, tmp / "out", RunControls(), StudyOptions(workers=2))
    return summary, pd.read_parquet(tmp / "out" / "results.parquet")


@pytest.mark.slow  # runs the calibration experiments of 5 testers on Dask (~45 s of CPU)
def test_one_row_per_tester_and_scenario_and_the_summary_reads_the_table(five) -> None:
    summary, table = five
    assert len(table) == TESTERS and list(table["tester"]) == list(range(TESTERS))
    assert (table["status"] == "ok").all(), table["error"].tolist()
    for col in ("rms_before_um", "mbs.removed_pct", "mbs.max_residual_um", "mlr_ar.removed_pct"):
        assert np.isfinite(table[col]).all(), col
    before, after = table["rms_before_um"], table["mbs.rms_after_um"]
    assert np.allclose(table["mbs.removed_pct"], 100 * (1 - after / before))
    mbs = summary["models"]["mbs"]["all"]
    assert mbs["removed_pct_median"] == pytest.approx(np.median(table["mbs.removed_pct"]))
    assert mbs["removed_pct_p10"] == pytest.approx(np.percentile(table["mbs.removed_pct"], 10))
    assert mbs["largest_residual_um"] == pytest.approx(table["mbs.max_residual_um"].max())
    goal = summary["goals"]["median_removed_pct"]["mbs"]
    assert goal["met"] == (goal["value"] >= 90.0)
    assert summary["goals"]["thermal_only_max_um"]["mbs"]["value"] is None  # no thermal-only row here
    # the testers differ: the draws reach the FMUs
    assert table["fmu.sensors.parameters.probe_zero_drift"].nunique() == TESTERS
    assert table["fmu.sensors.parameters.probe_span_drift"].nunique() == TESTERS
    # the probe bench finds each tester's drift: the acceptance (r >= 0.9, |bias| < 0.1 um/K)
    ident = summary["identification"]
    found, drawn = table["identified.probe_zero_drift"], table["fmu.sensors.parameters.probe_zero_drift"]
    assert ident["probe_zero_drift"]["r"] == pytest.approx(np.corrcoef(found, drawn)[0, 1])
    assert ident["probe_zero_drift"]["r"] >= 0.9 and abs(ident["probe_zero_drift"]["bias"]) < 0.1
    assert ident["negative_alpha_l"] == 0


@pytest.mark.slow  # runs the calibration experiments of 5 testers on Dask (~45 s of CPU)
def test_same_table_on_one_worker_and_with_fewer_testers(five, tmp_path: Path) -> None:
    _, table = five
    cfg = load_heldout(write_heldout(tmp_path / "two.toml", testers=2))
    run_heldout(cfg, tmp_path / "out", RunControls(), StudyOptions(workers=1))
    two = pd.read_parquet(tmp_path / "out" / "results.parquet")
    pd.testing.assert_frame_equal(two, table.iloc[:2].reset_index(drop=True))
    with pytest.raises(ConfigError, match="already holds"):  # never overwritten unasked
        run_heldout(cfg, tmp_path / "out", RunControls(), StudyOptions(workers=1))
    summary = run_heldout(
        cfg, tmp_path / "out", RunControls(), StudyOptions(workers=1, resume=True)
    )  # complete: nothing to run
    assert summary["timing"]["identify_s_mean"] is None
    pd.testing.assert_frame_equal(pd.read_parquet(tmp_path / "out" / "results.parquet"), two)


@pytest.mark.slow  # runs the calibration experiments of 5 testers on Dask (~45 s of CPU)
def test_coefficients_are_what_identify_finds_on_that_tester(five, tmp_path: Path) -> None:
    _, table = five
    cfg = load_heldout(write_heldout(tmp_path / "heldout.toml"))
    values = Draws(tuple(load_testers(cfg.spreads)), cfg.seed).draw(0)
    fmus = {f.name for f in load_scenario(SCENARIOS / "calibration" / EXPERIMENTS[0].scenario).fmus}
    # the tester as built as `twin identify --set` takes it
    sets = [f"{k}={json.dumps(v)}" for k, v in values.items() if instance_of(k) in (None, *fmus)]
    seeds = {
        e.name: [f"scenario.seed={scenario_seed(cfg.seed, Key.RUN, 0, 1000 + k)}"]
        for k, e in enumerate(EXPERIMENTS)
    }
    found = identify(sets, per_experiment=seeds).values()
    row = table.iloc[0]
    # the worker fits with BLAS on one thread (Dask's nanny sets it), this process with several:
    # the summation order moves the last digits of the fit, which the per-part expansion
    # coefficients and the drawn lengths leave less well conditioned (about 2e-6 relative)
    for name, value in found.items():
        assert row[f"identified.{name}"] == pytest.approx(value, rel=1e-4, abs=1e-15), name
    # not the drawn FMU value, not the committed nominal file, and different per tester
    assert row["identified.probe_zero_drift"] != row["fmu.sensors.parameters.probe_zero_drift"]
    nominal = load_coefficients(default_path()).values()
    # the creep spectrum's terms may sit at their bound (zero) on several testers alike: its
    # settled sum is what differs
    # and a body's growth may sit at its bound 0 on several testers: where above it, it differs
    bounded = set(ThermalCoefficients.growths())
    single = [n for n in nominal if n not in CREEP_COEFFICIENTS and n not in bounded]
    assert all(table[f"identified.{n}"].nunique() == TESTERS for n in single)
    assert all((table[f"identified.{n}"] != nominal[n]).all() for n in single)
    for n in bounded:
        free = table[f"identified.{n}"][table[f"identified.{n}"] > 1e-12]
        assert free.nunique() == len(free) and (table[f"identified.{n}"] >= 0).all(), n
    creep = table[[f"identified.{n}" for n in CREEP_COEFFICIENTS]].sum(axis=1)
    assert creep.nunique() == TESTERS and (creep != sum(nominal[n] for n in CREEP_COEFFICIENTS)).all()


def test_bad_heldout_file_is_one_line_per_problem(tmp_path: Path) -> None:
    path = write_heldout(tmp_path / "bad.toml", extra="colour = 'red'\n")
    with pytest.raises(ConfigError) as err:
        load_heldout(path)
    assert "heldout.colour" in str(err.value)
    assert main(["heldout", str(path)]) == 2
    assert main(["heldout", str(write_heldout(tmp_path / "ok.toml")), "--testers", "0"]) == 2


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        # a file that is no scenario ran on every tester's worker, each failing, and the
        # summary then ended in a KeyError traceback (a hostile review)
        (
            ("sine-load.toml", "notascenario.toml"),
            "scenario[0].file: notascenario.toml: scenario.step: missing",
        ),
        (
            ("scenario.duration = ", "scenario.durration = "),
            "scenario[0].file: sine-load.toml: scenario.durration",
        ),
        (
            (f'calibration = "{SCENARIOS / "calibration"}"', 'calibration = "/nonexistent"'),
            "heldout.calibration",
        ),
    ],
)
def test_a_scenario_or_calibration_that_cannot_load_is_refused_before_any_tester_runs(
    change: tuple[str, str], expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "notascenario.toml").write_text('[scenario]\nname = "x"\n')
    path = write_heldout(tmp_path / "h.toml")
    text = path.read_text()
    old, new = change
    if old == "sine-load.toml":  # relative to the held-out file
        text = text.replace(f'"{SCENARIOS / "sine-load.toml"}"', '"notascenario.toml"')
    else:
        assert old in text
        text = text.replace(old, new)
    path.write_text(text)
    assert main(["heldout", str(path), "--out", str(tmp_path / "out"), "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {path}: ") and expected in err[0], err
    assert not (tmp_path / "out").exists()


def test_the_identification_figures_read_one_row_per_tester(tmp_path: Path) -> None:
    """Three testers, two rows each (two scenarios): r and bias of the probe's zero drift by
    hand, the negative and the bound-held alpha*L counted per tester, not per row."""
    from twin.validation.heldout import summarise

    cfg = load_heldout(write_heldout(tmp_path / "h.toml", extra="", goals=IDENTIFICATION_GOALS))
    drawn = [0.1e-6, -0.2e-6, 0.4e-6]
    found = [0.15e-6, -0.15e-6, 0.45e-6]  # drawn + 0.05 um/K each: r 1, bias +0.05 um/K
    rows = []
    for i in range(3):
        for scenario in ("sine-load-short", "other"):
            rows.append({
                "tester": i, "scenario": scenario, "thermal_only": False, "status": "ok",
                "fmu.sensors.parameters.probe_zero_drift": drawn[i], "identified.probe_zero_drift": found[i],
                "fmu.sensors.parameters.probe_span_drift": 1e-4 * i, "identified.probe_span_drift": 1e-4 * i,
                "identified.alpha_l_t_plate": [-1e-8, 0.0, 4e-7][i], "identified.alpha_l_spindle": 0.0,
            })  # fmt: skip
    summary = summarise(cfg, pd.DataFrame(rows))
    ident = summary["identification"]
    assert ident["testers"] == 3
    assert ident["probe_zero_drift"]["r"] == pytest.approx(1.0)
    assert ident["probe_zero_drift"]["bias"] == pytest.approx(0.05, rel=1e-9)  # um/K
    assert ident["probe_span_drift"]["bias"] == 0.0
    assert ident["negative_alpha_l"] == 1  # tester 0's T-plate, counted once for its two rows
    assert ident["alpha_l_at_bound"] == {"alpha_l_t_plate": 1, "alpha_l_spindle": 3}
    goals = summary["goals"]
    assert goals["probe_drift_r"]["identified"] == {"value": pytest.approx(1.0), "met": True}
    assert goals["probe_drift_bias_um_per_K"]["identified"]["met"] is True  # 0.05 < 0.1
    assert goals["negative_alpha_l"]["identified"] == {"value": 1, "met": False}


def test_the_summary_of_testers_that_all_failed_says_there_is_no_row(tmp_path: Path) -> None:
    from twin.validation.heldout import MODELS, summarise

    cfg = load_heldout(write_heldout(tmp_path / "h.toml"))
    table = pd.DataFrame(
        {"tester": [0], "scenario": ["sine-load-short"], "thermal_only": [False], "status": ["failed"]}
    )
    summary = summarise(cfg, table)
    assert all(summary["models"][m]["all"] == {"rows": 0} for m in MODELS)
    assert summary["testers_failed"] == [0]


def test_jobs_made_from_files_read_once_are_those_made_from_the_files(tmp_path: Path) -> None:
    """The client reads each scenario file once per study and makes every tester's job from
    those scenarios: the same jobs as made each from the files, the scenarios read left as read
    (a tester's values make new ones), and two testers' jobs differ."""
    from twin.errormodel.coefficients import load_priors
    from twin.validation.heldout import load_bases, make_job

    cfg = load_heldout(write_heldout(tmp_path / "heldout.toml", testers=3))
    draws, priors = Draws(tuple(load_testers(cfg.spreads)), cfg.seed), load_priors()
    bases = load_bases(cfg)
    shared = [make_job(cfg, draws, priors, i, bases) for i in range(3)]
    assert shared == [make_job(cfg, draws, priors, i) for i in range(3)]
    assert bases == load_bases(cfg)
    assert shared[0] != shared[1] and shared[0].heldout != shared[1].heldout
