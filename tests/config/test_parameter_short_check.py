"""A drawn parameter value takes a short check in Scenario.with_parameters: every value
gives what the full check (twin.config.checks.parameter_value) gives, the value or its error."""

from __future__ import annotations

import math

import numpy as np
import pytest

from twin.config.checks import parameter_value
from twin.config.load import load_scenario, scenarios_dir
from twin.errors import ConfigError
from twin.fmu.catalog import variables

PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"

#: alpha_heel_block is a Real in [0, 1e-4]; reference_at_start a Boolean; seed an Integer
CASES = [
    ("alpha_heel_block", 1.2e-5),
    ("alpha_heel_block", 0.0),  # the range's ends are in it
    ("alpha_heel_block", 1e-4),
    ("alpha_heel_block", -0.0),
    ("alpha_heel_block", 1e-4 * (1 + 1e-15)),  # just outside
    ("alpha_heel_block", -1e-300),
    ("alpha_heel_block", math.nan),
    ("alpha_heel_block", math.inf),
    ("alpha_heel_block", -math.inf),
    ("alpha_heel_block", 0),  # an int: converted to a float
    ("alpha_heel_block", True),  # a bool is not a number here
    ("alpha_heel_block", np.float64(2e-5)),  # a float's subclass: the full check
    ("alpha_heel_block", "1e-5"),
    ("reference_at_start", 1.0),  # a float for a Boolean
    ("reference_at_start", True),
    ("no_such_parameter", 1.0),
]


@pytest.mark.parametrize(("name", "raw"), CASES)
def test_with_parameters_gives_what_the_full_check_gives(name: str, raw: object) -> None:
    scenario = load_scenario(PAPER)
    model = scenario.fmu("mechanics").model
    expected, why = parameter_value(model, name, raw, variables(model))
    if why is not None:
        with pytest.raises(ConfigError) as caught:
            scenario.with_parameters("mechanics", {name: raw})
        assert caught.value.message == why
        assert caught.value.key == f"fmu.mechanics.parameters.{name}"
        return
    got = scenario.with_parameters("mechanics", {name: raw}, source="drawn").fmu("mechanics").parameters[name]
    assert type(got.value) is type(expected)
    assert repr(got.value) == repr(expected)  # the same float to the bit (and -0.0 stays -0.0)
    assert got.source == "drawn"
