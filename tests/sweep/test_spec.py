"""Sweep files: SALib's problem dict one to one, spreads around the base, grids, and every
bad input as exit 2 with one line ``file: key: what``."""

from __future__ import annotations

import math
from pathlib import Path

import dask
import pytest

from tests.sweep.helpers import PAPER, write_spec
from twin.cli import main as twin
from twin.config.load import load_scenario, scenarios_dir
from twin.fmu.catalog import variables as model_variables
from twin.sweep.spec import Spec, load_spec

SINE = scenarios_dir() / "sine-load.toml"


def _spec(path: Path, body: str, base: Path = PAPER) -> Spec:
    return load_spec(write_spec(path, body, base=base))


def test_problem_table_is_salibs_problem_dict(tmp_path: Path) -> None:
    spec = _spec(
        tmp_path / "s.toml",
        """design = "saltelli"
samples = 8
[problem]
names = ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift"]
bounds = [[1.0, 9.0], [0.0, 3e-7]]
dists = ["unif", "norm"]
groups = ["room", "probe"]
""",
    )
    assert dict(spec.problem) == {
        "num_vars": 2,
        "names": ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift"],
        "bounds": [[1.0, 9.0], [0.0, 3e-7]],
        "dists": ["unif", "norm"],
        "groups": ["room", "probe"],
    }
    assert spec.scenario.source_path == str(PAPER.resolve()) and spec.name == "s" and spec.seed == 0


def test_spreads_compile_to_salib_rows_around_the_base_values(tmp_path: Path) -> None:
    spec = _spec(
        tmp_path / "mc.toml",
        """design = "montecarlo"
samples = 4
[spread]
# from the calibration file the paper's scenario includes
"fmu.thermal.parameters.g_detecting_frame_room" = { dist = "lognormal", sigma = 0.3 }
# from the FMU's declared start value: 1.17e-5 1/K, 4 % of it
"fmu.mechanics.parameters.alpha_long_pole" = { dist = "normal", sigma = 0.04, relative = true }
"fmu.sensors.parameters.probe_zero_drift" = { dist = "normal", mean = 0.0, sigma = 0.3e-6 }
# the probe's mounting tilt of the tester as built: the mechanics model's declared value
"fmu.mechanics.parameters.sensor_tilt" = { dist = "uniform", half_width = 0.0087 }
"input.thermal.t_room.rise" = { dist = "truncnorm", sigma = 1.0, low = 7.9, high = 9.9 }
""",
    )
    pairs = zip(spec.problem["dists"], spec.problem["bounds"], strict=True)
    rows = dict(zip(spec.problem["names"], pairs, strict=True))
    assert rows["fmu.thermal.parameters.g_detecting_frame_room"][0] == "lognorm"
    calibrated = load_scenario(PAPER).nominal("fmu.thermal.parameters.g_detecting_frame_room")
    assert calibrated is not None and calibrated != 1.0  # the calibration's value, not a default
    assert rows["fmu.thermal.parameters.g_detecting_frame_room"][1] == pytest.approx(
        [math.log(calibrated), 0.3]
    )
    assert rows["fmu.mechanics.parameters.alpha_long_pole"] == (
        "norm",
        pytest.approx([1.17e-5, 0.04 * 1.17e-5]),
    )
    assert rows["fmu.sensors.parameters.probe_zero_drift"] == ("norm", [0.0, 0.3e-6])
    tilt = float(model_variables("FixtureMechanics")["sensor_tilt"].start)
    assert rows["fmu.mechanics.parameters.sensor_tilt"] == (
        "unif",
        pytest.approx([tilt - 0.0087, tilt + 0.0087]),
    )
    assert rows["input.thermal.t_room.rise"] == ("truncnorm", [7.9, 9.9, 8.9, 1.0])


def test_grid_levels_and_fixed_overrides(tmp_path: Path) -> None:
    spec = _spec(
        tmp_path / "g.toml",
        """design = "grid"
set = ['input.thermal.t_room = { profile = "sine", mean = 293.15, amplitude = 0.0, period = "1 h" }']
[grid]
"input.thermal.t_room.amplitude" = [0.0, 1.5, 3.0]
"fmu.hydraulic.parameters.load_amplitude" = [0, 25e3]
""",
        base=SINE,
    )
    assert spec.names == ["input.thermal.t_room.amplitude", "fmu.hydraulic.parameters.load_amplitude"]
    assert spec.levels == ((0.0, 1.5, 3.0), (0, 25e3))
    assert spec.scenario.profile("thermal.t_room").kind == "sine"  # the fixed override, applied once


def main(args: list[str]) -> int:
    """``twin sweep ARGS``."""
    return twin(["sweep", *args])


# ------------------------------------------------------------------------------ bad input

