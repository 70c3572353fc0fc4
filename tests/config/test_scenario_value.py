"""The scenario as a value: each method returns a checked copy, the original stays as it was,
and what the loader would refuse is refused with its key."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.config.profiles import profile_function
from twin.config.spec import Profile, Scenario
from twin.errors import ConfigError

PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"
SINE = scenarios_dir() / "sine-load.toml"


@pytest.fixture(scope="module")
def paper() -> Scenario:
    return load_scenario(PAPER)


def test_with_parameter_is_the_loaders_value_and_leaves_the_original(paper: Scenario) -> None:
    changed = paper.with_parameter("mechanics", "alpha_long_pole", 1.21e-5, source="a tester as built")
    assert changed.fmu("mechanics").parameters["alpha_long_pole"].value == 1.21e-5
    assert changed.fmu("mechanics").parameters["alpha_long_pole"].source == "a tester as built"
    assert paper.fmu("mechanics").parameters["alpha_long_pole"].value == 1.17e-5  # the drawing's, untouched
    loaded = load_scenario(PAPER, ["fmu.mechanics.parameters.alpha_long_pole=1.21e-5"])
    assert dict(loaded.fmu("mechanics").parameters)["alpha_long_pole"].value == 1.21e-5
    # the same parameters in the same order as the loader gives them (the order they are set)
    assert list(changed.fmu("mechanics").parameters) == list(loaded.fmu("mechanics").parameters)


@pytest.mark.parametrize(
    ("instance", "name", "value", "key", "words"),
    [
        (
            "mechanics",
            "alpha_long_pol",
            1e-5,
            "fmu.mechanics.parameters.alpha_long_pol",
            "did you mean 'alpha_long_pole'",
        ),
        (
            "mechanics",
            "alpha_long_pole",
            -1.0,
            "fmu.mechanics.parameters.alpha_long_pole",
            "outside the physical range",
        ),
        (
            "mechanics",
            "alpha_long_pole",
            "1e-5",
            "fmu.mechanics.parameters.alpha_long_pole",
            "expected a number",
        ),
        ("mechanics", "alpha_long_pole", float("nan"), "fmu.mechanics.parameters.alpha_long_pole", "finite"),
        ("mechanix", "alpha_long_pole", 1e-5, "fmu.mechanix", "unknown FMU instance"),
    ],
)
def test_with_parameter_refuses_what_the_loader_refuses(
    paper: Scenario, instance: str, name: str, value: object, key: str, words: str
) -> None:
    with pytest.raises(ConfigError) as err:
        paper.with_parameter(instance, name, value)
    assert err.value.key == key and words in err.value.message, err.value


def test_with_input_replaces_the_profile_and_checks_its_range(paper: Scenario) -> None:
    t = np.array([0.0, 14400.0, 28800.0])
    room = Profile.of_table("thermal.t_room", t, [293.15, 297.0, 302.05], "a lab's room")
    changed = paper.with_input(room)
    assert changed.profile("thermal.t_room") == room and len(changed.profiles) == len(paper.profiles)
    assert profile_function(changed.profile("thermal.t_room"))(np.array([14400.0]))[0] == 297.0
    with pytest.raises(ConfigError, match="outside the range"):
        paper.with_input(Profile.of_table("thermal.t_room", t, [293.15, 297.0, 1e9]))
    with pytest.raises(ConfigError, match="times increasing"):
        paper.with_input(Profile.of_table("thermal.t_room", [0.0, 0.0], [293.15, 294.0]))
    with pytest.raises(ConfigError, match="a time given twice is a jump"):
        paper.with_input(
            Profile.of_table("thermal.t_room", [0.0, 5.0, 5.0, 5.0], [293.0, 293.0, 294.0, 295.0])
        )
    jump = paper.with_input(
        Profile.of_table("thermal.t_room", [0.0, 5.0, 5.0, 9.0], [293.0, 293.0, 295.0, 295.0])
    )
    values = profile_function(jump.profile("thermal.t_room"))(np.array([2.5, 5.0, 7.0]))
    np.testing.assert_array_equal(values, [293.0, 295.0, 295.0])  # from the jump on: its later value
    with pytest.raises(ConfigError, match="fed by a connection") as err:
        paper.with_input(Profile("sensors.t_base", "constant", {"value": 293.0}))
    assert err.value.key == "input.sensors.t_base"


def test_with_value_takes_what_a_sweep_varies(paper: Scenario) -> None:
    changed = (
        paper.with_value("input.thermal.t_room.rise", 9.9)
        .with_value("input.thermal.t_room.time_constant", "2 h")
        .with_value("fmu.sensors.parameters.probe_zero_drift", 0.2e-6)
        .with_value("scenario.seed", 7)
    )
    room = changed.profile("thermal.t_room").params
    assert room["rise"] == 9.9 and room["time_constant"] == 7200.0  # a duration in seconds
    assert changed.fmu("sensors").parameters["probe_zero_drift"].value == 0.2e-6 and changed.seed == 7
    assert (
        changed.nominal("input.thermal.t_room.rise") == 9.9
        and paper.nominal("input.thermal.t_room.rise") == 8.9
    )
    for key, value, words in [
        ("input.thermal.t_room.rize", 1.0, "has no parameter 'rize'"),
        ("scenario.duration", "1 h", "a study varies"),
        ("scenario.seed", 2**31, "[0, 2^31)"),
        ("input.thermal.t_room.rise", float("inf"), "finite"),
    ]:
        with pytest.raises(ConfigError) as err:
            paper.with_value(key, value)
        assert words in err.value.message and err.value.key is not None, (key, err.value)


def test_a_changed_scenario_runs_as_the_same_change_written_in_its_file(tmp_path) -> None:
    """A copy made by the methods and the file with the same values are the same scenario."""
    from twin.outputs.run_folder import scenario_fingerprint

    by_method = load_scenario(SINE).with_parameter("hydraulic", "load_amplitude", 40e3).with_seed(11)
    by_text = load_scenario(SINE, ["fmu.hydraulic.parameters.load_amplitude=40e3", "scenario.seed=11"])
    assert scenario_fingerprint(by_method) == scenario_fingerprint(by_text)
    assert dataclasses.replace(by_method, source_path="") == dataclasses.replace(by_text, source_path="")
