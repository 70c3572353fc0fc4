"""The scenario loader's pieces: durations, --set overrides, and what the paper's file becomes."""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import pytest

from twin.config.load import (
    MAX_DURATION_NS,
    apply_overrides,
    default_scenario_path,
    format_duration,
    load_scenario,
    load_scenario_data,
    parse_duration,
)
from twin.config.overrides import split_key
from twin.config.spec import NS_PER_S, Connection
from twin.errors import ConfigError, ConfigErrors

from .scenario_toml import paper_data, write

# ----------------------------------------------------------------------------- parse_duration


@pytest.mark.parametrize(
    ("value", "ns"),
    [
        ("0.1 s", 100_000_000),
        (0.1, 100_000_000),
        ("480 min", 480 * 60 * NS_PER_S),
        ("8 h", 480 * 60 * NS_PER_S),
        ("1 d", 86_400 * NS_PER_S),
        ("366 d", MAX_DURATION_NS),
        (1, NS_PER_S),
        (0, 0),
        (2.5, 2_500_000_000),
        (28800, 28_800 * NS_PER_S),
        ("1 s", NS_PER_S),
        ("1.0 s", NS_PER_S),
        ("1. s", NS_PER_S),
        ("10s", 10 * NS_PER_S),
        ("  5 min  ", 300 * NS_PER_S),
        ("1e-3 s", 1_000_000),
        ("1.5E2 ms", 150_000_000),
        ("250 us", 250_000),
        ("0.3 ms", 300_000),
        ("7 ns", 7),
        ("0.001 us", 1),
        (1e-9, 1),
        (-1, -NS_PER_S),  # a number is just seconds; callers check the sign ("must be positive")
    ],
)
def test_parse_duration(value, ns: int) -> None:
    got = parse_duration(value)
    assert got == ns and type(got) is int


def test_parse_duration_is_exact_where_floats_are_not() -> None:
    assert 0.1 * 3 != 0.3
    assert 3 * parse_duration("0.1 s") == parse_duration("0.3 s") == parse_duration(0.3)
    assert parse_duration(0.7) == 700_000_000  # int(0.7 * 1e9) would be 699_999_999
    assert sum(parse_duration("0.1 s") for _ in range(36_000)) == parse_duration("1 h")


@pytest.mark.parametrize(
    ("value", "word"),
    [
        ("1 sec", "expected a duration like"),
        ("1 S", "expected a duration like"),
        ("-1 s", "expected a duration like"),
        ("+1 s", "expected a duration like"),
        ("1", "expected a duration like"),
        ("min", "expected a duration like"),
        ("", "expected a duration like"),
        ("one s", "expected a duration like"),
        (".5 s", "expected a duration like"),
        ("1.2.3 s", "expected a duration like"),
        ("1 h 30 min", "expected a duration like"),
        ("0.5 ns", "whole number of nanoseconds"),
        ("1e-10 s", "whole number of nanoseconds"),
        (1e-10, "whole number of nanoseconds"),
        (True, "expected a duration"),
        (None, "NoneType"),
        ([1, "s"], "list"),
        ({"min": 480}, "dict"),
        (math.inf, "finite"),
        (math.nan, "finite"),
    ],
)
def test_parse_duration_rejects(value, word: str) -> None:
    with pytest.raises(ValueError, match=word):
        parse_duration(value)


# ----------------------------------------------------------------------------- format_duration


@pytest.mark.parametrize(
    ("ns", "text"),
    [
        (480 * 60 * NS_PER_S, "8 h"),
        (90 * NS_PER_S, "90 s"),
        (30 * 60 * NS_PER_S, "30 min"),
        (2 * 86_400 * NS_PER_S, "2 d"),
        (100_000_000, "100 ms"),
        (1_500_000, "1500 us"),
        (1_500, "1500 ns"),
        (7, "7 ns"),
        (0, "0 s"),
        (28_800_500_000_000, "28800500 ms"),
    ],
)
def test_format_duration(ns: int, text: str) -> None:
    assert format_duration(ns) == text


@pytest.mark.parametrize(
    "ns", [1, 999, 1_000, 123_456_789, NS_PER_S, 61 * NS_PER_S, MAX_DURATION_NS, 10**18 + 7]
)
def test_format_duration_round_trips(ns: int) -> None:
    assert parse_duration(format_duration(ns)) == ns


# ----------------------------------------------------------------------------- --set


