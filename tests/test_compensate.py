"""`twin compensate`: the error model on a CSV of measurements gives what the run gave."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from tests.runs import run_into
from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import default_path
from twin.errormodel.sources import DEFAULT_TEMPERATURES

pytestmark = pytest.mark.slow


def test_compensating_a_runs_csv_reproduces_the_runs_error_model(tmp_path: Path) -> None:
    sc = load_scenario(scenarios_dir() / "constant-load.toml", ['scenario.duration="20 min"'])
    run_into(sc, tmp_path / "run")
    config = tmp_path / "lab.toml"
    # what a lab writes down once: where its tester's identified coefficients are (here the
    # twin's committed ones, which the run used)
    config.write_text(f'[errormodel]\ncoefficients = "{default_path()}"\n')
    assert (
        main(
            [
                "compensate",
                str(tmp_path / "run" / "signals.csv"),
                "--config",
                str(config),
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 0
    )
    assert (tmp_path / "c" / "errormodel.csv").read_bytes() == (
        tmp_path / "run" / "errormodel.csv"
    ).read_bytes()
    a = json.loads((tmp_path / "c" / "summary.json").read_text())
    b = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert a["compensation"] == b["compensation"] and a["drift_mm"]["predicted"] == b["drift_mm"]["predicted"]
    assert (tmp_path / "c" / "error_budget.png").stat().st_size > 0


def test_a_labs_own_column_names(tmp_path: Path) -> None:
    # a lab's CSV: other names for the eight temperatures and the probe, no other sensors
    import numpy as np

    t = np.arange(0.0, 3600.0, 10.0)
    rise = 5.0 * (1 - np.exp(-t / 1800.0))
    names = [f"T{i}" for i in range(8)]
    lines = ["time," + ",".join(names) + ",probe"]
    for k, tk in enumerate(t):
        temps = [293.15 + rise[k]] * 8
        lines.append(",".join(repr(float(v)) for v in [tk, *temps, 4.8e-3 - 2e-6 * rise[k]]))
    csv = tmp_path / "lab.csv"
    csv.write_text("\n".join(lines) + "\n")
    points = list(DEFAULT_TEMPERATURES)  # the paper's eight measuring points
    config = tmp_path / "lab.toml"
    config.write_text(
        '[errormodel]\nreading = "probe"\nfactors = ["thermal"]\ntemperatures = { '
        + ", ".join(f'{p} = "T{i}"' for i, p in enumerate(points))
        + " }\n"
    )
    assert main(["compensate", str(csv), "--config", str(config), "--out", str(tmp_path / "out")]) == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["temperature_rise_C"]["room"] == pytest.approx(rise[-1], abs=0.05)
    assert summary["drift_mm"]["probe"] == pytest.approx(-2e-3 * rise[-1], rel=0.02)


def test_bad_compensate_config_is_bad_input(tmp_path: Path, capsys) -> None:
    config = tmp_path / "bad.toml"
    config.write_text("[errormodel]\ncoefficients = { no_such = 1.0 }\n")
    csv = tmp_path / "x.csv"
    csv.write_text("time,a\n0.0,1.0\n1.0,2.0\n")
    assert main(["compensate", str(csv), "--config", str(config)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "errormodel: coefficients" in err[0] and "no_such" in err[0]


def test_compensate_a_run_folder_reproduces_its_errormodel_csv(tmp_path: Path) -> None:
    # issue 14: no hand-written config; the run's own scenario (run.json) gives the error model
    run_dir = tmp_path / "run"
    assert (
        main(["run", "sine-load", "--out", str(run_dir), "--quiet", "--set", 'scenario.duration="10 min"'])
        == 0
    )
    assert main(["compensate", str(run_dir), "--out", str(tmp_path / "again")]) == 0
    assert (tmp_path / "again" / "errormodel.csv").read_bytes() == (run_dir / "errormodel.csv").read_bytes()
    again = json.loads((tmp_path / "again" / "summary.json").read_text())
    assert again["config"].startswith(str(run_dir / "run.json"))


def test_compensate_does_not_write_over_a_run_folder_without_force(tmp_path: Path, capsys) -> None:
    run_dir = tmp_path / "run"
    assert (
        main(["run", "sine-load", "--out", str(run_dir), "--quiet", "--set", 'scenario.duration="10 min"'])
        == 0
    )
    before = {n: (run_dir / n).read_bytes() for n in ("summary.json", "errormodel.csv", "error_budget.png")}
    capsys.readouterr()
    assert main(["compensate", str(run_dir), "--out", str(run_dir)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"twin: --out: {run_dir} holds another command's outputs (run.json, summary.json): "
        "--force writes over them, or name another --out"
    ]
    assert {n: (run_dir / n).read_bytes() for n in before} == before
    # --force writes the compensation's files there (the run's own error model: the same rows)
    assert main(["compensate", str(run_dir), "--out", str(run_dir), "--force"]) == 0
    assert (run_dir / "errormodel.csv").read_bytes() == before["errormodel.csv"]
    assert "input_rows" in json.loads((run_dir / "summary.json").read_text())


def test_the_template_runs_as_it_is(tmp_path: Path, capsys) -> None:
    assert main(["compensate", "--template", str(tmp_path / "tpl")]) == 0
    toml = (tmp_path / "tpl" / "LAB.toml").read_text()
    assert toml.count("#") > 10  # commented
    assert (
        main(
            ["compensate", str(tmp_path / "tpl" / "lab.csv"), "--config", str(tmp_path / "tpl" / "LAB.toml")]
        )
        == 0
    )
    summary = json.loads((tmp_path / "tpl" / "lab-compensated" / "summary.json").read_text())
    assert summary["temperature_rise_C"]["room"] == pytest.approx(2.0 * (1 - np.exp(-3.0)), abs=0.01)
    # and it does not overwrite a lab's files
    assert main(["compensate", "--template", str(tmp_path / "tpl")]) == 2
    assert "does not overwrite" in capsys.readouterr().err
