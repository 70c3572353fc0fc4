"""The co-simulation engineer's `twin run` (issue 29, point 5), in fmpy's and cosim-cli's
words: --start-time, --stop-time, --step-size, --output-interval, --record, --input-file,
--fmi-logging, --format mat, and `twin run X.fmu` for one FMU alone. Every run is a real one
(real FMUs, real files); bad values are one line and exit 2, with nothing written."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.fmu import catalog
from twin.outputs.csv import read_signals_csv

#: the files a run without an error model leaves out
ERROR_MODEL_FILES = ("errormodel.csv", "error_budget.png", "wear.png")


@pytest.fixture()
def lowpass(tmp_path: Path, lowpass_fmu: Path) -> Path:
    """tests/data/LowPass (another tool's FMU: y' = (u - y) / T, T = 1 s by default), copied
    where the test works."""
    return Path(shutil.copy(lowpass_fmu, tmp_path / "LowPass.fmu"))


def _csv(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _run(*argv: str) -> int:
    return main(["run", *argv, "--quiet"])


def _columns(out: Path) -> list[str]:
    return (out / "signals.csv").read_text().splitlines()[0].split(",")


def _lowpass_y(times: np.ndarray, u: np.ndarray, t_filter: float = 1.0) -> np.ndarray:
    """The filter's exact response, stepped from 0 on the values u holds at each row's time."""
    y = np.zeros_like(u)
    for k in range(1, len(times)):
        decay = np.exp(-(times[k] - times[k - 1]) / t_filter)
        y[k] = u[k - 1] + (y[k - 1] - u[k - 1]) * decay
    return y


# -- twin run X.fmu --------------------------------------------------------------------------


@pytest.mark.parametrize("model", catalog.model_names())
def test_every_built_fmu_runs_alone_with_its_default_experiment(model: str, tmp_path: Path, capsys) -> None:
    from fmpy import read_model_description

    from twin.config.single_fmu import instance_name

    path = catalog.fmu(model)
    out = tmp_path / "run"
    assert main(["run", str(path), "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "completed; no error model or paper report" in said
    experiment = read_model_description(str(path)).defaultExperiment
    table = read_signals_csv(out / "signals.csv")
    inst = instance_name(model)
    variables = catalog.variables(model)
    outputs = {f"{inst}.{n}" for n, v in variables.items() if v.causality == "output" and v.type == "Real"}
    inputs = {f"{inst}.{n}" for n, v in variables.items() if v.causality == "input" and v.type == "Real"}
    assert set(table.names()) == outputs | inputs  # every output, every input at its start value
    for name in inputs:
        np.testing.assert_array_equal(table[name], variables[name.split(".", 1)[1]].start)
    step = float(experiment.stepSize)
    expected = np.arange(round(float(experiment.stopTime) / step) + 1) * step
    np.testing.assert_allclose(table.time, expected, rtol=0, atol=1e-9)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and "evaluate = false" in summary["errormodel"]
    assert "errormodel_error" not in summary and "drift_mm" not in summary
    assert not any((out / f).exists() for f in ERROR_MODEL_FILES)


def test_an_external_fmu_runs_alone_and_equals_fmpys_simulation(lowpass: Path, tmp_path: Path) -> None:
    """The same FMU, the same input file: `twin run` and `fmpy.simulate_fmu` give the same
    output (fmpy's reading of the file: linear between rows, a repeated time is a jump)."""
    from fmpy import simulate_fmu
    from fmpy.util import read_csv

    inputs = _csv(tmp_path / "u.csv", "time,u\n0,0\n0.55,1\n1.2,1\n1.2,-2\n2,0.5\n")
    out = tmp_path / "run"
    assert _run(str(lowpass), "--out", str(out), "--input-file", str(inputs), "--stop-time", "3") == 0
    table = read_signals_csv(out / "signals.csv")
    assert table.names() == ["low_pass.y", "low_pass.u"]
    result = simulate_fmu(
        str(lowpass),
        start_time=0,
        stop_time=3,
        output_interval=0.1,
        input=read_csv(str(inputs)),
        output=["y"],
    )
    np.testing.assert_allclose(table.time, result["time"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(table["low_pass.y"], result["y"], rtol=1e-13, atol=1e-15)
    # the input as fmpy applies it at each communication point (the jump at 1.2 s: its later value)
    np.testing.assert_array_equal(table["low_pass.u"][[0, 12, 20, 30]], [0.0, -2.0, 0.5, 0.5])
    np.testing.assert_allclose(table["low_pass.u"][3], 3 / 5.5, rtol=1e-15)


def test_a_lone_fmu_takes_set_for_its_parameters(lowpass: Path, tmp_path: Path) -> None:
    inputs = _csv(tmp_path / "u.csv", "time,u\n0,1\n")  # one row: a constant
    out = tmp_path / "run"
    argv = ["--out", str(out), "--input-file", str(inputs), "--set", "fmu.low_pass.parameters.T=2.5"]
    assert _run(str(lowpass), *argv) == 0
    table = read_signals_csv(out / "signals.csv")
    np.testing.assert_allclose(
        table["low_pass.y"], _lowpass_y(table.time, table["low_pass.u"], 2.5), rtol=1e-12
    )
    assert table["low_pass.y"][-1] == pytest.approx(1 - np.exp(-10 / 2.5), rel=1e-12)


# -- the times ----------------------------------------------------------------------------------


def test_start_stop_step_and_interval_land_in_signals_csv(lowpass: Path, tmp_path: Path) -> None:
    inputs = _csv(tmp_path / "u.csv", "time,u\n0,0\n10,10\n")  # u = t
    out = tmp_path / "run"
    times = ["--start-time", "1", "--stop-time", "4 s", "--step-size", "0.25", "--output-interval", "500 ms"]
    assert _run(str(lowpass), "--out", str(out), "--input-file", str(inputs), *times) == 0
    table = read_signals_csv(out / "signals.csv")
    np.testing.assert_array_equal(table.time, np.arange(1.0, 4.01, 0.5))
    np.testing.assert_array_equal(table["low_pass.u"], table.time)  # the profile at the clock's time
    # the filter starts at rest at 1 s and steps every 0.25 s on u held over each step
    fine = np.arange(1.0, 4.01, 0.25)
    np.testing.assert_allclose(table["low_pass.y"], _lowpass_y(fine, fine)[::2], rtol=1e-12)
    assert json.loads((out / "summary.json").read_text())["sim_end_s"] == 4.0


def test_a_scenario_starts_later_with_its_fmus_set_up_at_that_time(tmp_path: Path) -> None:
    out = tmp_path / "run"
    times = ["--start-time", "1 min", "--stop-time", "3 min", "--output-interval", "30"]
    assert _run("constant-load", "--out", str(out), "--fmi-logging", *times) == 0
    table = read_signals_csv(out / "signals.csv")
    np.testing.assert_array_equal(table.time, [60.0, 90.0, 120.0, 150.0, 180.0])
    log = (out / "fmi.log").read_text().splitlines()
    setups = [ln for ln in log if "fmi2SetupExperiment" in ln]
    assert len(setups) == 5 and all(ln.endswith("start time 60 s") for ln in setups), setups
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "completed" and summary["sim_end_s"] == 180.0
    assert summary["timing"]["macro_steps"] == 1200  # 2 min of 0.1 s steps, none before the start
    assert "predicted" in summary["drift_mm"]  # the error model ran on the run's window


def test_an_event_before_the_start_is_refused(tmp_path: Path, capsys) -> None:
    from twin.config.load import scenarios_dir

    scenario = _csv(
        tmp_path / "with-event.toml",
        f'extends = "{scenarios_dir() / "constant-load.toml"}"\n'
        '[scenario]\nname = "with-event"\nduration = "5 min"\n'
        '[[event]]\nat = "1 min"\naction = "bias"\ntarget = "sensors.probe_meas"\nvalue = 1e-6\n',
    )
    out = tmp_path / "run"
    assert _run(str(scenario), "--out", str(out), "--start-time", "2 min") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "event[0].at: 1 min is before scenario.start (2 min)" in err[0], err
    assert not out.exists()
    assert _run(str(scenario), "--out", str(out), "--start-time", "1 min") == 0  # at it: applied


def test_an_fmu_that_cannot_begin_later_is_named(tmp_path: Path, capsys) -> None:
    """An FMU may refuse fmi2SetupExperiment's start time (FMI 2.0 has no flag to say so
    beforehand): a variant of LowPass that runs from 0 only is refused before the run, one
    line naming the instance, the start and the FMU's reason."""
    from fmpy.build import build_platform_binary

    unzipped = tmp_path / "FromZero"
    shutil.copytree(Path(__file__).parent / "data" / "LowPass", unzipped)
    source = unzipped / "sources" / "lowpass.c"
    text = source.read_text()
    setup = "    ((Filter *)c)->time = start;\n"
    assert setup in text
    refuse = (
        '    if (start != 0.0) { say((Filter *)c, fmi2Error, "runs from time 0 only"); return fmi2Error; }\n'
    )
    source.write_text(text.replace(setup, refuse + setup))
    (tmp_path / "build").mkdir()
    build_platform_binary(unzipped, build_dir=tmp_path / "build")
    fmu = Path(
        shutil.move(
            shutil.make_archive(str(tmp_path / "FromZero"), "zip", unzipped), tmp_path / "FromZero.fmu"
        )
    )
    out = tmp_path / "run"
    assert _run(str(fmu), "--out", str(out), "--start-time", "2") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        f"twin: {fmu}: scenario.start: FMU 'low_pass' refuses to begin at 2 s: runs from time 0 only"
    ]
    assert not out.exists()
    assert _run(str(fmu), "--out", str(out), "--stop-time", "2") == 0  # from 0 it runs


# -- what is recorded, and in which files ----------------------------------------------------------


def test_record_chooses_signals_csvs_columns_and_the_error_model_still_runs(tmp_path: Path) -> None:
    out = tmp_path / "run"
    record = ["--record", "sensors.probe_meas", "thermal.t_base", "--record", "hydraulic.radial_load"]
    assert _run("constant-load", "--out", str(out), "--stop-time", "2 min", *record) == 0
    assert _columns(out) == ["time", "sensors.probe_meas", "thermal.t_base", "hydraulic.radial_load"]
    units = json.loads((out / "signals.units.json").read_text())
    assert list(units) == ["time", "sensors.probe_meas", "thermal.t_base", "hydraulic.radial_load"]
    summary = json.loads((out / "summary.json").read_text())
    assert "predicted" in summary["drift_mm"] and "thermal" in summary["error_parts_mm"]
    assert (out / "errormodel.csv").is_file() and (out / "error_budget.png").is_file()
    # the same values as an unrestricted run's
    full = tmp_path / "full"
    assert _run("constant-load", "--out", str(full), "--stop-time", "2 min") == 0
    a, b = read_signals_csv(out / "signals.csv"), read_signals_csv(full / "signals.csv")
    for name in a.names():
        np.testing.assert_array_equal(a[name], b[name])


def test_record_takes_a_lone_fmus_variables_by_their_own_names(lowpass: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert _run(str(lowpass), "--out", str(out), "--record", "u", "low_pass.y", "time", "u") == 0
    assert _columns(out) == ["time", "low_pass.u", "low_pass.y"]


def test_compensate_names_a_column_record_left_out(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert _run("constant-load", "--out", str(out), "--stop-time", "2 min", "--record", "thermal.t_base") == 0
    assert main(["compensate", str(out), "--out", str(tmp_path / "comp")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "signals.csv" in err[0] and "no column" in err[0], err


def test_fmi_logging_writes_each_fmus_messages_with_instance_and_category(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    assert main(["run", "constant-load", "--out", str(out), "--stop-time", "1 min", "--fmi-logging"]) == 0
    said = capsys.readouterr().out
    assert f"fmi log: 15 messages of the FMUs in {out / 'fmi.log'}" in said
    lines = (out / "fmi.log").read_text().splitlines()
    instances = ("hydraulic", "oscillation", "thermal", "mechanics", "sensors")
    for inst in instances:
        mine = [ln for ln in lines if ln.startswith(f"{inst} ")]
        assert [ln.split(" ", 3)[1:3] for ln in mine] == [["fmi2OK", "[logAll]"]] * 3, mine
        assert "fmi2SetupExperiment" in mine[0] and "fmi2ExitInitializationMode" in mine[1]
        assert "fmi2Terminate: at 60" in mine[2] and mine[2].endswith("internal steps")
    # without the flag the FMUs log nothing and there is no fmi.log
    quiet = tmp_path / "quiet"
    assert _run("constant-load", "--out", str(quiet), "--stop-time", "1 min") == 0
    assert not (quiet / "fmi.log").exists()


def test_fmi_logging_keeps_an_fmus_error_with_its_category(tmp_path: Path, capsys) -> None:
    from twin.config.load import scenarios_dir

    scenario = _csv(
        tmp_path / "fault.toml",
        f'extends = "{scenarios_dir() / "constant-load.toml"}"\n'
        '[scenario]\nname = "fault"\nduration = "2 min"\n'
        '[[event]]\nat = "1 min"\naction = "fault"\ntarget = "mechanics"\nfault = "error"\n',
    )
    out = tmp_path / "run"
    assert _run(str(scenario), "--out", str(out), "--fmi-logging") == 1
    errors = [ln for ln in (out / "fmi.log").read_text().splitlines() if " fmi2Error " in ln]
    assert errors and errors[0].startswith("mechanics fmi2Error [logStatusError] "), errors


@pytest.mark.parametrize("scenario", ["lowpass", "constant-load"])
def test_format_mat_reads_back_to_the_csvs_values(scenario: str, request, tmp_path: Path) -> None:
    from scipy.io import loadmat

    source = str(request.getfixturevalue("lowpass")) if scenario == "lowpass" else scenario
    out = tmp_path / "run"
    assert _run(source, "--out", str(out), "--stop-time", "1 min", "--format", "mat") == 0
    table = read_signals_csv(out / "signals.csv")
    mat = loadmat(str(out / "signals.mat"), simplify_cells=True)
    np.testing.assert_array_equal(mat["time"], table.time)
    assert list(mat["names"]) == ["time", *table.names()]
    assert list(mat["mat_names"]) == ["time", *table.names()]  # the twin's names are MATLAB names
    for name in table.names():
        instance, variable = name.split(".", 1)
        np.testing.assert_array_equal(mat[instance][variable], table[name], err_msg=name)
    assert len(table) > 10


def test_mat_names_map_any_variable_name_to_a_matlab_name() -> None:
    from twin.outputs.mat import mat_names, mat_problem

    long = "v" * 70
    columns = ["f.der(x)", "f.x[1]", "f.x_1_", "f.x(1)", "f.1st", f"f.{long}", f"f.{long}z", "g.a.b"]
    mapped = mat_names(columns)
    assert [mapped[c] for c in columns] == [
        ("f", "der_x_"),
        ("f", "x_1_"),
        ("f", "x_1__2"),
        ("f", "x_1__3"),
        ("f", "x1st"),
        ("f", "v" * 63),
        ("f", "v" * 61 + "_2"),
        ("g", "a_b"),
    ]
    assert mat_problem(["thermal", "low_pass"]) is None
    assert "clash" in (mat_problem(["names"]) or "")


def test_resume_keeps_the_experiment_the_columns_and_the_mat_file(tmp_path: Path) -> None:
    out = tmp_path / "run"
    args = ["--out", str(out), "--start-time", "5 min", "--stop-time", "25 min", "--output-interval", "10"]
    args += [
        "--record",
        "sensors.probe_meas",
        "thermal.t_base",
        "--format",
        "mat",
        "--checkpoint-every",
        "5 min",
    ]
    assert _run("constant-load", *args) == 0
    whole = (out / "signals.csv").read_bytes()
    (out / "summary.json").unlink()
    (out / "signals.mat").unlink()
    assert main(["resume", str(out), "--quiet"]) == 0
    assert (out / "signals.csv").read_bytes() == whole
    summary = json.loads((out / "summary.json").read_text())
    assert summary["timing"]["resumed_from_s"] == 1200.0  # the last checkpoint, not the start
    assert (out / "signals.mat").is_file()
    meta = json.loads((out / "run.json").read_text())
    assert meta["experiment"] == {"start": "5 min", "stop": "25 min", "output_interval": "10"}
    assert meta["record"] == ["sensors.probe_meas", "thermal.t_base"] and meta["formats"] == ["mat"]


# -- the input file ---------------------------------------------------------------------------------


def test_an_input_file_drives_a_scenarios_input(tmp_path: Path) -> None:
    inputs = _csv(tmp_path / "room.csv", "time,thermal.t_room\n0,293.15\n120,303.15\n")
    out = tmp_path / "run"
    assert _run("constant-load", "--out", str(out), "--stop-time", "2 min", "--input-file", str(inputs)) == 0
    table = read_signals_csv(out / "signals.csv")
    # the column shows the value last set on the input: the thermal network takes it every 10 s
    # (and at the end, where every input takes its value)
    set_at = np.floor(table.time[:-1] / 10) * 10
    np.testing.assert_allclose(table["thermal.t_room"][:-1], 293.15 + set_at / 12, rtol=1e-15)
    assert table["thermal.t_room"][-1] == 303.15 and table.time[-1] == 120.0


@pytest.mark.parametrize("how", ["header", "sidecar"])
def test_an_input_files_unit_is_converted_to_the_inputs(how: str, lowpass: Path, tmp_path: Path) -> None:
    header = "u [mm]" if how == "header" else "u"
    inputs = _csv(tmp_path / "u.csv", f"time,{header}\n0,250\n1,750\n")
    if how == "sidecar":
        (tmp_path / "u.units.json").write_text(json.dumps({"time": {"unit": "s"}, "u": {"unit": "mm"}}))
    out = tmp_path / "run"
    assert _run(str(lowpass), "--out", str(out), "--input-file", str(inputs), "--stop-time", "1") == 0
    table = read_signals_csv(out / "signals.csv")
    np.testing.assert_allclose(table["low_pass.u"], 0.25 + 0.5 * table.time, rtol=1e-15)


def test_a_runs_signals_csv_drives_another_run(lowpass: Path, tmp_path: Path) -> None:
    first, second = tmp_path / "first", tmp_path / "second"
    inputs = _csv(tmp_path / "u.csv", "time,u\n0,0\n2,1\n")
    assert _run(str(lowpass), "--out", str(first), "--input-file", str(inputs), "--stop-time", "2") == 0
    replay = first / "signals.csv"
    assert _run(str(lowpass), "--out", str(second), "--input-file", str(replay), "--record", "y") == 2
    # its columns name an output too: only a file of inputs drives
    only_u = tmp_path / "only-u.csv"
    table = read_signals_csv(replay)
    only_u.write_text(
        "time,low_pass.u\n"
        + "".join(
            f"{float(t)!r},{float(u)!r}\n" for t, u in zip(table.time, table["low_pass.u"], strict=True)
        )
    )
    assert _run(str(lowpass), "--out", str(second), "--input-file", str(only_u), "--stop-time", "2") == 0
    assert (second / "signals.csv").read_bytes() == replay.read_bytes()


# -- bad values: one line, exit 2, nothing written --------------------------------------------------

BAD_CSV = {
    "no-time-column": ("t,u\n0,1\n", "first column must be 'time'"),
    "not-a-number": ("time,u\n0,1\n1,one\n", "line 3: column 'u': 'one' is not a number"),
    "time-goes-back": ("time,u\n0,1\n2,1\n1,1\n", "line 4: time 1.0 s is not after 2.0 s"),
    "three-rows-at-one-time": ("time,u\n0,1\n1,1\n1,2\n1,3\n", "line 5: time 1.0 s is not after"),
    "no-rows": ("time,u\n", "no rows"),
    "empty": ("", "empty file"),
    "nan": ("time,u\n0,nan\n1,1\n", "not a finite number"),
    "an-output": ("time,y\n0,1\n1,1\n", "low_pass.y is an output, not an input"),
    "unknown-column": ("time,v\n0,1\n1,1\n", "no free input named 'v'"),
    "unit-of-another-dimension": ("time,u [s]\n0,1\n1,1\n", "column 'u'"),
}


@pytest.mark.parametrize("case", BAD_CSV, ids=list(BAD_CSV))
def test_a_malformed_input_file_is_one_line_and_exit_2(
    case: str, lowpass: Path, tmp_path: Path, capsys
) -> None:
    text, expected = BAD_CSV[case]
    inputs = _csv(tmp_path / "in.csv", text)
    out = tmp_path / "run"
    assert _run(str(lowpass), "--out", str(out), "--input-file", str(inputs)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"twin: {inputs}: ") and expected in err[0], err
    assert not out.exists()


BAD_FLAGS = {
    "negative-step": (["--step-size", "-0.1"], "twin: --step-size: '-0.1': a time must not be negative"),
    "zero-step": (["--step-size", "0"], "twin: --step-size: '0': must be positive"),
    "stop-before-start": (
        ["--start-time", "3", "--stop-time", "2"],
        "twin: --stop-time: 2 s is not after --start-time (3 s)",
    ),
    "start-after-the-end": (
        ["--start-time", "20"],
        "scenario.start: 20 s is not before scenario.duration (10 s)",
    ),
    "start-off-the-grid": (
        ["--start-time", "0.05"],
        "scenario.start: 50 ms is not a multiple of scenario.step",
    ),
    "interval-off-the-grid": (
        ["--output-interval", "0.15"],
        "scenario.output_interval: 150 ms is not a multiple",
    ),
    "not-a-time": (["--stop-time", "ten"], "twin: --stop-time: expected a duration like"),
    "unknown-record": (
        ["--record", "yy"],
        "twin: --record: no column 'low_pass.yy' (did you mean 'low_pass.y'?)",
    ),
    "record-a-parameter": (["--record", "T"], "'low_pass.T' is a parameter (Real): signals.csv holds"),
    "unknown-format": (["--format", "xls"], "argument --format: invalid choice: 'xls'"),
    "missing-input-file": (["--input-file", "nowhere.csv"], "nowhere.csv: cannot read"),
}


@pytest.mark.parametrize("case", BAD_FLAGS, ids=list(BAD_FLAGS))
def test_a_bad_flag_is_one_line_and_exit_2(case: str, lowpass: Path, tmp_path: Path, capsys) -> None:
    flags, expected = BAD_FLAGS[case]
    out = tmp_path / "run"
    assert _run(str(lowpass), "--out", str(out), *flags) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and expected in err[0], err
    assert "Traceback" not in err[0] and not out.exists()


def test_several_bad_times_are_reported_at_once(lowpass: Path, capsys) -> None:
    assert _run(str(lowpass), "--step-size", "-1", "--output-interval", "x") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert [ln.split(":")[1].strip() for ln in err] == ["--step-size", "--output-interval"], err


def test_validate_checks_the_same_flags(lowpass: Path, capsys) -> None:
    assert main(["validate", str(lowpass), "--stop-time", "5", "--record", "y"]) == 0
    assert "ok (LowPass: 1 FMUs" in capsys.readouterr().out
    assert main(["validate", str(lowpass), "--record", "z"]) == 2
