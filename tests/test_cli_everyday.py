"""The everyday command line (issue 14, first part): shipped scenarios by name, `twin list`,
"did you mean" for a misspelt scenario, key or parameter, one `twin: ` per line, and the
paper's measured drift only beside the paper's replay."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main
from twin.config.load import scenarios_dir


def test_twin_list_shows_every_shipped_scenario_with_its_description(capsys) -> None:
    assert main(["list"]) == 0
    out = capsys.readouterr().out
    for p in scenarios_dir().glob("*.toml"):
        line = next(ln for ln in out.splitlines() if ln.strip().startswith(p.stem + " "))
        assert len(line.split(None, 1)[1]) > 10  # a description, not just the name
    assert "calibration/thermal-soak.toml" in out


def test_a_shipped_scenario_runs_by_its_name(tmp_path: Path, capsys) -> None:
    assert main(["validate", "sine-load"]) == 0
    assert "sine-load.toml: ok" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["validate", "sine-lod"], "did you mean 'sine-load'?"),
        (["run", "constant_load", "--uncertainty", "0"], "did you mean 'constant-load'?"),
        (["validate", "sine-load", "--set", "scenario.duraton=1"], "did you mean 'duration'?"),
        (
            ["validate", "sine-load", "--set", "fmu.mechanics.parameters.sensor_tlt=0.1"],
            "did you mean 'sensor_tilt'?",
        ),
    ],
    ids=["scenario", "scenario-underscore", "key", "parameter"],
)
def test_a_misspelling_gets_did_you_mean(argv: list[str], expected: str, capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err


def test_argument_errors_say_twin_once(capsys) -> None:
    assert main(["run", "--bogus"]) == 2
    assert main(["frob"]) == 2
    for line in capsys.readouterr().err.strip().splitlines():
        assert line.startswith("twin: ") and not line.startswith("twin: twin"), line


@pytest.mark.parametrize(
    ("argv", "named"),
    [
        (["run", ""], "scenario"),
        (["validate", " "], "scenario"),
        (["identify", "--out", ""], "--out"),
        (["identify", "--priors", ""], "--priors"),
        (["export-ssp", "", "--output", "x.ssp"], "scenario"),
        (["calibrate", "--out", ""], "--out"),
        (["geometry", "--scenarios", ""], "--scenarios"),
        (["compensate", "m.csv", "--config", ""], "--config"),
        (["sweep", ""], "spec"),
        (["heldout", ""], "file"),
        (["inspect", ""], "target"),
        (["run", "--set", "scenario.seed=1", "--set", ""], "--set"),
    ],
)
def test_an_empty_argument_is_refused_not_taken_for_the_default(
    argv: list[str], named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    # the commands read a missing argument as "the default": `identify --out ""` rewrote the
    # committed coefficients file, `validate ""` checked the paper's scenario
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    expected = (
        f"twin: {named}: is empty" if named.startswith("--") else f"twin: {argv[0]}: the {named} is empty"
    )
    assert err == [expected], err
    assert list(tmp_path.iterdir()) == []  # nothing written


@pytest.mark.parametrize("count", ["-1", "100001", "99999999999999999999"])
def test_a_monte_carlo_beyond_its_bound_is_refused_before_the_run(count: str, tmp_path: Path, capsys) -> None:
    # 10^9 samples were taken at their word: the machine ran out of memory, summary.json said
    # "completed" and the command was killed without a line
    assert main(["run", "--uncertainty", count, "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"twin: --uncertainty: expected a number of samples in [0, 100000], got {count}"], err
    assert not (tmp_path / "r").exists()


def test_the_papers_drift_is_shown_only_beside_the_papers_replay(tmp_path: Path, capsys) -> None:
    assert (
        main(["run", "constant-load", "--out", str(tmp_path / "a"), "--set", 'scenario.duration="2 min"'])
        == 0
    )
    assert main(["run", "--uncertainty", "0", "--out", str(tmp_path / "b")]) == 0
    out = capsys.readouterr().out.splitlines()
    other = next(ln for ln in out if ln.startswith("constant-load:"))
    paper = next(ln for ln in out if ln.startswith("li2017-thermal-experiment:"))
    assert "paper" not in other and "(paper -0.021 mm)" in paper


def test_the_progress_bar_names_its_phases_on_a_terminal(tmp_path: Path) -> None:
    # issue 14: not silent while the FMUs load (or build) and while the outputs are written
    import os
    import pty
    import select
    import subprocess
    import sys

    master, slave = pty.openpty()
    cmd = [sys.executable, "-c", "import sys; from twin.cli import console; sys.exit(console())", "run", "constant-load",
           "--out", str(tmp_path / "run"), "--set", 'scenario.duration="20 min"']  # fmt: skip
    proc = subprocess.Popen(cmd, stdin=slave, stdout=slave, stderr=slave)
    os.close(slave)
    text = b""
    while True:
        if select.select([master], [], [], 1.0)[0]:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                break
            if not chunk:
                break
            text += chunk
        elif proc.poll() is not None:
            break
    proc.wait(timeout=120)
    os.close(master)
    shown = text.decode(errors="replace")
    assert proc.returncode == 0, shown[-2000:]
    for phase in ("loading FMUs", "simulating", "writing outputs"):
        assert phase in shown, (phase, shown[-2000:])


@pytest.mark.parametrize(
    ("argv", "option", "expected"),
    [
        (["calibrate", "--out", "adir"], "--out", "expected a file name ending in .toml"),
        # the parameter file went to z.json and was overwritten by its own report (z.json)
        (["calibrate", "--out", "z.json"], "--out", "expected a file name ending in .toml"),
        (["calibrate", "--out", "afile/x.toml"], "--out", "afile is a file"),
        (["identify", "--out", "adir"], "--out", "expected a file name ending in .toml"),
        (["identify", "--out", "afile/x.toml"], "--out", "afile is a file"),
        (["identify", "--out", "/proc/x.toml"], "--out", "special file system (proc)"),
        (["export-ssp", "constant-load", "-o", "/dev/x.ssp"], "-o", "special file system (dev)"),
        (["export-ssp", "constant-load", "-o", "adir.ssp"], "-o", "exists and is not a file"),
    ],
)
def test_an_output_file_no_command_can_write_is_refused_before_it_computes(
    argv: list[str], option: str, expected: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    # they were found after seconds of fitting (exit 1), or not at all: /dev/x.ssp was written
    monkeypatch.chdir(tmp_path)
    (tmp_path / "adir").mkdir()
    (tmp_path / "adir.ssp").mkdir()
    (tmp_path / "afile").write_text("x")
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {option}: ") and expected in err[0], err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adir", "adir.ssp", "afile"]
    assert not any((tmp_path / "adir").iterdir()) and not Path("/dev/x.ssp").exists()


@pytest.mark.parametrize(
    ("sets", "reason"),
    [
        (["fmu.thermal.parameters.hyd_share_oil=0.5"], "the hyd_share_* parameters sum to 0.5"),
        (
            ["fmu.thermal.parameters.c_sensor=0.001", "fmu.thermal.parameters.g_sensor_room=1e5"],
            "the network is too stiff for solver_step = 10 s",  # the paper's: its period
        ),
    ],
)
def test_validate_refuses_parameters_the_fmus_themselves_refuse(sets: list[str], reason: str, capsys) -> None:
    # each value in its range, together refused by the FMU's own check: validate said "ok",
    # and twin run failed in the FMU's initialization after making its run folder
    argv = ["validate", "li2017-thermal-experiment"]
    for s in sets:
        argv += ["--set", s]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fmu.thermal.parameters: the FMU refuses them" in err[0] and reason in err[0], (
        err
    )


def test_run_refuses_parameters_the_fmus_refuse_before_it_makes_its_folder(tmp_path: Path, capsys) -> None:
    # it used to fail in the FMU's initialization with exit 1 and a run folder begun
    out = tmp_path / "r"
    argv = [
        "run",
        "--set",
        "fmu.thermal.parameters.hyd_share_oil=0.5",
        "--uncertainty",
        "0",
        "--out",
        str(out),
    ]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "fmu.thermal.parameters: the FMU refuses them" in err[0], err
    assert not out.exists()
