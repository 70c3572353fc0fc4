"""`twin identify --records DIR --config LAB.toml` (issue 31, the lab's front door): a lab's own
records of the calibration experiments, in its column names and units, identify the error
model's coefficients exactly as the same experiments run on the twin do."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from twin.calibration.identify import identify, run_experiment
from twin.cli import main
from twin.errormodel.coefficients import load_coefficients
from twin.errormodel.identify import CALIBRATIONS, EXPERIMENTS, LAB_FIELDS
from twin.errormodel.sources import EXTRA_TEMPERATURES, Columns

TWIN = Columns()
# the lab's own names: "T_<point>" for the temperatures, "<field>_ch" for the rest
LAB_NAMES = {
    **{col: f"T_{point}" for point, col in TWIN.temperatures.items()},
    **{col: f"T_{point}" for point, col in EXTRA_TEMPERATURES.items()},  # the probe bench's
    **{TWIN.names(f)[0]: f"{f}_ch" for f in LAB_FIELDS if f != "temperatures"},
}
LAB_TOML = (
    "[errormodel]\n"
    + "temperatures = { "
    + ", ".join(f'{p} = "T_{p}"' for p in [*TWIN.temperatures, *EXTRA_TEMPERATURES])
    + " }\n"
    + "".join(f'{f} = "{f}_ch"\n' for f in LAB_FIELDS if f != "temperatures")
)
NEEDED = [e for e in EXPERIMENTS if any(e.name in c.experiments for c in CALIBRATIONS)]


@pytest.fixture(scope="module")
def lab_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Each calibration experiment run on the nominal twin, written as a lab's logger would:
    its own column names and header order (SI: the numbers must be the same to the bit)."""
    folder = tmp_path_factory.mktemp("lab")
    for e in NEEDED:
        table = run_experiment(e).table
        names = [n for n in table.names() if n in LAB_NAMES]
        with (folder / (Path(e.scenario).stem + ".csv")).open("w", newline="") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["time", *(LAB_NAMES[n] for n in names)])
            for k, t in enumerate(table.time):
                w.writerow([repr(float(t)), *(repr(float(table[n][k])) for n in names)])
    (folder / "LAB.toml").write_text(LAB_TOML)
    return folder


def test_lab_csvs_of_twin_runs_identify_what_the_runs_identify(lab_folder: Path, tmp_path: Path) -> None:
    out = tmp_path / "lab-identified.toml"
    args = ["identify", "--records", str(lab_folder), "--config", str(lab_folder / "LAB.toml")]
    assert main([*args, "--out", str(out), "--quiet"]) == 0
    from_lab = load_coefficients(out)
    from_twin = identify()
    assert from_lab.values() == from_twin.values()  # the same numbers in, the same fit out
    assert all(e["record"] == "lab" for e in from_lab.identified["experiments"].values())


def test_a_missing_record_is_named_and_nothing_written(
    lab_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    partial = tmp_path / "partial"
    partial.mkdir()
    for f in lab_folder.iterdir():
        if f.name != "gauge-blocks.csv":
            (partial / f.name).write_bytes(f.read_bytes())
    out = tmp_path / "x.toml"
    code = main(
        ["identify", "--records", str(partial), "--config", str(partial / "LAB.toml"), "--out", str(out)]
    )
    assert code == 2 and not out.exists()
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "gauge-blocks.csv" in err and "gauge_blocks" in err


def test_records_need_their_lab_toml(lab_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["identify", "--records", str(lab_folder)]) == 2
    assert "--config" in capsys.readouterr().err


def test_the_probes_bench_needs_the_thermometer_on_its_body(
    lab_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # the bench identifies the probe's drifts against its body's temperature: without that
    # column named, the fit would read the frame's, which the bench does not have
    toml = tmp_path / "LAB.toml"
    toml.write_text(LAB_TOML.replace(', probe_body = "T_probe_body"', ""))
    assert "probe_body" not in toml.read_text()
    code = main(
        ["identify", "--records", str(lab_folder), "--config", str(toml), "--out", str(tmp_path / "x.toml")]
    )
    assert code == 2
    err = capsys.readouterr().err.strip()
    assert (
        len(err.splitlines()) == 1 and "errormodel.temperatures.probe_body" in err and "probe_heating" in err
    )
