"""External FMUs: a scenario names an FMI 2.0 co-simulation .fmu by path, checked by fmpy's
validation before the run; `twin inspect` lists its variables. The FMU is tests/data/LowPass, a
low-pass filter the twin's FMU code did not produce (built by fmpy's own build)."""

from __future__ import annotations

import math
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errors import ConfigError
from twin.fmu import external
from twin.outputs.csv import read_signals_csv

TESTER = scenarios_dir() / "base" / "tester-system.toml"
T_FILTER = 5.0


def _scenario(folder: Path, model: str = "LowPass.fmu", extra: str = "") -> Path:
    path = folder / "with-filter.toml"
    path.write_text(
        f'extends = "{TESTER}"\n'
        '[scenario]\nname = "with-filter"\nduration = "2 min"\noutput_interval = "0.1 s"\n'
        f'[fmu.filter]\nmodel = "{model}"\nperiod = "0.1 s"\nunconnected = "a test system: the inputs nothing feeds keep their start values"\n'
        f'parameters = {{ T = {{ value = {T_FILTER}, source = "test: a 5 s filter of the probe" }} }}\n'
        '[connections]\n"sensors.probe_meas" = "filter.u"\n' + extra
    )
    return path


@pytest.fixture()
def folder(tmp_path: Path, lowpass_fmu: Path) -> Path:
    shutil.copy(lowpass_fmu, tmp_path / "LowPass.fmu")
    return tmp_path


def test_a_scenario_runs_an_external_fmu_and_records_it(folder: Path) -> None:
    out = folder / "run"
    assert main(["run", str(_scenario(folder)), "--out", str(out), "--quiet"]) == 0
    table = read_signals_csv(out / "signals.csv")
    y, u = table["filter.y"], table["sensors.probe_meas"]
    assert table.meta["filter.y"].unit == "m"
    # the master's Jacobi exchange: the filter steps from t_k to t_k+1 on the probe's value at t_k
    decay = math.exp(-0.1 / T_FILTER)
    expected = u[:-1] + (y[:-1] - u[:-1]) * decay
    np.testing.assert_allclose(y[1:], expected, rtol=1e-12, atol=1e-15)
    assert abs(y[-1] - u[-1]) < abs(y[1] - u[1]) or np.ptp(u) == 0  # it follows the probe


def test_inspect_lists_the_external_fmus_variables(lowpass_fmu: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["inspect", str(lowpass_fmu)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("LowPass: FMI 2.0 (co-simulation)")
    rows = {line.split()[0]: line.split() for line in out.splitlines()[2:]}
    assert rows["u"][1:5] == ["input", "continuous", "Real", "m"]
    assert rows["y"][1:5] == ["output", "continuous", "Real", "m"]
    assert rows["T"][1:5] == ["parameter", "fixed", "Real", "s"]


def _rezip(src: Path, dst: Path, edit) -> Path:
    """A copy of the FMU ``src`` with its members changed by ``edit(name, data) -> data | None``."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for info in zin.infolist():
            data = edit(info.filename, zin.read(info))
            if data is not None:
                zout.writestr(info.filename, data)
    return dst


def _md(edit):
    return lambda name, data: edit(data) if name == "modelDescription.xml" else data


BROKEN = {
    "missing": None,
    "not-a-zip": lambda src, dst: dst.write_bytes(b"not a zip file") and dst,
    "broken-xml": lambda src, dst: _rezip(src, dst, _md(lambda d: d[: len(d) // 2])),
    "model-exchange-only": lambda src, dst: _rezip(
        src,
        dst,
        _md(
            lambda d: d.replace(
                b'<CoSimulation modelIdentifier="LowPass"', b'<ModelExchange modelIdentifier="LowPass"'
            ).replace(b"</CoSimulation>", b"</ModelExchange>")
        ),
    ),
    "fmi-3": lambda src, dst: _rezip(
        src, dst, _md(lambda d: d.replace(b'fmiVersion="2.0"', b'fmiVersion="3.0"'))
    ),
    "fails-validation": lambda src, dst: _rezip(
        src, dst, _md(lambda d: d.replace(b'<Unknown index="2" dependencies=""/>', b'<Unknown index="3"/>'))
    ),
    "no-binary-for-this-platform": lambda src, dst: _rezip(
        src, dst, lambda name, data: None if name.startswith("binaries/") else data
    ),
}
WORDS = {
    "missing": "cannot read",
    "not-a-zip": "not an FMU",
    "broken-xml": "modelDescription",
    "model-exchange-only": "model exchange only",
    "fmi-3": "FMI 3.0",
    "fails-validation": "fmpy validate",
    "no-binary-for-this-platform": "no binary for",
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_a_broken_external_fmu_is_one_line_before_anything_runs(
    case: str, tmp_path: Path, lowpass_fmu: Path, capsys: pytest.CaptureFixture
) -> None:
    make = BROKEN[case]
    if make is not None:
        make(lowpass_fmu, tmp_path / "Bad.fmu")
    scenario = _scenario(tmp_path, "Bad.fmu")
    out = tmp_path / "run"
    for args in (["validate", str(scenario)], ["run", str(scenario), "--out", str(out), "--quiet"]):
        assert main(args) == 2
        err = capsys.readouterr().err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and "Traceback" not in err, err
        assert "fmu.filter.model" in lines[0] and "Bad.fmu" in lines[0] and WORDS[case] in lines[0], lines[0]
    assert not out.exists()


def test_an_fmu_replaced_after_its_check_is_not_loaded(folder: Path, lowpass_fmu: Path) -> None:
    scenario = load_scenario(_scenario(folder))
    model = scenario.fmu("filter").model
    assert external.is_external(model) and Path(model) == (folder / "LowPass.fmu").resolve()
    data = bytearray((folder / "LowPass.fmu").read_bytes())
    data[-30] ^= 0xFF  # same size, and the modification time set back: only the hash can tell
    stat = (folder / "LowPass.fmu").stat()
    (folder / "LowPass.fmu").write_bytes(bytes(data))
    import os

    os.utime(folder / "LowPass.fmu", ns=(stat.st_atime_ns, stat.st_mtime_ns))
    with pytest.raises(ConfigError, match="changed since it was checked"):
        external.verified_path(model)
