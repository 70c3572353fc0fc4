"""twin update's calibration records (issue 31): a lab's probe-heating bench record, a CSV named
by its LAB.toml, adds the probe's identified zero and span drift to the likelihood."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from twin.calibration import update as U
from twin.calibration.bench import LINKS, identified_links, lab_bench_records
from twin.calibration.emulator import derive, twin_drift
from twin.calibration.identify import run_experiment
from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.identify import EXPERIMENTS
from twin.errormodel.sources import EXTRA_TEMPERATURES, Columns

RECORD = scenarios_dir() / "records" / "li2017.toml"
ZERO, SPAN = LINKS["probe_zero_drift"], LINKS["probe_span_drift"]
#: the bench's probe: drifts well inside the prior (0.5 um/K, 1e-4/K) but not its centre
TRUE = {ZERO: -3.1e-7, SPAN: 6.0e-5}
TWIN = Columns()
LAB_TOML = (
    "[errormodel]\n"
    + "temperatures = { "
    + ", ".join(f'{p} = "T_{p}"' for p in [*TWIN.temperatures, *EXTRA_TEMPERATURES])
    + " }\n"
    + 'reading = "probe_mm"\n'
    + 'units = { probe_mm = "mm" }\n'
)


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A record file of the paper's drift plus the bench record of a probe of known drifts: the
    twin's probe heated alone, written as a lab's logger would (its names, the probe in mm)."""
    folder = tmp_path_factory.mktemp("bench")
    experiment = next(e for e in EXPERIMENTS if e.name == "probe_heating")
    overrides = [f"{k}={v!r}" for k, v in TRUE.items()]
    table = run_experiment(experiment, overrides).table
    names = {**{c: f"T_{p}" for p, c in {**TWIN.temperatures, **EXTRA_TEMPERATURES}.items()}}
    kept = [n for n in table.names() if n in names]
    with (folder / "probe-heating.csv").open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["time", *(names[n] for n in kept), "probe_mm"])
        for k, t in enumerate(table.time):
            w.writerow(
                [
                    repr(float(t)),
                    *(repr(float(table[n][k])) for n in kept),
                    repr(1e3 * float(table[TWIN.reading][k])),
                ]
            )
    (folder / "LAB.toml").write_text(LAB_TOML)
    text = RECORD.read_text().replace('"../', f'"{RECORD.parent.parent}/')
    text += (
        '\n[[calibration]]\nexperiment = "probe_heating"\nrecord = "probe-heating.csv"\nlab = "LAB.toml"\n'
        'source = "the twin\'s probe heated alone, drifts set (test)"\n'
    )
    (folder / "record.toml").write_text(text)
    return folder


def test_the_bench_record_identifies_the_probe_drifts_within_their_errors(lab: Path) -> None:
    record = U.load_record(lab / "record.toml")
    assert [b.record.name for b in record.calibration] == ["probe-heating.csv"]
    links = identified_links(lab_bench_records(record.calibration))
    assert set(links) == {ZERO, SPAN}
    for key, (value, se) in links.items():
        # the fit's standard error is small against the prior and covers the set value
        assert 0 < se < 0.1 * {ZERO: 5e-7, SPAN: 1e-4}[key], (key, se)
        assert abs(value - TRUE[key]) < 4 * se, (key, value, se)


def test_the_links_pull_the_probe_drifts_to_the_bench_and_nothing_without_them(lab: Path) -> None:
    record = dataclasses.replace(
        U.load_record(lab / "record.toml", sampler={"walkers": 80, "steps": 2000, "burn": 500, "thin": 5}),
        held_samples=2,
    )
    scenario = load_scenario(record.scenario)
    prior, roles = U.sampled_rows(record, scenario)
    nominal = {n: float(scenario.nominal(n)) for n in prior.names}
    emulator = derive(twin_drift(scenario), nominal, prior.scales(), roles)
    links = identified_links(lab_bench_records(record.calibration))
    k = prior.names.index(ZERO)
    sds = {}
    for label, given in (("with", links), ("without", None)):
        chains, _ = U.sample(record, prior, emulator, 2e-3, given)
        theta = prior.theta(chains.reshape(-1, chains.shape[-1])[:, :-1])[:, k]
        sds[label] = float(np.std(theta))
        if given:
            value, se = links[ZERO]
            assert abs(np.mean(theta) - value) < 3 * se + 0.2 * np.std(theta)
    # the bench knows the zero drift to ~1 % of its prior: the posterior narrows by far
    assert sds["with"] < 0.1 * sds["without"], sds


@pytest.mark.parametrize(
    ("table", "words"),
    [
        (
            'experiment = "thermal_soak"\nrecord = "probe-heating.csv"\nlab = "LAB.toml"\nsource = "x"',
            ["calibration[0].experiment", "probe_heating"],
        ),
        (
            'experiment = "probe_heating"\nrecord = "nope.csv"\nlab = "LAB.toml"\nsource = "x"',
            ["calibration[0].record", "nope.csv"],
        ),
        (
            'experiment = "probe_heating"\nrecord = "probe-heating.csv"\nlab = "LAB.toml"\nsource = "x"\nunit = "mm"',
            ["calibration[0].unit"],
        ),
    ],
)
def test_a_bad_calibration_table_gets_one_line_and_exit_2(
    lab: Path, table: str, words: list[str], capsys
) -> None:
    text = (
        (lab / "record.toml").read_text().rsplit("[[calibration]]", 1)[0] + "[[calibration]]\n" + table + "\n"
    )
    bad = lab / "bad.toml"
    bad.write_text(text)
    assert main(["update", str(bad), "--out", str(lab / "never")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(bad) in err, err
    assert all(w in err for w in words), err
    assert not (lab / "never").exists()


def test_a_bench_record_without_the_probe_drift_sampled_is_refused(lab: Path, capsys) -> None:
    text = (lab / "record.toml").read_text()
    groups = 'groups = ["alphas", "lengths", "point-vs-mean", "probe drift"]'
    assert groups in text
    bad = lab / "unsampled.toml"
    bad.write_text(text.replace(groups, 'groups = ["alphas", "lengths", "point-vs-mean"]'))
    assert main(["update", str(bad), "--out", str(lab / "never")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "calibration" in err and "probe drift" in err, err


def test_the_update_with_a_bench_record_plots_both_records(lab: Path) -> None:
    """End to end through the command: the drift and the bench's two terms, each in
    predictive.png beside its prior, and the bench's terms in summary.json."""
    out = lab / "out"
    args = ["update", str(lab / "record.toml"), "--walkers", "72", "--steps", "3000", "--burn", "1000"]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert set(summary["calibration"]["terms"]) == {ZERO, SPAN}
    png = (out / "predictive.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000
