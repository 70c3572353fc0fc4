"""Hostile and careless files (issue 13): special files, huge or deeply nested files, numbers no
float holds, long or cyclic ``extends`` chains, misspelt error-model columns. Each: exit 2, one
line naming the file (and the key where there is one), no traceback, nothing hangs."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.config.scenario_toml import paper_text
from twin.cli import main
from twin.config.reader import MAX_TOML_BYTES, MAX_TOML_DEPTH, read_toml
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
    # into the paper's own [fmu.thermal.parameters] (a second table of that name is a TOML error)
    table = "[fmu.thermal.parameters]\n"
    return lambda d: _scenario(d, paper_text().replace(table, f"{table}c_base = {value}\n", 1))


def _errormodel(extra: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, paper_text().replace("[errormodel]\n", "[errormodel]\n" + extra + "\n", 1))


def _with_uncertainty(line: str) -> Callable[[Path], Path]:
    return lambda d: _scenario(d, paper_text().replace("samples = 200", line, 1))


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


# ----------------------------------------------------------------------------- issue 13: more of each class


def _symlink_to(target: str | Callable[[Path], Path]) -> Callable[[Path], Path]:
    """A scenario extending a symlink to ``target`` (a path, or a maker of one in the folder)."""

    def make(d: Path) -> Path:
        dest = target(d) if callable(target) else Path(target)
        (d / "link.toml").symlink_to(dest)
        return _scenario(d, 'extends = "link.toml"\n')

    return make


def _fifo_path(d: Path) -> Path:
    os.mkfifo(d / "pipe")
    return d / "pipe"


def _big_path(d: Path) -> Path:
    p = d / "big.toml"
    with open(p, "wb") as f:
        f.truncate(MAX_TOML_BYTES + 1)  # sparse: refused by its size before anything is read
    return p


def _cycle_of_two(d: Path) -> Path:
    _scenario(d, 'extends = "b.toml"\n', "a.toml")
    _scenario(d, 'extends = "a.toml"\n', "b.toml")
    return d / "a.toml"


def _cycle_through_symlink(d: Path) -> Path:
    (d / "sub").mkdir()
    (d / "sub" / "back.toml").symlink_to(d / "a.toml")
    _scenario(d, 'extends = "sub/back.toml"\n', "a.toml")
    return d / "a.toml"


def _file_with(name: str, content: str | bytes) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        p = d / name
        p.write_bytes(content if isinstance(content, bytes) else content.encode())
        return p

    return make


def _without_thermal_files(text: str) -> str:
    import re

    return re.sub(r'parameter_files = \["[^\]]*li2017-thermal-network.toml"\]\n', "", text, count=1)


def _parameter_file(target: str | Callable[[Path], Path]) -> Callable[[Path], Path]:
    """The paper's scenario whose thermal instance reads one parameter file, ``target``."""

    def make(d: Path) -> Path:
        dest = target(d) if callable(target) else Path(target)
        text = _without_thermal_files(paper_text())
        text = text.replace(
            'model = "ThermalNetwork"', f'model = "ThermalNetwork"\nparameter_files = ["{dest}"]', 1
        )
        return _scenario(d, text)

    return make


def _identified_with(coefficient: str, key: str, new: str) -> str:
    """The committed coefficients file with one key of one coefficient given ``new`` (whatever
    value a rerun of `twin identify` left there)."""
    from twin.errormodel.coefficients import default_path

    text = default_path().read_text()
    line = re.compile(rf"(\[coefficients\.{coefficient}\]\n(?:[^\[\n].*\n)*?){key} = [^\n]*\n")
    changed, n = line.subn(rf"\g<1>{key} = {new}\n", text)
    assert n == 1, (coefficient, key)
    return changed


def _coefficients(target: str | Callable[[Path], Path]) -> Callable[[Path], Path]:
    def make(d: Path) -> Path:
        dest = target(d) if callable(target) else Path(target)
        return _scenario(
            d, paper_text().replace("[errormodel]\n", f'[errormodel]\ncoefficients = "{dest}"\n', 1)
        )

    return make


