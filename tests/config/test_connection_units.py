"""Units at connections (issue 29): compatible units converted with pint (twin.units), different
dimensions refused before anything runs, a unit-less input fed once the scenario says its unit.

The FMUs: the thermal network (temperatures in K, energies in J) and the test-only models of
tests/data/models: Lag (a lag of a temperature in degC) and Gain (no units declared)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import load_scenario
from twin.cosim.master import run_scenario
from twin.cosim.plan import InputKind, make_plan

T_LAG = 60.0
PERIOD = 10.0

THERMAL = """
[scenario]
name = "units"
duration = "20 min"
step = "10 s"
output_interval = "10 s"
seed = 1
[fmu.thermal]
model = "ThermalNetwork"
period = "10 s"
parameters = { solver_step = 1.0 }
[input.thermal.t_room]
profile = "ramp"
start = 293.15
end = 303.15
duration = "10 min"
[input.thermal.q_hydraulic]
profile = "constant"
value = 300.0
[input.thermal.q_friction]
profile = "constant"
value = 0.0
[input.thermal.q_pole_heater]
profile = "constant"
value = 0.0
[input.thermal.fault_inject]
profile = "constant"
value = 0.0
"""


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "units.toml"
    path.write_text(text)
    return path


def _lag(models: dict[str, Path], connection: str = '[connections]\n"thermal.t_bearing" = "lag.u"\n') -> str:
    return (
        THERMAL
        + f'[fmu.lag]\nmodel = "{models["Lag"]}"\nperiod = "10 s"\n'
        + f"parameters = {{ T = {T_LAG}, x0 = 20.0, solver_step = 1.0 }}\n"
        + connection
    )


def _lagged(u: np.ndarray, y0: float) -> np.ndarray:
    """What the lag shows at each exchange when its input is ``u`` held over each step."""
    decay = math.exp(-PERIOD / T_LAG)
    y = [y0]
    for value in u[:-1]:
        y.append(value + (y[-1] - value) * decay)
    return np.array(y)


def test_a_kelvin_output_reaches_a_celsius_input_converted(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    scenario = load_scenario(_write(tmp_path, _lag(test_models)))
    [c] = [c for c in scenario.connections if c.dst == "lag.u"]
    assert (c.factor, c.offset) == (1.0, -273.15)  # pint's K -> degC
    table = run_scenario(scenario).table
    assert table is not None
    t_bearing = table["thermal.t_bearing"]
    assert t_bearing.min() > 290.0 and np.ptp(t_bearing) > 0.1  # a temperature in K that moves
    assert table.meta["lag.y"].unit == "degC"
    np.testing.assert_allclose(table["lag.y"], _lagged(t_bearing - 273.15, 20.0), rtol=1e-12, atol=1e-12)


def test_a_delayed_connection_converts_too_its_initial_value_in_the_inputs_unit(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    delay = '[[delay]]\nfrom = "thermal.t_bearing"\nto = "lag.u"\ninitial = 25.0\n'
    scenario = load_scenario(_write(tmp_path, _lag(test_models, delay)))
    plan = make_plan(scenario)
    lag = plan.instances[1]
    [u] = lag.inputs
    assert (u.kind, u.initial, u.factor, u.offset) == (InputKind.DELAYED, 25.0, 1.0, -273.15)
    table = run_scenario(scenario).table
    assert table is not None
    # the input is 25 degC at the first exchange, then the bearing's temperature one exchange late
    u_held = np.concatenate([[25.0], table["thermal.t_bearing"][:-1] - 273.15])
    np.testing.assert_allclose(table["lag.y"], _lagged(u_held, 20.0), rtol=1e-12, atol=1e-12)


def test_units_of_different_dimensions_are_refused_in_one_line(
    test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = _write(tmp_path, _lag(test_models, '[connections]\n"thermal.energy_in" = "lag.u"\n'))
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert (
        f"{path}: connections.\"thermal.energy_in\": unit mismatch: thermal.energy_in is in 'J', lag.u in 'degC'"
        in lines[0]
    )
    assert "[temperature]" in lines[0]


def _gain(
    models: dict[str, Path], units: str = "", feed: str = '[connections]\n"thermal.t_bearing" = "gain.u"\n'
) -> str:
    return (
        THERMAL
        + f'[fmu.gain]\nmodel = "{models["Gain"]}"\nperiod = "10 s"\nparameters = {{ solver_step = 1.0 }}\n'
        + units
        + '[input.gain.k]\nprofile = "constant"\nvalue = 1.0\n'
        + '[input.gain.w]\nprofile = "constant"\nvalue = 0.0\n'
        + feed
    )


def test_a_unit_less_input_is_refused_a_signal_with_a_unit_until_the_scenario_gives_it_one(
    test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    path = _write(tmp_path, _gain(test_models))
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1, lines
    assert "thermal.t_bearing is in 'K', gain.u has no unit" in lines[0]
    assert '[fmu.gain] units = { u = "..." }' in lines[0]


def test_a_unit_the_scenario_gives_converts_and_labels_the_signal(
    test_models: dict[str, Path], tmp_path: Path
) -> None:
    scenario = load_scenario(_write(tmp_path, _gain(test_models, 'units = { u = "degC", y = "degC" }\n')))
    assert dict(scenario.fmu("gain").units) == {"u": "degC", "y": "degC"}
    table = run_scenario(scenario).table
    assert table is not None
    assert table.meta["gain.y"].unit == "degC"
    # y = 1 * u + 0: the gain shows the bearing's temperature in degC, one exchange late (Jacobi)
    np.testing.assert_array_equal(table["gain.y"][1:], table["thermal.t_bearing"][:-1] - 273.15)


@pytest.mark.parametrize(
    ("units", "words"),
    [
        ('{ u = "kelvinz" }', "fmu.gain.units.u: unknown unit 'kelvinz'"),
        ('{ solver_step = "s" }', "fmu.gain.units.solver_step: "),
        ('{ v = "K" }', "has no Real input or output 'v'"),
        ("{ u = 3 }", 'expected a unit such as "degC"'),
        ('"K"', "fmu.gain.units: expected a table"),
    ],
)
def test_a_bad_unit_given_to_a_variable_is_one_line(
    units: str, words: str, test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    # the input driven rather than connected: the unit given is the one problem
    text = _gain(
        test_models, f"units = {units}\n", feed='[input.gain.u]\nprofile = "constant"\nvalue = 1.0\n'
    )
    path = _write(tmp_path, text)
    assert main(["validate", str(path)]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and words in lines[0], lines


def test_a_variable_with_its_own_unit_keeps_it(
    test_models: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    text = _lag(test_models).replace("[connections]", '[fmu.lag.units]\nu = "K"\n[connections]')
    assert main(["validate", str(_write(tmp_path, text))]) == 2
    err = capsys.readouterr().err
    assert "fmu.lag.units.u: " in err and "declares 'degC' for u" in err
