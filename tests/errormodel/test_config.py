"""The error model's [errormodel] table: the paper's eight measuring points, and a thermometer on
the probe's body where a tester has one (its drifts then read their own temperature)."""

from __future__ import annotations

import numpy as np
import pytest

from twin.errormodel.config import errormodel_config, model_defaults
from twin.errormodel.sources import EXTRA_TEMPERATURES, ThermalCoefficients, thermal_errors
from twin.errors import ConfigError


def test_a_probe_body_thermometer_is_a_measuring_point() -> None:
    cfg = errormodel_config(model_defaults(), {"temperatures": {"probe_body": "T_probe"}}, "lab.toml", 300.0)
    assert cfg.temperatures["probe_body"] == "T_probe" and len(cfg.temperatures) == 9
    assert EXTRA_TEMPERATURES["probe_body"] == "sensors.t_probe_body_meas"


def test_a_misspelt_point_is_refused_naming_the_known_ones() -> None:
    with pytest.raises(ConfigError, match="did you mean 'probe_body'"):
        errormodel_config(model_defaults(), {"temperatures": {"probe_bdy": "T"}}, "lab.toml", 300.0)


def test_the_probes_drifts_read_its_body_where_it_is_measured() -> None:
    # 1 um/K of zero drift: with the body's thermometer the drift follows the body (2 K), without
    # it the frame's bottom (5 K) stands in
    g = ThermalCoefficients.from_values(
        {n: 0.0 for n in ThermalCoefficients.units()} | {"probe_zero_drift": 1e-6}
    )
    rises = {p: np.array([0.0, 5.0]) for p in ("bearing_block", "heel_block", "bearing", "t_plate", "base",
                                               "long_pole", "detecting_frame", "room")}  # fmt: skip
    without = thermal_errors(rises, g)["displacement_sensor"]["p_dz"]
    with_body = thermal_errors({**rises, "probe_body": np.array([0.0, 2.0])}, g)["displacement_sensor"][
        "p_dz"
    ]
    assert without[-1] == pytest.approx(-5e-6) and with_body[-1] == pytest.approx(-2e-6)