MORE_HOSTILE = [
    # special files behind a symlink: the reader opens what the link points at, then refuses it
    Hostile("extends-symlink-to-dev-zero", "regular file", _symlink_to("/dev/zero"), "extends"),
    Hostile("extends-symlink-to-fifo", "regular file", _symlink_to(_fifo_path), "extends"),
    Hostile("extends-symlink-to-directory", "directory", _symlink_to("/tmp"), "extends"),
    Hostile("extends-symlink-to-huge-file", "bytes", _symlink_to(_big_path), "extends"),
    Hostile("extends-dangling-symlink", "not found", _symlink_to("/nonexistent/x.toml"), "extends"),
    Hostile(
        "extends-sparse-huge-file", "bytes", lambda d: (_big_path(d), _extends("big.toml")(d))[1], "extends"
    ),
    Hostile("scenario-is-fifo", "regular file", lambda d: _fifo_path(d)),
    Hostile("scenario-is-dev-zero", "regular file", lambda d: Path("/dev/zero"), file="/dev/zero"),
    Hostile("scenario-is-sparse-huge", "bytes", _big_path),
    # extends cycles and chains
    Hostile("extends-cycle-of-two", "circular", _cycle_of_two, "extends"),
    Hostile("extends-cycle-through-symlink", "circular", _cycle_through_symlink, "extends"),
    Hostile("extends-chain-of-17", "chain", _chain(17), "extends", file="c16.toml"),
    Hostile("extends-empty-name", "directory", _extends(""), "extends"),
    Hostile("extends-table", "file name", lambda d: _scenario(d, "[extends]\na = 1\n"), "extends"),
    # nesting beyond any scenario's needs
    Hostile("deep-array-100000", "nested", _nested("array", 100_000)),
    Hostile("deep-inline-tables-10000", "nested", _nested("table", 10_000)),
    Hostile(
        "deep-mixed-arrays-and-tables",
        "nested",
        lambda d: _scenario(d, paper_text() + "\nx = " + "[{ a = " * 3000 + "1" + " }]" * 3000 + "\n"),
    ),
    Hostile(
        "deep-table-header",
        "nested",
        lambda d: _scenario(d, paper_text() + "\n[" + ".".join(["t"] * 5000) + "]\nx = 1\n"),
    ),
    Hostile(
        "deep-dotted-key",
        "nested",
        lambda d: _scenario(d, "x" + ".y" * 5000 + " = 1\n" + paper_text()),
    ),
    Hostile(
        "key-of-900-kB",
        "unknown key",
        lambda d: _scenario(d, "a" * 900_000 + " = 1\n" + paper_text()),
    ),
    # parameter files: the same reader, the same limits
    Hostile(
        "parameter-file-dev-zero", "regular file", _parameter_file("/dev/zero"), "fmu.thermal.parameter_files"
    ),
    Hostile(
        "parameter-file-fifo", "regular file", _parameter_file(_fifo_path), "fmu.thermal.parameter_files"
    ),
    Hostile("parameter-file-directory", "directory", _parameter_file("/tmp"), "fmu.thermal.parameter_files"),
    Hostile("parameter-file-huge", "bytes", _parameter_file(_big_path), "fmu.thermal.parameter_files"),
    Hostile(
        "parameter-file-deep",
        "nested",
        _parameter_file(_file_with("deep.toml", "[parameters]\nc_base = " + "[" * 3000 + "]" * 3000 + "\n")),
        "fmu.thermal.parameter_files",
    ),
    Hostile(
        "parameter-file-int-beyond-64-bit",
        "64-bit",
        _parameter_file(_file_with("int.toml", "[parameters]\nc_base = " + "9" * 30 + "\n")),
        "fmu.thermal.parameter_files",
    ),
    Hostile(
        "parameter-file-not-utf8",
        "UTF-8",
        _parameter_file(_file_with("latin1.toml", b"[parameters]\n# caf\xe9\n")),
        "fmu.thermal.parameter_files",
    ),
    Hostile(
        "parameter-file-syntax",
        "syntax",
        _parameter_file(_file_with("syntax.toml", "[parameters\nc_base = 1\n")),
        "fmu.thermal.parameter_files",
    ),
    Hostile(
        "parameter-file-value-out-of-range",
        "physical range",
        _parameter_file(_file_with("range.toml", "[parameters]\nc_base = -1.0\n")),
        "range.toml: parameters.c_base",
    ),
    Hostile(
        "parameter-file-value-nan",
        "finite",
        _parameter_file(_file_with("nan.toml", "[parameters]\ng_base_room = nan\n")),
        "nan.toml: parameters.g_base_room",
    ),
    # coefficients files of the error model
    Hostile("coefficients-dev-zero", "regular file", _coefficients("/dev/zero"), file="/dev/zero"),
    Hostile("coefficients-fifo", "regular file", _coefficients(_fifo_path), file="pipe"),
    Hostile("coefficients-directory", "directory", _coefficients("/tmp"), file="/tmp"),
    Hostile("coefficients-huge", "bytes", _coefficients(_big_path), file="big.toml"),
    # the file that names it and the key, as for extends (not only the missing file's path)
    Hostile(
        "coefficients-missing",
        "nope.toml: file not found",
        _coefficients("nope.toml"),
        "errormodel.coefficients",
    ),
    Hostile(
        "coefficients-deep",
        "nested",
        _coefficients(_file_with("deep.toml", "x = " + "[" * 5000 + "]" * 5000 + "\n")),
        file="deep.toml",
    ),
    # a value no tester has: it overflowed the error model, and the run ended on a plot
    # that could not be drawn (a hostile review); refused with its key instead
    Hostile(
        "coefficient-1e308",
        "beyond any tester",
        _coefficients(_file_with("k.toml", _identified_with("alpha_l_heel_block", "value", "1e308"))),
        "coefficients.alpha_l_heel_block.value",
        file="k.toml",
    ),
    Hostile(
        "coefficient-std-error-unit-slip",
        "beyond any tester",
        _coefficients(_file_with("k.toml", _identified_with("alpha_l_heel_block", "std_error", "0.33"))),
        "coefficients.alpha_l_heel_block.std_error",
        file="k.toml",
    ),
    # [uncertainty]: twin run checks it before the run, so twin validate does too
    Hostile(
        "uncertainty-negative-samples", "integer", _with_uncertainty("samples = -64"), "uncertainty.samples"
    ),
    Hostile("uncertainty-unknown-key", "unknown", _with_uncertainty("samplez = 64"), "uncertainty.samplez"),
    # a mistyped count filled the machine's memory before the first sample ran
    Hostile(
        "uncertainty-billion-samples",
        "100000",
        _with_uncertainty("samples = 1_000_000_000"),
        "uncertainty.samples",
    ),
]
HOSTILE += MORE_HOSTILE


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


