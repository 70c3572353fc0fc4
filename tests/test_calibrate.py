"""`twin calibrate` reproduces the committed calibration of the thermal network."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from twin.calibrate import BODIES, calibrate_file
from twin.config.load import default_scenario_path, load_scenario
from twin.reference import TEMPERATURE_RISE_K

pytestmark = pytest.mark.slow


def test_calibration_reproduces_the_committed_parameter_file(tmp_path: Path) -> None:
    committed = default_scenario_path().parent / "calibration" / "li2017-thermal-network.toml"
    out = calibrate_file(default_scenario_path(), tmp_path / "cal.toml")
    new = tomllib.loads(out.read_text())["parameters"]
    old = tomllib.loads(committed.read_text())["parameters"]
    assert new.keys() == old.keys()
    for k in new:
        assert new[k]["value"] == pytest.approx(old[k]["value"], rel=1e-6), k
        assert new[k]["source"].startswith("calibrated:")
    # the fit meets the measured rises it was fitted to (the room is the scenario's input)
    header = out.read_text().splitlines()[2]
    for body in BODIES:
        assert f"{body} " in header
    assert set(BODIES) | {"room"} == set(TEMPERATURE_RISE_K)


def test_the_scenario_uses_the_calibrated_values() -> None:
    sc = load_scenario(default_scenario_path())
    params = sc.fmu("thermal").parameters
    assert params["c_spindle"].value != 4700.0  # the estimate was replaced
    assert "calibrated" in params["c_spindle"].source
