"""SSP 1.0: the tester system exported (`twin export-ssp`), read by another co-simulation master
(libcosim, through libcosimpy's `CosimExecution.from_ssp_file`) and by the twin itself
(`twin run tester.ssp`); archives from others refused in one line when the twin cannot run them."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import scenarios_dir
from twin.outputs.csv import read_signals_csv
from twin.signals.table import SignalTable

TESTER = scenarios_dir() / "base" / "tester-system.toml"
DURATION = "2 min"


def _delayed_loop(folder: Path) -> Path:
    """The tester system with its friction loop closed through an explicit one-exchange delay
    (friction heat -> thermal network): a choice libcosim has no means to express."""
    path = folder / "delayed-loop.toml"
    path.write_text(
        f'extends = "{TESTER}"\n'
        f'[scenario]\nname = "tester-delayed-friction-loop"\nduration = "{DURATION}"\n'
        '[connections]\n"oscillation.q_friction_avg" = []\n'
        '[[delay]]\nfrom = "oscillation.q_friction_avg"\nto = "thermal.q_friction"\ninitial = 0.0\n'
    )
    return path


def _export(scenario: Path | str, out: Path, capsys: pytest.CaptureFixture | None = None) -> Path:
    assert (
        main(["export-ssp", str(scenario), "-o", str(out), "--set", f'scenario.duration="{DURATION}"']) == 0
    )
    return out


def _libcosim(ssp: Path, names: list[str], steps: int, every: int) -> dict[str, np.ndarray]:
    """The archive in libcosim: every ``every`` base steps, the last value of each named
    variable ("instance.variable")."""
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_ssp_file(str(ssp))
    index = {i.name.decode(): i.index for i in execution.slave_infos()}
    refs = {n: {v.name.decode(): v.reference for v in execution.slave_variables(i)} for n, i in index.items()}
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    rows = []
    for _ in range(steps):
        assert execution.step(every)
        row = []
        for name in names:
            inst, var = name.split(".", 1)
            row.append(observer.last_real_values(index[inst], [refs[inst][var]])[0])
        rows.append(row)
    values = np.array(rows)
    return {name: values[:, j] for j, name in enumerate(names)}


def _run(scenario: Path | str, out: Path, *sets: str) -> SignalTable:
    args = ["run", str(scenario), "--out", str(out), "--quiet", "--uncertainty", "0"]
    for s in (f'scenario.duration="{DURATION}"', *sets):
        args += ["--set", s]
    assert main(args) == 0
    return read_signals_csv(out / "signals.csv")


def test_the_export_is_valid_ssp_and_holds_the_system(tmp_path: Path) -> None:
    from fmpy.ssp.ssd import read_ssd

    ssp = _export(TESTER, tmp_path / "tester.ssp")
    ssd = read_ssd(str(ssp), validate=True)  # fmpy checks it against the SSP 1.0 schema
    components = {c.name: c for c in ssd.system.elements}
    assert set(components) == {"hydraulic", "oscillation", "thermal", "mechanics", "sensors"}
    assert components["thermal"].source == "resources/ThermalNetwork.fmu"
    assert len(ssd.system.connections) == 35  # the friction heat's loop among them, undelayed
    with zipfile.ZipFile(ssp) as zf:
        names = set(zf.namelist())
        assert {f"resources/{n}.ssv" for n in components} <= names
        ssv = zf.read("resources/hydraulic.ssv").decode()
    assert 'name="load_mean"' in ssv and 'value="200000.0"' in ssv
    assert 'name="station_on"' in ssv  # a constant input travels as a start value
    # the same scenario gives the same archive, byte for byte
    assert _export(TESTER, tmp_path / "again.ssp").read_bytes() == ssp.read_bytes()


def test_libcosim_runs_the_export_and_agrees_bit_for_bit(tmp_path: Path) -> None:
    """Tolerance 0: the same FMU binaries with the same parameters and seeds, the same base step
    and per-FMU periods (libcosim's step size hints), and both masters exchange Jacobi-style
    (each FMU steps on the values its inputs had at the start of its step, held over it). The
    friction loop runs undelayed in both: neither of its ends has direct feedthrough."""
    ours = _run(TESTER, tmp_path / "ours")
    ssp = _export(TESTER, tmp_path / "tester.ssp")
    names = ours.names()
    theirs = _libcosim(ssp, names, steps=len(ours) - 1, every=10)  # output every 1 s = 10 steps
    assert len(names) > 70
    for name in names:
        np.testing.assert_array_equal(theirs[name], ours[name][1:], err_msg=name)


def test_with_a_delayed_loop_libcosim_differs_only_downstream_of_the_delay(tmp_path: Path) -> None:
    """The friction loop delayed by choice: libcosim has no one-exchange delay, so the friction
    heat reaches the thermal network one 10 s step earlier there. The load and the swing do not
    depend on it and stay bit-identical; the bearing's temperature differs by about the heat of
    one step, the base (far from the bearing in the network) by far less."""
    scenario = _delayed_loop(tmp_path)
    ours = _run(scenario, tmp_path / "ours")
    ssp = _export(scenario, tmp_path / "tester.ssp")
    names = ["hydraulic.radial_load", "oscillation.angle", "thermal.t_bearing", "thermal.t_base"]
    theirs = _libcosim(ssp, names, steps=len(ours) - 1, every=10)
    for name in ("hydraulic.radial_load", "oscillation.angle"):
        np.testing.assert_array_equal(theirs[name], ours[name][1:], err_msg=name)
    gap = {n: np.abs(theirs[n] - ours[n][1:]).max() for n in ("thermal.t_bearing", "thermal.t_base")}
    assert 0 < gap["thermal.t_bearing"] < 3.0
    assert gap["thermal.t_base"] < 1e-3 * gap["thermal.t_bearing"]


def test_the_twin_runs_its_export_with_the_same_bytes(tmp_path: Path) -> None:
    ssp = _export(TESTER, tmp_path / "tester.ssp")
    from_toml = _run(TESTER, tmp_path / "toml")
    from_ssp = _run(ssp, tmp_path / "ssp")
    assert (tmp_path / "ssp" / "signals.csv").read_bytes() == (tmp_path / "toml" / "signals.csv").read_bytes()
    assert from_ssp.names() == from_toml.names()
    # --set reaches a system read from an archive as from a file
    changed = _run(ssp, tmp_path / "set", "fmu.hydraulic.parameters.load_mean=100e3")
    assert changed["hydraulic.radial_load"][-1] == pytest.approx(100e3, rel=1e-3)


def test_what_an_archive_cannot_hold_is_named(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["export-ssp", "li2017-thermal-experiment", "-o", str(tmp_path / "paper.ssp")]) == 0
    captured = capsys.readouterr()
    assert "not in the archive: input thermal.t_room (exponential profile)" in captured.err
    assert "3 components" in captured.out


def test_an_external_fmu_travels_in_the_archive(tmp_path: Path, lowpass_fmu: Path) -> None:
    import shutil

    shutil.copy(lowpass_fmu, tmp_path / "LowPass.fmu")
    scenario = tmp_path / "filter.toml"
    scenario.write_text(
        f'extends = "{TESTER}"\n[scenario]\nname = "filter"\n'
        '[fmu.filter]\nmodel = "LowPass.fmu"\nperiod = "0.1 s"\n'
        '[connections]\n"sensors.probe_meas" = "filter.u"\n'
    )
    ssp = _export(scenario, tmp_path / "filter.ssp")
    with zipfile.ZipFile(ssp) as zf:
        assert "resources/LowPass.fmu" in zf.namelist()
    assert "filter.y" in _run(ssp, tmp_path / "run").names()


#: an exported SystemStructure.ssd with one attribute's value changed: (attribute, new value)
SSD_EDITS = {
    "seed-superscript-two": ("seed", "\u00b2"),  # str.isdigit() takes it, int() does not
    "seed-negative": ("seed", "-7"),
    "seed-a-word": ("seed", "abc"),
    "seed-a-fraction": ("seed", "1.5"),
    "seed-empty": ("seed", ""),
    "start-time-100-s": ("startTime", "100.0"),
    "start-time-inf": ("startTime", "INF"),
}


def _bad_archive(tmp_path: Path, case: str) -> Path:
    good = _export(TESTER, tmp_path / "good.ssp")
    path = tmp_path / f"{case}.ssp"
    if case == "not-a-zip":
        path.write_bytes(b"PK but not really")
        return path
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(path, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "SystemStructure.ssd":
                if case == "no-ssd":
                    continue
                if case == "doctype":
                    data = data.replace(b"?>", b'?>\n<!DOCTYPE x [<!ENTITY e SYSTEM "/etc/passwd">]>', 1)
                if case in SSD_EDITS:
                    attribute, value = SSD_EDITS[case]
                    data, n = re.subn(
                        rf'\b{attribute}="[^"]*"'.encode(), f'{attribute}="{value}"'.encode(), data
                    )
                    assert n == 1, case
                if case == "not-ssp":
                    data = data.replace(b"<ssd:Elements>", b"<ssd:Elementz>").replace(
                        b"</ssd:Elements>", b"</ssd:Elementz>"
                    )
            zout.writestr(info, data)
        if case == "escaping-member":
            zout.writestr("../escaped.txt", b"x")
    return path


@pytest.mark.parametrize(
    ("case", "word"),
    [
        ("not-a-zip", "not an SSP archive"),
        ("no-ssd", "no SystemStructure.ssd"),
        ("doctype", "document type"),
        ("not-ssp", "not valid SSP 1.0"),
        ("escaping-member", "outside the archive"),
        # the twin's annotations are checked as a scenario file's [scenario] table is
        ("seed-superscript-two", "scenario.seed: expected an integer in [0, 2^31), got '\u00b2'"),
        ("seed-negative", "scenario.seed: expected an integer in [0, 2^31), got -7"),
        ("seed-a-word", "scenario.seed: expected an integer in [0, 2^31), got 'abc'"),
        ("seed-a-fraction", "scenario.seed: expected an integer in [0, 2^31), got '1.5'"),
        ("seed-empty", "scenario.seed: expected an integer in [0, 2^31), got ''"),
        ("start-time-100-s", "startTime '100.0': a start time other than 0 is not supported"),
        ("start-time-inf", "startTime 'INF': a start time other than 0 is not supported"),
    ],
)
def test_an_archive_the_twin_cannot_run_is_one_line(
    case: str, word: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = _bad_archive(tmp_path, case)
    capsys.readouterr()
    assert main(["run", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert str(path) in lines[0] and word in lines[0], lines[0]
    assert not (tmp_path / "run").exists() and not (tmp_path.parent / "escaped.txt").exists()


@pytest.mark.parametrize("out", ["tester.zip", "no-such-folder/tester.ssp"])
def test_export_refuses_a_bad_output_name(out: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["export-ssp", str(TESTER), "-o", str(tmp_path / out)]) == 2
    assert capsys.readouterr().err.startswith("twin: -o: ")
