"""The loader under random edits of a valid scenario's TEXT (issue 13): a line deleted, doubled
or swapped, a value replaced by another TOML value (NaN, inf, 1e999, an integer of hundreds of
digits, nesting, a date, a string where a number goes), stray TOML punctuation typed in.

Whatever the edit, ``twin validate`` either accepts the file (exit 0, "ok") or refuses it with
exit 2 and one line per problem, each ``twin: FILE: ...``; never a traceback, never another
exception from the loader. The dict-level properties are in tests/properties/; these reach the
TOML reader and its limits too.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from twin.cli import main
from twin.config.load import load_scenario
from twin.errors import ConfigError

from .scenario_toml import paper_text

SETTINGS = settings(
    max_examples=100,
    deadline=None,
    derandomize=True,  # the same examples on every run and in CI
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)

PAPER = paper_text()
LINES = PAPER.split("\n")
#: where a value starts: "key = value" lines (not comments, not headers)
VALUE_LINES = [i for i, ln in enumerate(LINES) if re.match(r"^\s*[\w\".-]+\s*=\s*\S", ln)]

#: TOML values that are wrong somewhere, or everywhere
VALUES = st.sampled_from(
    [
        "nan",
        "inf",
        "-inf",
        "1e999",
        "-1e999",
        "0",
        "-1",
        "1e30",
        "9" * 25,
        "-" + "9" * 400,
        "9" * 5000,
        "0.0",
        "true",
        '""',
        '"0 s"',
        '"-5 min"',
        '"1e30 s"',
        '"' + "1" * 5000 + ' s"',
        "[]",
        "{}",
        "[" * 40 + "]" * 40,
        "[" * 3000 + "]" * 3000,
        "{ a = " * 50 + "1" + " }" * 50,
        "1979-05-27",
        '"sensors.probe_mea"',
        '"/dev/zero"',
        '["/dev/zero"]',
        '"../../x"',
    ]
)
PUNCTUATION = st.text(alphabet="[]{}=\"',.#\n x1-", min_size=1, max_size=6)


@st.composite
def mutated(draw: st.DrawFn) -> str:
    """The paper's scenario text with one to three random edits."""
    lines = list(LINES)
    for _ in range(draw(st.integers(1, 3))):
        how = draw(st.sampled_from(["value", "value", "delete", "double", "swap", "type"]))
        event(how)
        if how == "value":
            i = draw(st.sampled_from(VALUE_LINES))
            if i < len(lines) and "=" in lines[i]:
                key = lines[i].split("=", 1)[0]
                lines[i] = f"{key}= {draw(VALUES)}"
        elif how == "delete":
            del lines[draw(st.integers(0, len(lines) - 1))]
        elif how == "double":
            i = draw(st.integers(0, len(lines) - 1))
            lines.insert(i, lines[i])
        elif how == "swap":
            i, j = draw(st.integers(0, len(lines) - 1)), draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        else:
            i = draw(st.integers(0, len(lines) - 1))
            k = draw(st.integers(0, len(lines[i])))
            lines[i] = lines[i][:k] + draw(PUNCTUATION) + lines[i][k:]
    return "\n".join(lines)


def _case_file(tmp_path_factory: pytest.TempPathFactory, text: str) -> Path:
    path = tmp_path_factory.mktemp("mut") / "mutated.toml"
    path.write_text(text, encoding="utf-8")
    return path


@SETTINGS
@given(text=mutated())
def test_validate_accepts_or_gives_one_line_per_problem(
    tmp_path_factory: pytest.TempPathFactory, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path = _case_file(tmp_path_factory, text)
    capsys.readouterr()
    code = main(["validate", str(path)])
    out, err = capsys.readouterr()
    assert "Traceback" not in err
    if code == 0:
        event("accepted")
        assert out.startswith(f"{path}: ok"), out
        return
    event("refused")
    assert code == 2, err
    lines = err.strip().split("\n")
    assert lines and lines != [""]
    for line in lines:
        # the scenario's name, or the file it names that cannot be read (a coefficients file)
        assert line.startswith("twin: "), line
        assert str(path) in line or "/dev/zero" in line or ".toml" in line, line


@SETTINGS
@given(text=mutated())
def test_the_loader_raises_nothing_but_config_errors(
    tmp_path_factory: pytest.TempPathFactory, text: str
) -> None:
    path = _case_file(tmp_path_factory, text)
    try:
        load_scenario(path)
    except ConfigError as exc:
        problems = getattr(exc, "problems", [exc])
        assert str(exc).split("\n") == [str(p) for p in problems]
    except Exception as exc:
        pytest.fail(f"{type(exc).__name__} instead of a ConfigError: {exc!r}"[:500])


def test_the_unmutated_text_loads(tmp_path: Path) -> None:
    """The base of the mutations is valid: each refusal comes from its edit."""
    path = tmp_path / "paper.toml"
    path.write_text(PAPER, encoding="utf-8")
    assert load_scenario(path).name == "li2017-thermal-experiment"
    assert len(VALUE_LINES) > 50
