"""SSP 1.0: the tester system exported (`twin export-ssp`), read by another co-simulation master
(libcosim, through libcosimpy's `CosimExecution.from_ssp_file`) and by the twin itself
(`twin run tester.ssp`); archives the twin cannot run refused in one line."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.outputs.csv import read_signals_csv
from twin.signals.table import SignalTable

from .archives import libcosim_run

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


def _export(scenario: Path | str, out: Path, *flags: str) -> Path:
    """The scenario's archive; ``--lossy`` for a scenario with a delayed connection (the tester's
    friction heat), which the twin reads back delayed and another master runs undelayed."""
    args = ["export-ssp", str(scenario), "-o", str(out), "--set", f'scenario.duration="{DURATION}"', *flags]
    assert main(args) == 0
    return out


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
    # every connection of the scenario, the friction heat's loop among them, undelayed
    assert len(ssd.system.connections) == len(load_scenario(TESTER).connections) >= 35
    with zipfile.ZipFile(ssp) as zf:
        names = set(zf.namelist())
        assert {f"resources/{n}.ssv" for n in components} <= names
        ssv = zf.read("resources/hydraulic.ssv").decode()
        text = zf.read("SystemStructure.ssd").decode()
    assert 'name="load_mean"' in ssv and 'value="200000.0"' in ssv
    assert 'name="station_on"' in ssv  # a constant input travels as a start value
    # every unit a connector names is defined, as the FMU's UnitDefinitions define it
    assert {u.name for u in ssd.units} >= {"N", "K", "W", "rad", "m"}
    newton = next(u for u in ssd.units if u.name == "N")
    assert (int(newton.kg), int(newton.m), int(newton.s)) == (1, 1, -2)
    assert 'twin:Parameter source="' in ssv  # each parameter's source travels with it
    assert "twin:Delay" not in text  # the friction loop travels as it runs: undelayed
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
    theirs = libcosim_run(ssp, names, steps=len(ours) - 1, every=10)  # output every 1 s = 10 steps
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
    ssp = _export(scenario, tmp_path / "tester.ssp", "--lossy")
    names = ["hydraulic.radial_load", "oscillation.angle", "thermal.t_bearing", "thermal.t_base"]
    theirs = libcosim_run(ssp, names, steps=len(ours) - 1, every=10)
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


def test_what_another_master_could_not_run_is_refused_unless_lossy(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    scenario = _delayed_loop(tmp_path)
    out = tmp_path / "tester.ssp"
    capsys.readouterr()
    assert main(["export-ssp", str(scenario), "-o", str(out)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert lines == [
        f"twin: {scenario}: delay: the archive cannot carry the delayed connection oscillation.q_friction_avg -> "
        "thermal.q_friction: SSP has no delay (--lossy writes it undelayed for other masters; the twin reads "
        "it back delayed)"
    ]
    assert not out.exists()
    assert main(["export-ssp", str(scenario), "-o", str(out), "--lossy"]) == 0
    captured = capsys.readouterr()
    assert "left out (--lossy): delay: the delayed connection oscillation.q_friction_avg" in captured.err
    assert "5 components" in captured.out
    with zipfile.ZipFile(out) as zf:
        assert "<twin:Delay initial=" in zf.read("SystemStructure.ssd").decode()
    # the twin reads the annotation back: its run of the archive is its run of the file
    _run(scenario, tmp_path / "toml")
    _run(out, tmp_path / "ssp")
    assert (tmp_path / "ssp" / "signals.csv").read_bytes() == (tmp_path / "toml" / "signals.csv").read_bytes()


def test_a_scheduled_event_is_refused_unless_lossy(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    scenario = tmp_path / "event.toml"
    scenario.write_text(
        f'extends = "{TESTER}"\n[scenario]\nname = "event"\n'
        '[[event]]\nat = "60 s"\naction = "set"\ntarget = "hydraulic.station_on"\nvalue = 0.0\n'
    )
    capsys.readouterr()
    assert main(["export-ssp", str(scenario), "-o", str(tmp_path / "event.ssp")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"twin: {scenario}: event: the archive cannot carry the event at 60.0 s (set hydraulic.station_on): "
        "SSP has no scheduled events (--lossy leaves it out)"
    ]
    assert main(["export-ssp", str(scenario), "-o", str(tmp_path / "event.ssp"), "--lossy"]) == 0


def test_the_paper_replay_carries_its_room_its_settings_and_their_files(tmp_path: Path) -> None:
    """The replay's exponential room travels as a SignalSource; its error model, Monte Carlo and
    reference tables in the twin's annotation, the Monte Carlo's spreads file in the archive."""
    ssp = _export("li2017-thermal-experiment", tmp_path / "paper.ssp")
    with zipfile.ZipFile(ssp) as zf:
        names = set(zf.namelist())
        text = zf.read("SystemStructure.ssd").decode()
        room = zf.read("resources/thermal_t_room_profile.ssv").decode()
    assert {"resources/SignalSource.fmu", "resources/twin/priors.toml"} <= names
    assert '<twin:Profile source="paper: room +8.9 K over 480 min' in text
    assert 'name="profile">\n      <ssv:Integer value="2"' in room  # exponential
    assert '"reference": {"experiment": "li2017"}' in text
    assert '"spreads": "resources/twin/priors.toml"' in text


def test_an_external_fmu_travels_in_the_archive(tmp_path: Path, lowpass_fmu: Path) -> None:
    import shutil

    shutil.copy(lowpass_fmu, tmp_path / "LowPass.fmu")
    scenario = tmp_path / "filter.toml"
    scenario.write_text(
        f'extends = "{TESTER}"\n[scenario]\nname = "filter"\n'
        '[fmu.filter]\nmodel = "LowPass.fmu"\nperiod = "0.1 s"\n'
        '[connections]\n"sensors.probe_meas" = "filter.u"\n'
    )
    ssp = _export(scenario, tmp_path / "filter.ssp", "--lossy")
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


def _edited_ssd(data: bytes, case: str) -> bytes:
    """The exported SystemStructure.ssd, broken as ``case`` says."""
    if case == "doctype":
        return data.replace(b"?>", b'?>\n<!DOCTYPE x [<!ENTITY e SYSTEM "/etc/passwd">]>', 1)
    if case == "doctype-utf-16":  # no "<!DOCTYPE" bytes to find: the parsed document says
        text = data.decode().replace("UTF-8", "UTF-16").replace("?>", '?>\n<!DOCTYPE x [<!ENTITY e "x">]>', 1)
        return text.encode("utf-16")
    if case in SSD_EDITS:
        attribute, value = SSD_EDITS[case]
        data, n = re.subn(rf'\b{attribute}="[^"]*"'.encode(), f'{attribute}="{value}"'.encode(), data)
        assert n == 1, case
    if case == "not-ssp":
        data = data.replace(b"<ssd:Elements>", b"<ssd:Elementz>").replace(
            b"</ssd:Elements>", b"</ssd:Elementz>"
        )
    return data


def _bad_archive(tmp_path: Path, case: str) -> Path:
    good = _export(TESTER, tmp_path / "good.ssp", "--lossy")
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
                data = _edited_ssd(data, case)
            zout.writestr(info, data)
        if case == "escaping-member":
            zout.writestr("../escaped.txt", b"x")
        if case == "a-file-and-a-folder":  # zz is a file, and zz/inner would need it as a folder
            zout.writestr("zz", b"x")
            zout.writestr("zz/inner", b"y")
    return path


@pytest.mark.parametrize(
    ("case", "word"),
    [
        ("not-a-zip", "not an SSP archive"),
        ("no-ssd", "no SystemStructure.ssd"),
        ("doctype", "document type"),
        ("doctype-utf-16", "document type"),
        ("a-file-and-a-folder", "member 'zz/inner' lies in 'zz', which is a file of the archive"),
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


def test_a_fifo_named_ssp_is_refused_at_once(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """A FIFO would block the reader (nobody writes to it): refused before it is opened."""
    import os

    fifo = tmp_path / "blocking.ssp"
    os.mkfifo(fifo)
    capsys.readouterr()
    assert main(["validate", str(fifo)]) == 2
    assert (
        capsys.readouterr().err.strip()
        == f"twin: {fifo}: is not a regular file (an SSP archive is a zip file)"
    )


@pytest.mark.parametrize("out", ["tester.zip", "no-such-folder/tester.ssp"])
def test_export_refuses_a_bad_output_name(out: str, tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main(["export-ssp", str(TESTER), "-o", str(tmp_path / out)]) == 2
    assert capsys.readouterr().err.startswith("twin: -o: ")


#: the paper replay's archive with one of the twin's own annotations changed: (old, new, words)
PAPER_EDITS = {
    "a-profile-stepping-apart": (
        'value="10.0" />\n          </ssc:Annotation>\n          <ssc:Annotation type="io.github.twin">',
        'value="20.0" />\n          </ssc:Annotation>\n          <ssc:Annotation type="io.github.twin">',
        "twin:Profile: the source steps every 20.0 s, the input it feeds every 10.0 s",
    ),
    "a-setting-of-a-later-version": (
        "<twin:Tables>",
        "<twin:Future/><twin:Tables>",
        "twin:Scenario/twin:Future: an annotation (io.github.twin) this version of the twin does not apply",
    ),
    "tables-that-are-not-json": (
        "<twin:Tables>{",
        "<twin:Tables>{{",
        "twin:Tables: not the twin's tables as JSON",
    ),
}


@pytest.mark.parametrize("case", sorted(PAPER_EDITS))
def test_the_twins_own_annotations_are_checked(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    good = _export("li2017-thermal-experiment", tmp_path / "paper.ssp")
    old, new, words = PAPER_EDITS[case]
    path = tmp_path / f"{case}.ssp"
    with zipfile.ZipFile(good) as zin, zipfile.ZipFile(path, "w") as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "SystemStructure.ssd":
                assert old.encode() in data, case
                data = data.replace(old.encode(), new.encode(), 1)
            zout.writestr(info, data)
    capsys.readouterr()
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], lines
