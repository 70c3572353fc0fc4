"""A lab's record in its logger's units (issue 31, the lab's front door): LAB.toml names the
time column and each column's unit; a record in mm, degC and minutes gives the numbers of the
same record in SI; a column whose magnitude no sensor of this tester reads in SI (a probe in mm
read as metres) is refused with its column, one line and exit 2, nothing written."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.errormodel.sources import DEFAULT_TEMPERATURES
from twin.signals.csv import read_table

POINTS = list(DEFAULT_TEMPERATURES)
COLUMNS = {p: f"T_{p}" for p in POINTS}


@pytest.fixture(scope="module")
def twin_record(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The virtual lab's record: one hour of the paper's experiment on the twin, its DAQ's
    eight temperatures and probe, in SI under the lab's column names."""
    folder = tmp_path_factory.mktemp("run")
    args = ["run", "li2017-thermal-experiment", "--uncertainty", "0", "--stop-time", "3600"]
    assert main([*args, "--out", str(folder / "run")]) == 0
    table = read_table(folder / "run" / "signals.csv")
    path = folder / "lab_si.csv"
    with path.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["time", *COLUMNS.values(), "probe"])
        names = [f"sensors.t_{p}_meas" for p in POINTS] + ["sensors.probe_meas"]
        cols = [table.time, *(table[n] for n in names)]
        for row in zip(*cols, strict=True):
            w.writerow([repr(float(v)) for v in row])
    return path


def _toml(units: dict[str, str] | None = None, time: str | None = None, extra: str = "") -> str:
    temps = ", ".join(f'{p} = "{c}"' for p, c in COLUMNS.items())
    text = f'[errormodel]\nreading = "probe"\nfactors = ["thermal"]\ntemperatures = {{ {temps} }}\n{extra}'
    if time is not None:
        text += f'time = "{time}"\n'
    if units:
        text += "units = { " + ", ".join(f'"{k}" = "{v}"' for k, v in units.items()) + " }\n"
    return text


def _lab_units(src: Path, dst: Path) -> None:
    """The same record as a lab's logger writes it: temperatures in degC, the probe in mm, the
    time in minutes and last."""
    rows = list(csv.reader(src.open()))
    with dst.open("w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow([*rows[0][1:], "t_min"])
        for r in rows[1:]:
            t, *temps, probe = (float(v) for v in r)
            w.writerow([*(repr(v - 273.15) for v in temps), repr(probe * 1e3), repr(t / 60.0)])


def _compensate(tmp_path: Path, record: Path, toml: str, out: str) -> int:
    config = tmp_path / f"{out}.toml"
    config.write_text(toml)
    return main(["compensate", str(record), "--config", str(config), "--out", str(tmp_path / out)])


def test_a_record_in_mm_degc_and_minutes_equals_the_same_record_in_si(
    twin_record: Path, tmp_path: Path
) -> None:
    lab = tmp_path / "lab_mm.csv"
    _lab_units(twin_record, lab)
    units = {"t_min": "min", "probe": "mm", **{c: "degC" for c in COLUMNS.values()}}
    assert _compensate(tmp_path, twin_record, _toml(), "si") == 0
    assert _compensate(tmp_path, lab, _toml(units, time="t_min"), "mm") == 0
    si = json.loads((tmp_path / "si" / "summary.json").read_text())
    mm = json.loads((tmp_path / "mm" / "summary.json").read_text())
    for key in ("drift_mm", "error_parts_mm", "temperature_rise_C", "wear_mm"):
        for name, value in si[key].items():
            assert mm[key][name] == pytest.approx(value, rel=1e-9, abs=1e-12), (key, name)
    a, b = read_table(tmp_path / "si" / "errormodel.csv"), read_table(tmp_path / "mm" / "errormodel.csv")
    np.testing.assert_allclose(b.time, a.time, rtol=1e-12)
    for name in ("errormodel.e_z", "errormodel.wear_compensated"):
        np.testing.assert_allclose(b[name], a[name], rtol=0, atol=1e-12)  # m: a picometre
    assert si["drift_mm"]["probe"] != 0.0  # the record moves: equal numbers are not two zeros


def test_a_probe_in_mm_without_its_unit_is_refused_naming_the_column(
    twin_record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab = tmp_path / "lab_mm.csv"
    _lab_units(twin_record, lab)
    temps = {c: "degC" for c in COLUMNS.values()}  # the temperatures given, the probe not
    assert _compensate(tmp_path, lab, _toml({"t_min": "min", **temps}, time="t_min"), "out") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "'probe' (errormodel.reading)" in err and "4.8" in err and "units" in err
    assert not (tmp_path / "out" / "errormodel.csv").exists()


def test_temperatures_in_degc_read_as_kelvin_are_refused(
    twin_record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lab = tmp_path / "lab_mm.csv"
    _lab_units(twin_record, lab)
    assert _compensate(tmp_path, lab, _toml({"t_min": "min", "probe": "mm"}, time="t_min"), "out") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "errormodel.temperatures." in err and "K" in err


@pytest.mark.parametrize(
    ("units", "time", "expected"),
    [
        ({"probe": "degC"}, None, "errormodel.units.probe"),  # another dimension
        ({"prbe": "mm"}, None, "errormodel.units.prbe"),  # no column it reads
        ({"probe": "furlongs per fortnight"}, None, "errormodel.units.probe"),  # no unit
        ({"time": "degC"}, None, "errormodel.units.time"),  # a time that is no duration
        ({}, "clock", "no time column 'clock'"),  # a time column the file lacks
    ],
)
def test_units_that_cannot_be_used_are_one_line_naming_the_key(
    twin_record: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    units: dict[str, str],
    time: str | None,
    expected: str,
) -> None:
    assert _compensate(tmp_path, twin_record, _toml(units, time=time), "out") == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err, err


def test_the_summary_says_whose_coefficients_compensated(
    twin_record: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _compensate(tmp_path, twin_record, _toml(), "default") == 0
    default = json.loads((tmp_path / "default" / "summary.json").read_text())
    assert "defaults" in default["coefficients"]
    assert "default coefficients, not your tester's" in capsys.readouterr().err
    own = tmp_path / "identified.toml"
    root = Path(__file__).resolve().parents[1]
    own.write_text((root / "scenarios" / "calibration" / "identified.toml").read_text())
    assert _compensate(tmp_path, twin_record, _toml(extra=f'coefficients = "{own}"\n'), "own") == 0
    named = json.loads((tmp_path / "own" / "summary.json").read_text())
    assert named["coefficients"] == str(own)
    assert "default coefficients" not in capsys.readouterr().err
    # the compensated wear: the reading's change less the predicted error
    wear, drift = named["wear_mm"]["compensated"], named["drift_mm"]
    assert wear == pytest.approx(drift["probe"] - drift["predicted"], abs=1e-15)
