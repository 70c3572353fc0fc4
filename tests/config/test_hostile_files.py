"""Hostile and careless files (issue 13): special files, huge or deeply nested files, numbers no
float holds, long or cyclic ``extends`` chains, misspelt error-model columns. Each: exit 2, one
line naming the file (and the key where there is one), no traceback, nothing hangs."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.config.scenario_toml import paper_text
from twin.cli import main
from twin.config.problems import MAX_TOML_BYTES, MAX_TOML_DEPTH, read_toml
from twin.errors import ConfigError


@dataclass(frozen=True)
class Hostile:
    id: str
    word: str  # a distinctive word of the message
    make: Callable[[Path], Path]  # writes the files into the folder, returns the scenario to validate
    key: str | None = None
    file: str | None = None  # the file the line names, if not the one validated


def _scenario(d: Path, text: str, name: str = "s.toml") -> Path:
    p = d / name
    p.write_text(text, encoding="utf-8")
    return p


def _extends(target: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, f'extends = "{target}"\n')


def _fifo(d: Path) -> Path:
    os.mkfifo(d / "fifo.toml")
    return _scenario(d, 'extends = "fifo.toml"\n')


def _chain(n: int) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        for i in range(n):
            _scenario(d, f'extends = "c{i + 1}.toml"\n', f"c{i}.toml")
        _scenario(d, paper_text(), f"c{n}.toml")
        return d / "c0.toml"

    return make


def _cycle(d: Path) -> Path:
    _scenario(d, 'extends = "b.toml"\n', "a.toml")
    _scenario(d, 'extends = "c.toml"\n', "b.toml")
    _scenario(d, 'extends = "a.toml"\n', "c.toml")
    return d / "a.toml"


def _nested(kind: str, depth: int) -> Callable[[Path], Path]:
    if kind == "array":
        body = "x = " + "[" * depth + "]" * depth
    else:
        body = "x = " + "{ a = " * depth + "1" + " }" * depth
    return lambda d: _scenario(d, paper_text() + "\n" + body + "\n")


def _with(line: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, paper_text().replace("seed = 2017", line, 1))


def _thermal_parameter(value: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, paper_text() + f"\n[fmu.thermal.parameters]\nc_base = {value}\n")


def _errormodel(extra: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, paper_text().replace("[errormodel]\n", "[errormodel]\n" + extra + "\n", 1))


HOSTILE = [
    # special files: refused before anything is read from them
    Hostile("extends-dev-zero", "regular file", _extends("/dev/zero"), "extends"),
    Hostile("extends-dev-null", "regular file", _extends("/dev/null"), "extends"),
    Hostile("extends-dev-urandom", "regular file", _extends("/dev/urandom"), "extends"),
    Hostile("extends-fifo", "regular file", _fifo, "extends"),
    Hostile("extends-directory", "directory", _extends("."), "extends"),
    Hostile("extends-parent-directory", "directory", _extends(".."), "extends"),
    Hostile("extends-missing", "not found", _extends("nope.toml"), "extends"),
    Hostile("extends-proc-self-mem", "cannot read", _extends("/proc/self/mem"), "extends"),
    Hostile("extends-number", "file name", lambda d: _scenario(d, "extends = 5\n"), "extends"),
    Hostile("extends-list", "file name", lambda d: _scenario(d, 'extends = ["a.toml"]\n'), "extends"),
    # sizes
    Hostile(
        "huge-file",
        "bytes",
        lambda d: _scenario(d, paper_text() + "\n# " + "x" * (MAX_TOML_BYTES + 10) + "\n"),
    ),
    Hostile(
        "extends-huge-file",
        "bytes",
        lambda d: (
            _scenario(d, "# " + "x" * (MAX_TOML_BYTES + 10) + "\n", "big.toml"),
            _scenario(d, 'extends = "big.toml"\n'),
        )[1],
        "extends",
    ),
    # nesting
    Hostile("deep-array-5000", "nested", _nested("array", 5000)),
    Hostile("deep-array-40", "nested", _nested("array", MAX_TOML_DEPTH + 8)),
    Hostile("deep-inline-tables-2000", "nested", _nested("table", 2000)),
    Hostile("deep-inline-tables-40", "nested", _nested("table", MAX_TOML_DEPTH + 8)),
    # extends chains
    Hostile("extends-cycle-of-three", "circular", _cycle, "extends"),
    Hostile("extends-self", "circular", lambda d: _scenario(d, 'extends = "s.toml"\n'), "extends"),
    # the line names the file where the chain grew too long
    Hostile("extends-chain-of-40", "chain", _chain(40), "extends", file="c16.toml"),
    # numbers
    Hostile("int-beyond-64-bit", "64-bit", _with("seed = 99999999999999999999999"), "scenario.seed"),
    Hostile(
        "int-negative-beyond-64-bit", "64-bit", _with("seed = -99999999999999999999999"), "scenario.seed"
    ),
    Hostile("int-5000-digits", "digits", _with("seed = " + "9" * 5000)),
    Hostile(
        "int-beyond-float-as-parameter",
        "64-bit",
        _thermal_parameter("9" * 400),
    ),
    Hostile("float-inf-parameter", "finite", _thermal_parameter("inf")),
    Hostile("float-nan-parameter", "finite", _thermal_parameter("nan")),
    Hostile("float-overflow-parameter", "finite", _thermal_parameter("1e999")),
    # the error model's columns, checked against what the run records
    Hostile(
        "errormodel-misspelt-reading",
        "did you mean",
        _errormodel('reading = "sensors.probe_mea"'),
        "errormodel.reading",
    ),
    Hostile(
        "errormodel-misspelt-temperature",
        "not recorded",
        _errormodel('temperatures = { base = "sensors.t_bas_meas" }'),
        "errormodel.temperatures.base",
    ),
    Hostile(
        "errormodel-unknown-instance",
        "not recorded",
        _errormodel('true_wear = "wear.depth"'),
        "errormodel.true_wear",
    ),
    Hostile("errormodel-reading-number", "column", _errormodel("reading = 5"), "errormodel"),
]


def test_the_hostile_corpus_has_unique_ids() -> None:
    assert len({h.id for h in HOSTILE}) == len(HOSTILE) >= 30


@pytest.mark.parametrize("case", HOSTILE, ids=[h.id for h in HOSTILE])
def test_a_hostile_file_gets_one_line_and_exit_2(case: Hostile, tmp_path: Path, capsys) -> None:
    path = case.make(tmp_path)
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("twin: ") and (case.file or path.name) in lines[0], err
    if case.key:
        assert f"{case.key}: " in lines[0] or f"{case.key}." in lines[0], err
    assert case.word.lower() in lines[0].lower(), err


# ----------------------------------------------------------------------------- any bytes at all


_TOMLISH = st.lists(
    st.sampled_from(
        [
            "[",
            "]",
            "{",
            "}",
            "=",
            '"',
            "'",
            ",",
            "\n",
            "a",
            "x.y",
            " ",
            "1",
            "9" * 30,
            "1e999",
            "nan",
            "[[",
            "]]",
            "#",
        ]
    ),
    max_size=400,
).map("".join)


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(st.one_of(st.binary(max_size=2000), _TOMLISH.map(str.encode)))
def test_any_bytes_give_data_or_one_config_error(
    tmp_path_factory: pytest.TempPathFactory, data: bytes
) -> None:
    path = tmp_path_factory.mktemp("any") / "x.toml"
    path.write_bytes(data)
    try:
        out = read_toml(path, str(path))
    except ConfigError as exc:
        assert "\n" not in str(exc) and str(path) in str(exc)
        return
    assert isinstance(out, dict)