@pytest.mark.parametrize(
    ("key", "parts"),
    [
        ("scenario.seed", ["scenario", "seed"]),
        ("seed", ["seed"]),
        ('connections."thermal.t_clamp"', ["connections", "thermal.t_clamp"]),
        ('input."thermal".t_room.rise', ["input", "thermal", "t_room", "rise"]),
        ('input.thermal."t_room"', ["input", "thermal", "t_room"]),
        ('"scenario"."seed"', ["scenario", "seed"]),
        ('a"b.c"d', ["ab.cd"]),  # quotes may sit inside a part; they only protect the dots
    ],
)
def testsplit_key(key: str, parts: list[str]) -> None:
    assert split_key(key) == parts


@pytest.mark.parametrize("key", ['connections."thermal.t_clamp', "a..b", ".a", "a.", "", '""', 'a.""'])
def test_split_key_rejects(key: str) -> None:
    with pytest.raises(ConfigError, match="malformed key") as info:
        split_key(key)
    assert info.value.source == "--set"


def test_overrides_read_values_as_toml_else_as_text() -> None:
    data = paper_data()
    apply_overrides(
        data,
        [
            "scenario.seed=7",
            "scenario.duration=30 min",  # not TOML: the plain text
            'scenario.step="0.5 s"',
            "scenario.description=a=b",  # only the first '=' splits
            " scenario.output_interval = 20",
            "fmu.thermal.parameters.start_at_room=true",
            "fmu.thermal.parameter_files=[]",
            'fmu.mechanics.parameters.l_clamp={ value = 0.05, source = "drawing" }',
        ],
    )
    sc = data["scenario"]
    assert (sc["seed"], sc["duration"], sc["step"], sc["description"]) == (7, "30 min", "0.5 s", "a=b")
    assert sc["output_interval"] == 20
    assert data["fmu"]["thermal"]["parameters"]["start_at_room"] is True
    assert data["fmu"]["thermal"]["parameter_files"] == []
    assert data["fmu"]["mechanics"]["parameters"]["l_clamp"] == {"value": 0.05, "source": "drawing"}


def test_overrides_with_quoted_dotted_keys() -> None:
    data = paper_data()
    apply_overrides(
        data,
        [
            'connections."thermal.t_clamp"=["mechanics.t_clamp", "sensors.t_base"]',
            'input."thermal".t_room.rise=9.5',
            'input.thermal."q_hydraulic".value=250',
        ],
    )
    assert data["connections"]["thermal.t_clamp"] == ["mechanics.t_clamp", "sensors.t_base"]
    assert data["input"]["thermal"]["t_room"]["rise"] == 9.5
    assert data["input"]["thermal"]["q_hydraulic"]["value"] == 250


def test_overrides_create_missing_tables() -> None:
    data = paper_data()
    data.pop("errormodel", None)
    apply_overrides(data, ["input.mechanics.t_x.profile=constant", "errormodel.reading=sensors.probe_meas"])
    assert data["input"]["mechanics"]["t_x"] == {"profile": "constant"}
    assert data["errormodel"] == {"reading": "sensors.probe_meas"}


def test_bad_overrides_are_all_reported() -> None:
    data = paper_data()
    with pytest.raises(ConfigErrors) as info:
        apply_overrides(data, ["scenario.seed", "scenario.step.x=1", 'a."b=1', "scenario.seed=3"])
    lines = str(info.value).splitlines()
    assert len(lines) == 3 and all(ln.startswith("--set: ") for ln in lines)
    assert "KEY=VALUE" in lines[0] and "'step' is not a table" in lines[1] and "malformed" in lines[2]
    assert info.value.problems[1].key == "scenario.step.x"
    assert data["scenario"]["seed"] == 3  # the good ones still applied (nothing runs anyway)


def test_one_bad_override_is_a_plain_config_error() -> None:
    with pytest.raises(ConfigError) as info:
        apply_overrides(paper_data(), ["nothing"], source="s.toml: --set")
    assert not isinstance(info.value, ConfigErrors)
    assert str(info.value) == "s.toml: --set: expected KEY=VALUE, got 'nothing'"


def test_load_scenario_names_the_file_in_override_problems(tmp_path: Path) -> None:
    path = write(tmp_path / "s.toml", paper_data())
    with pytest.raises(ConfigError, match=r"^.*s\.toml: --set: expected KEY=VALUE"):
        load_scenario(path, ["nothing"])


# ----------------------------------------------------------------------------- the paper's scenario


@pytest.fixture(scope="module")
def paper():
    return load_scenario(default_scenario_path())


@pytest.fixture(scope="module")
def raw() -> dict:
    return tomllib.loads(default_scenario_path().read_text(encoding="utf-8"))