def test_a_byte_order_mark_at_the_start_is_read_past(tmp_path: Path, capsys) -> None:
    """Notepad saves UTF-8 with a byte-order mark, which tomllib refuses ('Invalid statement
    at line 1, column 1'): the file reads as without it."""
    plain = _scenario(tmp_path, paper_text(), "plain.toml")
    marked = tmp_path / "marked.toml"
    marked.write_bytes(b"\xef\xbb\xbf" + plain.read_bytes())
    assert read_toml(marked, str(marked)) == read_toml(plain, str(plain))
    assert main(["validate", str(marked)]) == 0, capsys.readouterr().err
    # only at the start: elsewhere it is a character TOML does not allow there
    inside = tmp_path / "inside.toml"
    inside.write_bytes(plain.read_bytes() + b"\xef\xbb\xbf\n")
    with pytest.raises(ConfigError, match="TOML syntax error"):
        read_toml(inside, str(inside))


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


# ----------------------------------------------------------------------------- sweep files

_SWEEP_HEAD = '[sweep]\nbase = "{base}"\ndesign = "lhs"\nsamples = 8\nseed = 1\n'
_TILT = "fmu.mechanics.parameters.sensor_tilt"  # declared range [-0.2, 0.2] rad


def _problem(bounds: str, name: str = _TILT) -> str:
    return f'[problem]\nnames = ["{name}"]\nbounds = [{bounds}]\n'


SWEEPS = [
    # (id, base: None for the shipped sine-load scenario or a maker of another, body, key, word)
    ("base-dev-zero", "/dev/zero", _problem("[0.0, 0.01]"), "sweep.base", "regular file"),
    ("base-fifo", _fifo_path, _problem("[0.0, 0.01]"), "sweep.base", "regular file"),
    ("base-directory", "/tmp", _problem("[0.0, 0.01]"), "sweep.base", "directory"),
    ("base-huge", _big_path, _problem("[0.0, 0.01]"), "sweep.base", "bytes"),
    ("deep-nesting", None, "x = " + "[" * 5000 + "]" * 5000 + "\n", None, "nested"),
    ("bounds-int-beyond-64-bit", None, _problem("[0, " + "9" * 400 + "]"), "problem.bounds[0][1]", "64-bit"),
    ("bounds-nan", None, _problem("[0.0, nan]"), "problem.bounds[0]", "finite"),
    ("bounds-end-out-of-range", None, _problem("[-10.0, 10.0]"), _TILT, "physical range"),
    ("bounds-upper-out-of-range", None, _problem("[0.0, 0.3]"), _TILT, "physical range"),
    ("bounds-near-float-max", None, _problem("[1e308, 1.7e308]"), _TILT, "physical range"),
    (
        "spread-out-of-range",
        None,
        f'[spread]\n"{_TILT}" = {{ dist = "uniform", half_width = 1.0 }}\n',
        _TILT,
        "physical range",
    ),
    ("samples-int-beyond-64-bit", None, _problem("[0.0, 0.01]"), "sweep.samples", "64-bit"),
]


