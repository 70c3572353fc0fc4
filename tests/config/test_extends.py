"""The one merge rule of ``extends`` (docs/scenario-files.md): tables merge key by key whatever
their keys, an input's profile of another kind replaces the base's, arrays of tables extend the
base's with ``remove = true`` to take one out, everything else is replaced. And every shipped
scenario keeps its base's value of every parameter, input and connection it does not set."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.cli import main
from twin.config.load import load_scenario, read_scenario_data, scenarios_dir
from twin.config.reader import read_toml
from twin.errors import ConfigError

BASE = """
[scenario]
name = "base"
duration = "10 min"
step = "1 s"
output_interval = "1 s"

[fmu.hydraulic]
model = "HydraulicLoader"
period = "1 s"
unconnected = { fault_inject = "no fault injected" }
[fmu.hydraulic.parameters]
profile = { value = 0, source = "constant load" }
load_mean = { value = 100e3, source = "test" }
piston_area = { value = 0.008, source = "test" }

[input.hydraulic.station_on]
profile = "constant"
value = 1.0

[input.hydraulic.load_offset]
profile = "sine"
mean = 0.0
amplitude = 10.0
period = "1 min"

[[event]]
at = "1 min"
action = "bias"
target = "hydraulic.radial_load"
value = 5.0

[[event]]
at = "2 min"
action = "bias"
target = "hydraulic.radial_load"
value = 7.0
"""


def _files(tmp_path: Path, over: str) -> Path:
    (tmp_path / "base.toml").write_text(BASE, encoding="utf-8")
    path = tmp_path / "over.toml"
    path.write_text('extends = "base.toml"\n' + over, encoding="utf-8")
    return path


def test_a_parameter_named_profile_does_not_replace_its_table(tmp_path: Path) -> None:
    # the bug: a table holding a key named "profile" was taken for an input's profile and
    # replaced whole, so a sine load lost the base's piston area
    data = read_scenario_data(_files(tmp_path, "[fmu.hydraulic.parameters]\nprofile = { value = 1 }\n"))
    params = data["fmu"]["hydraulic"]["parameters"]
    assert params["profile"] == {"value": 1}  # a parameter is one value: not the base's source
    assert params["piston_area"] == {"value": 0.008, "source": "test"}
    assert params["load_mean"] == {"value": 100e3, "source": "test"}


def test_an_input_profile_of_another_kind_replaces_the_bases(tmp_path: Path) -> None:
    over = '[input.hydraulic.station_on]\nprofile = "table"\npoints = [[0.0, 1.0], [60.0, 0.0]]\n'
    data = read_scenario_data(_files(tmp_path, over))
    assert data["input"]["hydraulic"]["station_on"] == {
        "profile": "table",
        "points": [[0.0, 1.0], [60.0, 0.0]],
    }


def test_an_input_profile_of_the_same_kind_merges_key_by_key(tmp_path: Path) -> None:
    data = read_scenario_data(_files(tmp_path, "[input.hydraulic.load_offset]\namplitude = 20.0\n"))
    assert data["input"]["hydraulic"]["load_offset"] == {
        "profile": "sine", "mean": 0.0, "amplitude": 20.0, "period": "1 min"
    }  # fmt: skip
    load_scenario(tmp_path / "over.toml")  # and the result is a valid scenario


def test_arrays_of_tables_extend_the_bases(tmp_path: Path) -> None:
    over = '[[event]]\nat = "3 min"\naction = "bias"\ntarget = "hydraulic.radial_load"\nvalue = 9.0\n'
    sc = load_scenario(_files(tmp_path, over))
    assert [e.value for e in sc.events] == [5.0, 7.0, 9.0]


def test_remove_takes_out_the_bases_entries_it_names(tmp_path: Path) -> None:
    over = '[[event]]\nremove = true\nat = "1 min"\n'
    sc = load_scenario(_files(tmp_path, over))
    assert [e.value for e in sc.events] == [7.0]


def test_remove_that_names_nothing_is_an_error_naming_the_entry(tmp_path: Path, capsys) -> None:
    path = _files(tmp_path, '[[event]]\nremove = true\nat = "9 min"\n')
    with pytest.raises(
        ConfigError, match=r"removes nothing: no event of the file it extends has at = '9 min'"
    ):
        read_scenario_data(path)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "over.toml: event[0]: removes nothing" in err[0], err


def test_a_connection_is_removed_by_giving_its_output_no_input(tmp_path: Path) -> None:
    base = scenarios_dir() / "base" / "tester-system.toml"
    path = tmp_path / "s.toml"
    path.write_text(f'extends = "{base}"\n[connections]\n"thermal.t_sensor" = []\n', encoding="utf-8")
    sc = load_scenario(
        path,
        [
            'fmu.sensors.unconnected.t_probe_body="the probe body at its start value"',
            'fmu.mechanics.unconnected.t_sensor="the probe body at its start value"',
        ],
    )
    assert not any(c.src == "thermal.t_sensor" for c in sc.connections)
    assert len(sc.connections) == len(load_scenario(base).connections) - 2  # the DAQ's and the mechanics'


def test_values_and_arrays_of_values_are_replaced(tmp_path: Path) -> None:
    data = read_scenario_data(_files(tmp_path, '[scenario]\nduration = "5 min"\n'))
    assert data["scenario"]["duration"] == "5 min" and data["scenario"]["step"] == "1 s"


def _extending(path: Path) -> list[tuple[Path, Path]]:
    """(file, the file it extends) for every shipped scenario that extends another."""
    data = read_toml(path, str(path))
    return [(path, (path.parent / data["extends"]).resolve())] if "extends" in data else []


SHIPPED = [p for folder in ("", "calibration") for p in sorted((scenarios_dir() / folder).glob("*.toml"))]
EXTENDING = [pair for p in SHIPPED for pair in _extending(p)]


@pytest.mark.parametrize("path, base", EXTENDING, ids=[p.stem for p, _ in EXTENDING])
def test_every_shipped_scenario_keeps_its_bases_values_where_it_sets_none(path: Path, base: Path) -> None:
    own = read_toml(path, str(path))
    sc, base_sc = load_scenario(path), load_scenario(base)
    own_fmus = own.get("fmu", {})
    base_fmus = {f.name: f for f in base_sc.fmus}
    checked = 0
    for f in sc.fmus:
        if f.name not in base_fmus:
            continue
        given = own_fmus.get(f.name, {})
        if "parameter_files" in given:
            continue  # the file names its own parameter files: every value may come from them
        set_here = set(given.get("parameters", {}))
        for name, parameter in base_fmus[f.name].parameters.items():
            if name not in set_here:
                assert f.parameters.get(name) == parameter, f"{path.name}: fmu.{f.name}.parameters.{name}"
                checked += 1
    own_inputs = {f"{fmu}.{var}" for fmu, table in own.get("input", {}).items() for var in table}
    profiles = {p.target: p for p in sc.profiles}
    for p in base_sc.profiles:
        if p.target not in own_inputs:
            assert profiles.get(p.target) == p, f"{path.name}: input.{p.target}"
            checked += 1
    own_outputs = set(own.get("connections", {}))
    for c in base_sc.connections:
        if c.src not in own_outputs:
            assert c in sc.connections, f"{path.name}: connection {c.src} -> {c.dst}"
            checked += 1
    assert checked > 0