def test_paper_scenario_times(paper) -> None:
    assert paper.name == "li2017-thermal-experiment"
    assert paper.duration_ns == 480 * 60 * NS_PER_S
    assert paper.step_ns == NS_PER_S
    assert paper.output_interval_ns == 10 * NS_PER_S
    assert paper.drift_window_ns == 5 * 60 * NS_PER_S
    assert paper.seed == 2017
    assert paper.source_path == str(default_scenario_path())
    assert paper.events == ()


def test_paper_fmus(paper, raw) -> None:
    assert [f.name for f in paper.fmus] == list(raw["fmu"])
    for f in paper.fmus:
        assert f.model == raw["fmu"][f.name]["model"]
        assert f.period_ns == parse_duration(raw["fmu"][f.name]["period"])
    thermal = paper.fmu("thermal")
    # the drawing's values, then the calibration's over them (later files win)
    merged: dict = {}
    for f in raw["fmu"]["thermal"]["parameter_files"]:
        merged.update(tomllib.loads((default_scenario_path().parent / f).read_text())["parameters"])
    # and the scenario's own (inline: the solver's step at the period)
    for name, p in raw["fmu"]["thermal"].get("parameters", {}).items():
        merged[name] = p
    assert set(thermal.parameters) == set(merged)
    assert thermal.parameters["solver_step"].value * 1e9 == thermal.period_ns
    for name, p in thermal.parameters.items():
        assert p.value == merged[name]["value"]
        assert p.source == merged[name]["source"]
    mech = {k: p.value for k, p in paper.fmu("mechanics").parameters.items()}
    assert mech["solver_step"] == 1.0 and mech["l_detecting_frame"] == 0.362  # inline, and the drawing's


def test_paper_connections_are_what_the_file_says(paper, raw) -> None:
    expected = []
    for src, dsts in raw["connections"].items():
        for dst in [dsts] if isinstance(dsts, str) else dsts:
            expected.append(Connection(src, dst))
    assert list(paper.connections) == expected
    assert len(expected) == 24  # the bearing block: two halves to the mechanics, its cap to the DAQ
    assert Connection("thermal.t_pole_lower", "sensors.t_long_pole") in paper.connections
    assert Connection("mechanics.probe_true", "sensors.probe_true") in paper.connections
    assert not any(c.delay for c in paper.connections)


def test_paper_profiles_are_what_the_file_says(paper, raw) -> None:
    files = {f"{inst}.{var}": t for inst, per_var in raw["input"].items() for var, t in per_var.items()}
    by_target = {p.target: p for p in paper.profiles}
    assert set(by_target) == set(files)
    for target, t in files.items():
        p = by_target[target]
        assert p.kind == t["profile"]
        assert p.source == t["source"]
        assert p.table == ()
    room = by_target["thermal.t_room"]
    assert dict(room.params) == {"start": 293.15, "rise": 8.9, "time_constant": 7200.0, "rise_at": 28800.0}
    assert dict(by_target["thermal.q_hydraulic"].params) == {"value": 300.0}
    for target in ("thermal.q_friction", "mechanics.radial_load", "mechanics.angle"):
        assert dict(by_target[target].params) == {"value": 0.0}


def test_scenario_is_frozen(paper) -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        paper.seed = 1  # type: ignore[misc]
    with pytest.raises(TypeError):
        paper.fmu("thermal").parameters["c_base"] = 1  # type: ignore[index]
    with pytest.raises(TypeError):
        paper.profiles[0].params["start"] = 0.0  # type: ignore[index]
    with pytest.raises(TypeError):
        paper.errormodel["reading"] = "x"  # type: ignore[index]


def test_overrides_reach_the_scenario() -> None:
    s = load_scenario(
        default_scenario_path(),
        [
            "scenario.seed=7",
            'scenario.duration="30 min"',
            'connections."thermal.t_clamp"=[]',
            'fmu.mechanics.unconnected.t_clamp="test: the clamp at its start temperature"',
        ],
    )
    assert s.seed == 7 and s.duration_ns == 30 * 60 * NS_PER_S
    assert not any(c.src == "thermal.t_clamp" for c in s.connections)
    assert len(s.connections) == 23


