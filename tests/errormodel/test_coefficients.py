"""The coefficients file: the error model reads its coefficients from it and from nothing else.

Not from the FMUs' parameters (a scenario that changes the truth leaves the model's coefficients
as they were), and a bad file is one line of bad input naming the file and the key.
"""

from __future__ import annotations

import math
import pickle
import tomllib
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.config.load import load_scenario, scenarios_dir
from twin.errormodel.coefficients import (
    coefficient_units,
    default_path,
    load_coefficients,
    load_priors,
    parse_coefficients,
)
from twin.errormodel.config import errormodel_config, evaluation_config
from twin.errormodel.sources import MechanicalCoefficients, ThermalCoefficients
from twin.errors import ConfigError

#: the tester's truth, changed well beyond the spreads of a tester as built (facts 6)
PERTURBED_TRUTH = [
    "fmu.mechanics.parameters.alpha_long_pole=1.6e-5",
    "fmu.mechanics.parameters.alpha_heel_block=0.8e-5",
    "fmu.mechanics.parameters.l_detecting_frame=0.30",
    "fmu.mechanics.parameters.l_pole_lower=0.35",
    "fmu.mechanics.parameters.h_bearing_block=0.2",
    "fmu.mechanics.parameters.liner_modulus=2.0e9",
    "fmu.mechanics.parameters.compliance_structure=2e-10",
    "fmu.mechanics.parameters.sensor_tilt=0.05",
    "fmu.mechanics.parameters.abbe_offset=0.04",
    "fmu.mechanics.parameters.spindle_runout=5e-6",
    "fmu.sensors.parameters.probe_zero_drift=1.0e-6",
]


def committed():
    return load_coefficients(default_path())


def test_the_committed_file_holds_every_coefficient_with_a_finite_positive_standard_error() -> None:
    c = committed()
    assert list(c.coefficients) == list(coefficient_units())
    for name, x in c.coefficients.items():
        assert math.isfinite(x.value), name
        assert math.isfinite(x.std_error) and x.std_error > 0, name
        assert x.unit == coefficient_units()[name]
        assert x.experiment in c.fits, name
    for fit in c.fits.values():
        assert 1 <= fit.rank <= len(fit.parameters)
        assert len(fit.correlation) == len(fit.parameters)
    assert c.identified["by"] == "twin identify"


def test_a_written_file_reads_back_the_same(tmp_path: Path) -> None:
    c = committed()
    path = c.write(tmp_path / "c.toml", header="a header\nof two lines")
    back = load_coefficients(path)
    assert back.coefficients == c.coefficients
    assert back.identified == c.identified
    for name, fit in c.fits.items():
        assert back.fits[name].parameters == fit.parameters
        # a correlation is written to four places
        np.testing.assert_allclose(back.fits[name].correlation, fit.correlation, atol=1e-4)
        assert back.fits[name].condition_number == fit.condition_number
    assert path.read_text().startswith("# a header\n# of two lines\n")


def test_coefficients_pickle() -> None:
    # a sweep's Dask workers send them back
    c = committed()
    assert pickle.loads(pickle.dumps(c)) == c


@pytest.mark.parametrize(
    "scenario", ["li2017-thermal-experiment.toml", "constant-load.toml", "day-night.toml"]
)
def test_changing_the_tester_does_not_change_the_error_models_coefficients(scenario: str) -> None:
    nominal = load_scenario(scenarios_dir() / scenario)
    perturbed = load_scenario(scenarios_dir() / scenario, PERTURBED_TRUTH)
    # the truth did change ...
    assert perturbed.fmu("mechanics").parameters["alpha_long_pole"].value == 1.6e-5
    assert perturbed.fmu("sensors").parameters["probe_zero_drift"].value == 1.0e-6
    assert (
        nominal.fmu("mechanics").parameters["alpha_long_pole"].value == 1.17e-5
    )  # the drawing's handbook value
    # ... the model did not: its coefficients are the file's, for both runs
    a, b = evaluation_config(nominal), evaluation_config(perturbed)
    assert a.thermal == b.thermal == committed().thermal()
    assert a.mechanics == b.mechanics == committed().mechanics()


def test_a_scenario_names_its_coefficients_file_relative_to_itself(tmp_path: Path) -> None:
    mine = committed().with_values(alpha_l_detecting_frame=9.9e-6, load_compliance=3.3e-10)
    mine.write(tmp_path / "mine.toml")
    scenario = tmp_path / "s.toml"
    base = (scenarios_dir() / "constant-load.toml").resolve()
    scenario.write_text(f'extends = "{base}"\n[errormodel]\ncoefficients = "mine.toml"\n')
    cfg = evaluation_config(load_scenario(scenario))
    assert cfg.thermal.alpha_l_detecting_frame == 9.9e-6
    assert cfg.mechanics.load_compliance == 3.3e-10