@pytest.mark.parametrize(("sid", "base", "body", "key", "word"), SWEEPS, ids=[s[0] for s in SWEEPS])
def test_a_hostile_sweep_file_gets_one_line(
    sid: str, base: str | Callable[[Path], Path] | None, body: str, key: str | None, word: str, tmp_path: Path
) -> None:
    """A sweep file is read by the same reader and its design checked at its ends before any point runs."""
    from tests.config.scenario_toml import PAPER
    from twin.sweep.spec import load_spec

    target = PAPER.parent / "sine-load.toml" if base is None else base(tmp_path) if callable(base) else base
    head = _SWEEP_HEAD.format(base=target)
    if sid == "samples-int-beyond-64-bit":
        head = head.replace("samples = 8", "samples = " + "9" * 30)
    path = tmp_path / "sweep.toml"
    path.write_text(head + body, encoding="utf-8")
    with pytest.raises(ConfigError) as exc:
        load_spec(path)
    lines = str(exc.value).split("\n")
    assert len(lines) == 1, str(exc.value)
    assert lines[0].startswith(f"{path}: "), lines[0]
    if key:
        assert f": {key}: " in lines[0] or f": {key} " in lines[0], lines[0]
    assert word.lower() in lines[0].lower(), lines[0]


def test_bytes_read_again_are_not_parsed_again_and_each_reader_gets_its_own_copy(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """read_toml keeps what it parsed by the bytes' SHA-256 (a sweep's client reads the same
    parameter files for every point): same bytes, one parse; changed bytes, a new one; and a
    reader that changes its data (as ``--set`` does) changes nobody else's."""
    import tomllib

    from twin.config import reader

    parses: list[str] = []
    real = tomllib.loads
    monkeypatch.setattr(reader.tomllib, "loads", lambda text: parses.append(text) or real(text))
    path = tmp_path / "parameters.toml"
    path.write_text('[parameters]\nL = 0.125\nname = "a"\n')
    first = read_toml(path, "first")
    first["parameters"]["L"] = 99.0  # a reader's own change
    second = read_toml(path, "second")
    assert second == {"parameters": {"L": 0.125, "name": "a"}} and len(parses) == 1
    path.write_text('[parameters]\nL = 0.25\nname = "a"\n')
    assert read_toml(path, "changed")["parameters"]["L"] == 0.25 and len(parses) == 2
    path.write_text("[parameters]\nL = \n")  # bad bytes: refused each time, never kept
    for _ in range(2):
        with pytest.raises(ConfigError, match="TOML syntax error"):
            read_toml(path, "broken")
    assert len(parses) == 4


def test_a_reader_of_parsed_bytes_shares_no_table_or_array_with_another(tmp_path: Path) -> None:
    """The copy a reader gets of cached data is new at every level a reader can change: tables
    in arrays of tables, arrays in arrays, inline tables; the scalars (immutable) may be shared."""
    import datetime

    text = (
        'when = 2017-03-01T08:00:00Z\nv = [1, [2.5, "x"]]\n'
        '[[profile]]\nat = "0 s"\nset = { load = 1.0 }\n[[profile]]\nat = "1 h"\n'
    )
    path = tmp_path / "profile.toml"
    path.write_text(text)
    first = read_toml(path, "first")
    expected = {
        "when": datetime.datetime(2017, 3, 1, 8, 0, tzinfo=datetime.UTC),
        "v": [1, [2.5, "x"]],
        "profile": [{"at": "0 s", "set": {"load": 1.0}}, {"at": "1 h"}],
    }
    assert first == expected
    first["v"][1].append(3)  # a reader's own changes, at every depth
    first["profile"][0]["set"]["load"] = 2.0
    first["profile"][1]["at"] = "2 h"
    first["profile"].append({})
    assert read_toml(path, "second") == expected
    # data a caller built (a sweep point's) may hold other types: those are deep-copied
    from twin.config.reader import toml_copy

    built = {"pair": ([1.0], "x")}
    copied = toml_copy(built)
    copied["pair"][0].append(2.0)
    assert built == {"pair": ([1.0], "x")}