def test_a_transformed_connection_feeds_its_input() -> None:
    """An input fed by a ``{ to, factor, offset }`` connection is connected; without it, it is named."""
    base = default_scenario_path()
    s = load_scenario(
        base, ['connections."thermal.t_clamp"={ to = "mechanics.t_clamp", factor = 1.0, offset = 0.5 }']
    )
    (c,) = [c for c in s.connections if c.src == "thermal.t_clamp"]
    assert (c.dst, c.factor, c.offset) == ("mechanics.t_clamp", 1.0, 0.5)
    with pytest.raises(ConfigErrors, match=r"fmu\.mechanics.*input 't_clamp'.*is not connected"):
        load_scenario(base, ['connections."thermal.t_clamp"=[]'])


# ----------------------------------------------------------------------------- more of the loader


def _load(data: dict, tmp_path: Path):
    return load_scenario(write(tmp_path / "s.toml", data))


def test_delayed_loop_becomes_a_delayed_connection(tmp_path: Path) -> None:
    data = paper_data()
    del data["input"]["thermal"]["t_room"]
    data["delay"] = [{"from": "sensors.t_room_meas", "to": "thermal.t_room", "initial": 293.15}]
    s = _load(data, tmp_path)
    assert s.connections[-1] == Connection(
        "sensors.t_room_meas", "thermal.t_room", delay=True, initial=293.15
    )


def test_events_profiles_and_parameters(tmp_path: Path) -> None:
    data = paper_data()
    data["event"] = [
        {"at": "2 h", "action": "bias", "target": "sensors.probe_meas", "value": 1e-6},
        {
            "at": "1 h",
            "action": "ramp",
            "target": "thermal.q_hydraulic",
            "value": 500.0,
            "duration": "10 min",
        },
    ]
    data["input"]["thermal"]["q_friction"] = {
        "profile": "table",
        "points": [[0, 0.0], ["1 h", 5.0], [7200, 5.0]],
    }
    data["input"]["mechanics"]["angle"] = {
        "profile": "sine",
        "mean": 0.0,
        "amplitude": 0.3,
        "period": "1 min",
    }
    data["fmu"]["thermal"]["parameters"] = {
        "start_at_room": False,
        "c_base": {"value": 5e4, "source": "estimate"},
    }
    data["fmu"]["sensors"]["parameters"] = {"seed": 11}
    s = _load(data, tmp_path)
    assert [(e.at_ns, e.action, e.duration_ns) for e in s.events] == [
        (3600 * NS_PER_S, "ramp", 600 * NS_PER_S),
        (7200 * NS_PER_S, "bias", 0),
    ]
    friction = next(p for p in s.profiles if p.target == "thermal.q_friction")
    assert friction.table == ((0.0, 0.0), (3600.0, 5.0), (7200.0, 5.0))
    angle = next(p for p in s.profiles if p.target == "mechanics.angle")
    assert dict(angle.params) == {"mean": 0.0, "amplitude": 0.3, "period": 60.0}
    thermal = s.fmu("thermal").parameters
    assert thermal["start_at_room"].value is False
    assert (thermal["c_base"].value, thermal["c_base"].source) == (5e4, "estimate")
    assert "c_bearing_block" in thermal  # the parameter file still applies
    seed = s.fmu("sensors").parameters["seed"].value
    assert seed == 11 and type(seed) is int


def test_scenario_parameters_override_the_parameter_file(tmp_path: Path) -> None:
    data = paper_data()
    data["fmu"]["thermal"]["parameters"] = {"c_bearing_block": 1234.0}
    p = _load(data, tmp_path).fmu("thermal").parameters["c_bearing_block"]
    assert (p.value, p.source) == (1234.0, "")


def test_problems_carry_source_and_key(tmp_path: Path) -> None:
    data = paper_data()
    data["scenario"]["step"] = "0 s"
    data["connections"]["thermal.t_oil"] = "mechanics.t_clamp"
    with pytest.raises(ConfigErrors) as info:
        load_scenario_data(data, "here.toml", tmp_path)
    assert [(e.source, e.key) for e in info.value.problems] == [
        ("here.toml", "scenario.step"),
        ("here.toml", 'connections."thermal.t_oil"'),
    ]
    assert isinstance(info.value, ValueError)  # callers that only know ValueError still catch it
    assert info.value.exit_code == 2


def test_a_broken_instance_is_reported_once(tmp_path: Path) -> None:
    """Connections, profiles and events naming an unusable FMU do not repeat its problem."""
    data = paper_data()
    data["fmu"]["thermal"]["period"] = "ten seconds"
    data["event"] = [{"at": "1 h", "action": "set", "target": "thermal.q_hydraulic", "value": 1.0}]
    with pytest.raises(ConfigError) as info:
        load_scenario_data(data, "s.toml", tmp_path)
    assert str(info.value).count("\n") == 0
    assert "fmu.thermal.period" in str(info.value)