def test_a_labs_errormodel_table_may_hold_the_coefficients_inline() -> None:
    table = {
        name: {"value": x.value, "std_error": x.std_error, "unit": x.unit, "experiment": "lab"}
        for name, x in committed().coefficients.items()
    }
    table["probe_zero_drift"]["value"] = 0.7e-6
    cfg = errormodel_config(None, {"coefficients": table}, "LAB.toml", 300.0)
    assert cfg.thermal.probe_zero_drift == 0.7e-6
    assert cfg.mechanics == committed().mechanics()


def test_the_error_models_coefficients_are_declared_with_units_and_the_priors_cover_them() -> None:
    units = coefficient_units()
    assert set(units) == {*ThermalCoefficients.units(), *MechanicalCoefficients.units()}
    assert all(units[n] == ("1/K" if n == "probe_span_drift" else "m/K") for n in ThermalCoefficients.units())
    priors = load_priors()
    assert set(priors) == set(units)
    # every thermal coefficient has a real prior (the soak cannot see every one of them)
    assert all(priors[n].sigma and priors[n].sigma > 0 for n in ThermalCoefficients.units())


# ----------------------------------------------------------------------------- bad files


def _file_text() -> str:
    return default_path().read_text(encoding="utf-8")


def _table_span(text: str, table: str) -> tuple[int, int]:
    """Where the body of ``[table]`` starts and ends in ``text``."""
    start = text.index(f"[{table}]\n") + len(table) + 3
    return start, text.index("\n\n", start)


def _without(table: str) -> str:
    """The committed file without ``[table]``."""
    text = _file_text()
    start, end = _table_span(text, table)
    return text[: start - len(table) - 3] + text[end + 2 :]


def _bad(edit: str) -> str:
    """The committed file with one coefficient's table edited (``key=value``, or ``key`` to
    take the key out)."""
    text = _file_text()
    start, end = _table_span(text, "coefficients.load_compliance")
    lines = dict(line.split(" = ", 1) for line in text[start:end].splitlines())
    key, _, value = edit.partition("=")
    if value:
        lines[key] = value
    else:
        lines.pop(key)
    body = "\n".join(f"{k} = {v}" for k, v in lines.items())
    return text[:start] + body + text[end:]


#: edits of the load compliance's table: case | edit (key=value, or key to take it out) | the
#: message's key below coefficients.load_compliance | words the message holds
EDITS = """
no value           | value            | .value      | missing
NaN value          | value=nan        | .value      | finite
infinite value     | value=inf        | .value      | finite
text value         | value="2e-10"    | .value      | finite
infinite std_error | std_error=inf    | .std_error  | finite
negative std_error | std_error=-1e-13 | .std_error  | negative
no std_error       | std_error        | .std_error  | missing
wrong unit         | unit="mm/N"      | .unit       | 'm/N'
no unit            | unit             | .unit       | no unit
no experiment      | experiment       | .experiment | missing
unknown key        | colour=1         |             | colour
"""
BAD = {
    case: (_bad(edit), f"coefficients.load_compliance{key}", words)
    for case, edit, key, words in (
        [field.strip() for field in line.split("|")] for line in EDITS.strip().splitlines()
    )
}
UNKNOWN = '\n[coefficients.creep]\nvalue = 1.0\nstd_error = 0.1\nunit = "1"\nexperiment = "x"\n'
BAD |= {
    "missing coefficient": (_without("coefficients.load_compliance"), "coefficients", "load_compliance"),
    "unknown coefficient": (_file_text() + UNKNOWN, "coefficients", "creep"),
    "not TOML": ("[coefficients\n", "", "TOML syntax error"),
    "bad fit": (_file_text().replace("rank = ", "rank = 1.5 #", 1), "fit.", "integer"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_a_bad_coefficients_file_is_one_line_of_bad_input(case: str, tmp_path: Path) -> None:
    text, key, words = BAD[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_coefficients(path)
    message = str(err.value)
    assert len(message.splitlines()) == 1, message
    assert str(path) in message and key in message and words in message, message


def test_the_bad_cases_differ_from_the_good_file_only_where_they_say() -> None:
    # the helper really edits the table (so each case tests what its name says)
    good = tomllib.loads(_file_text())["coefficients"]["load_compliance"]
    bad = tomllib.loads(_bad('unit="mm/N"'))["coefficients"]["load_compliance"]
    assert {k: v for k, v in bad.items() if k != "unit"} == {k: v for k, v in good.items() if k != "unit"}
    parse_coefficients(tomllib.loads(_file_text()), "good")  # and the good file passes
    shorter = tomllib.loads(_without("coefficients.load_compliance"))
    assert set(shorter["coefficients"]) == set(coefficient_units()) - {"load_compliance"}


def test_a_scenario_naming_a_bad_file_fails_validation_with_one_line(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(BAD["wrong unit"][0])
    scenario = str(scenarios_dir() / "constant-load.toml")
    assert main(["validate", scenario, "--set", f'errormodel.coefficients="{bad}"']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "coefficients.load_compliance.unit" in err[0]
    assert main(["validate", scenario, "--set", f'errormodel.coefficients="{tmp_path / "none.toml"}"']) == 2
    assert "file not found" in capsys.readouterr().err