LHS = 'design = "lhs"\nsamples = 4\n'
#: eight conductances of the thermal network, each in a grid of twenty levels
GRID_KEYS = [
    "g_base_room",
    "g_heel_block_room",
    "g_bearing_block_room",
    "g_spindle_room",
    "g_t_plate_room",
    "g_detecting_frame_room",
    "g_clamp_room",
    "g_oil_room",
]
BAD = {
    "unknown key": (
        LHS + '[problem]\nnames = ["input.thermal.t_room.rize"]\nbounds = [[0.0, 9.0]]\n',
        "input.thermal.t_room.rize: the 'exponential' profile has no parameter 'rize'",
    ),
    "unknown parameter": (
        LHS + '[problem]\nnames = ["fmu.thermal.parameters.g_nowhere"]\nbounds = [[1.0, 2.0]]\n',
        "fmu.thermal.parameters.g_nowhere: ThermalNetwork has no parameter 'g_nowhere'",
    ),
    "unknown table": (LHS + "[problems]\nnames = []\n", "problems: unknown key"),
    "empty names": (LHS + "[problem]\nnames = []\nbounds = []\n", "problem: empty design"),
    "no samples": (
        'design = "lhs"\nsamples = 0\n[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n',
        "sweep.samples: empty design",
    ),
    "empty grid": ('design = "grid"\n[grid]\n"input.thermal.t_room.rise" = []\n', "empty design"),
    "negative spread": (
        LHS + '[spread]\n"input.thermal.t_room.rise" = { dist = "normal", sigma = -0.5 }\n',
        "sigma: negative spread -0.5",
    ),
    "impossible uniform": (
        LHS + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[9.0, 0.0]]\n',
        "impossible unif [9.0, 0.0]",
    ),
    "impossible normal": (
        LHS + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[1.0, 0.0]]\ndists = ["norm"]\n',
        "impossible norm [1.0, 0.0]: standard deviation must be positive",
    ),
    "lognormal of a negative": (
        LHS + '[spread]\n"fmu.sensors.parameters.probe_zero_drift" = { dist = "lognormal", sigma = 0.3 }\n',
        "lognormal needs 'sigma' and a positive median",
    ),
    "spread of a parameter nobody has": (
        LHS + '[spread]\n"fmu.sensors.parameters.nope" = { dist = "normal", sigma = 0.3e-6 }\n',
        "spread.\"fmu.sensors.parameters.nope\": SensorsDAQ has no parameter 'nope'",
    ),
    "unknown distribution": (
        LHS + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\ndists = ["gauss"]\n',
        "unknown distribution 'gauss'",
    ),
    "centre out of range": (
        LHS + '[problem]\nnames = ["fmu.thermal.parameters.g_base_room"]\nbounds = [[-9.0, -1.0]]\n',
        "outside the physical range",
    ),
    "unknown design": ('design = "taguchi"\n', "sweep.design: expected one of"),
    "name escaping the folder": (
        'name = "../../x"\n'
        + LHS
        + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n',
        "sweep.name: '../../x' cannot name a folder",
    ),
    "absolute name": (
        'name = "/tmp/x"\n'
        + LHS
        + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n',
        "sweep.name: '/tmp/x' cannot name a folder",
    ),
    # a 2.5 KB file once asked for 2.56e10 points and a Saltelli design for 5.9e7: the
    # machine's memory filled before a point ran (a hostile review)
    "grid of ten billion points": (
        'design = "grid"\n[grid]\n'
        + "".join(f'"fmu.thermal.parameters.{g}" = {[1.0 + i / 10 for i in range(20)]}\n' for g in GRID_KEYS),
        "grid: 25600000000 points, more than the 1000000 a sweep may have",
    ),
    "saltelli of 59 million points": (
        'design = "saltelli"\nsamples = 8388608\n[problem]\nnames = ["input.thermal.t_room.rise", '
        '"fmu.thermal.parameters.g_base_room", "fmu.thermal.parameters.g_oil_room"]\n'
        "bounds = [[0.0, 1.0], [10.0, 20.0], [10.0, 20.0]]\n",
        "sweep.samples: 41943040 points, more than the 1000000 a sweep may have",
    ),
    "sobol not a power of two": (
        'design = "saltelli"\nsamples = 12\n[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n',
        "sweep.samples: saltelli needs a power of two",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_sweep_file_exits_2_with_one_line(
    case: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    body, expected = BAD[case]
    path = write_spec(tmp_path / "bad.toml", body)
    assert main([str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1, err
    assert err[0].startswith(f"twin: {path}: ") and expected in err[0], err[0]
    assert not (tmp_path / "out").exists()  # nothing started


def test_missing_base_and_missing_file_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main([str(tmp_path / "nope.toml")]) == 2
    assert capsys.readouterr().err.strip() == f"twin: {tmp_path / 'nope.toml'}: file not found"
    path = tmp_path / "s.toml"
    path.write_text('[sweep]\nbase = "missing.toml"\ndesign = "lhs"\n')
    assert main([str(path)]) == 2
    assert "missing.toml: file not found" in capsys.readouterr().err


def test_unreachable_scheduler_exits_2_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    path = write_spec(
        tmp_path / "s.toml", LHS + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n'
    )
    # distributed adds its defaults to dask's config when first imported; imported inside the
    # set() below, they would leave with it (set() removes keys it did not find), and later
    # tests in this process would miss every distributed.* key (KeyError 'distributed')
    import distributed  # noqa: F401

    with dask.config.set({"distributed.comm.timeouts.connect": "2s"}):
        code = main([str(path), "--out", str(tmp_path / "out"), "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and err[0].startswith("twin: --scheduler: cannot reach the scheduler")
    assert not (tmp_path / "out").exists()  # a retry needs no --resume


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--workers", "0"], "expected a positive number of workers"),
        (["--workers", "2", "--scheduler", "tcp://x:1"], "--workers: applies to the local cluster only"),
    ],
)
def test_bad_arguments_exit_2(
    args: list[str], expected: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = write_spec(
        tmp_path / "s.toml", LHS + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n'
    )
    assert main([str(path), *args]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and expected in err[0]


def test_a_bad_fixed_override_is_named_where_it_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    body = 'design = "lhs"\nsamples = 2\nset = ["scenario.bogus = 3", "fmu.thermal.parameters.zzz = 3"]\n'
    path = write_spec(
        tmp_path / "s.toml",
        body + '[problem]\nnames = ["input.thermal.t_room.rise"]\nbounds = [[0.0, 1.0]]\n',
    )
    assert main([str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"twin: {path}: sweep.set: scenario.bogus: unknown key")
    assert all(line.startswith(f"twin: {path}: sweep.set: ") for line in err)
    assert not (tmp_path / "out").exists()
