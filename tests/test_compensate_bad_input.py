"""`twin compensate` with careless and hostile files (issue 13): one line and exit 2 for a file
or a setting it cannot use; rows it cannot use are left out, flagged, and the rest computed."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.errormodel.sources import DEFAULT_TEMPERATURES

POINTS = list(DEFAULT_TEMPERATURES)
GOOD_TOML = (
    '[errormodel]\nreading = "probe"\nfactors = ["thermal"]\ntemperatures = { '
    + ", ".join(f'{p} = "T{i}"' for i, p in enumerate(POINTS))
    + " }\n"
)


def lab_csv(n: int = 400, *, bad: dict[int, str] | None = None, newline_at_end: bool = True) -> str:
    t = np.arange(n) * 10.0
    rise = 5.0 * (1 - np.exp(-t / 1800.0))
    lines = ["time," + ",".join(f"T{i}" for i in range(8)) + ",probe"]
    for k in range(n):
        values = (
            [repr(float(t[k]))] + [repr(float(293.15 + rise[k]))] * 8 + [repr(float(4.8e-3 - 2e-6 * rise[k]))]
        )
        if bad and k in bad:
            col, text = bad[k].split("=", 1)
            values[int(col)] = text
        lines.append(",".join(values))
    return "\n".join(lines) + ("\n" if newline_at_end else "")


def _compensate(tmp_path: Path, csv: str | bytes | None, toml: str | None, out: str = "out") -> int:
    c = tmp_path / "lab.csv"
    if isinstance(csv, bytes):
        c.write_bytes(csv)
    elif csv is not None:
        c.write_text(csv)
    args = ["compensate", str(c), "--out", str(tmp_path / out)]
    if toml is not None:
        (tmp_path / "lab.toml").write_text(toml)
        args += ["--config", str(tmp_path / "lab.toml")]
    return main(args)


BAD: list[tuple[str, Callable[[], str | bytes | None], str | None, str]] = [
    # (id, the CSV, the config, a word of the one line)
    ("csv-missing", lambda: None, GOOD_TOML, "cannot read"),
    ("csv-empty", lambda: "", GOOD_TOML, "empty"),
    ("csv-header-only", lambda: "time,T0,probe\n", GOOD_TOML, "two samples"),
    ("csv-first-column-not-time", lambda: "t,a\n0,1\n1,2\n", GOOD_TOML, "time"),
    ("csv-duplicate-column", lambda: "time,a,a\n0,1,1\n1,2,2\n", GOOD_TOML, "twice"),
    (
        "csv-not-utf8",
        lambda: lab_csv(bad={5: "9=X"}).encode().replace(b"X", b"\xff\xfe"),
        GOOD_TOML,
        "cannot read",
    ),
    ("csv-header-not-utf8", lambda: b"time,\xff\n0,1\n1,2\n", GOOD_TOML, "cannot read"),
    ("csv-time-not-increasing", lambda: lab_csv(bad={5: "0=0.0"}), GOOD_TOML, "time"),
    ("csv-time-nan", lambda: lab_csv(bad={5: "0=nan"}), GOOD_TOML, "time"),
    ("csv-a-word", lambda: lab_csv(bad={5: "3=warm"}), GOOD_TOML, "not a number"),
    ("csv-short-row", lambda: lab_csv() + "1e9,1\n", GOOD_TOML, "values"),
    ("csv-missing-reading-column", lambda: lab_csv().replace(",probe", ",probe_mm", 1), GOOD_TOML, "probe"),
    ("toml-errormodel-number", lab_csv, "errormodel = 5\n", "expected a table"),
    ("toml-errormodel-string", lab_csv, 'errormodel = "x"\n', "expected a table"),
    ("toml-unknown-table", lab_csv, GOOD_TOML + "[extra]\na = 1\n", "unknown"),
    ("toml-drift-window-zero", lab_csv, GOOD_TOML + 'drift_window = "0 s"\n', "positive"),
    ("toml-drift-window-negative", lab_csv, GOOD_TOML + 'drift_window = "-5 min"\n', "drift_window"),
    ("toml-drift-window-word", lab_csv, GOOD_TOML + 'drift_window = "long"\n', "drift_window"),
    ("toml-factors-unknown", lab_csv, GOOD_TOML.replace('["thermal"]', '["heat"]'), "factors"),
    ("toml-reading-number", lab_csv, GOOD_TOML.replace('reading = "probe"', "reading = 5"), "column"),
    (
        "toml-temperatures-list",
        lab_csv,
        '[errormodel]\nreading = "probe"\ntemperatures = [1, 2]\n',
        "temperatures",
    ),
    ("toml-syntax", lab_csv, "[errormodel\n", "syntax"),
    ("toml-huge-int", lab_csv, GOOD_TOML + "factors2 = 99999999999999999999999\n", "64-bit"),
    ("toml-deep", lab_csv, "x = " + "[" * 3000 + "]" * 3000 + "\n", "nested"),
    ("toml-coefficients-unknown", lab_csv, GOOD_TOML + "coefficients = { no_such = 1.0 }\n", "no_such"),
    (
        "all-rows-nan",
        lambda: lab_csv(3, bad={0: "9=nan", 1: "9=nan", 2: "9=nan"}),
        GOOD_TOML,
        "fewer than two",
    ),
]


@pytest.mark.parametrize(("case", "csv", "toml", "word"), BAD, ids=[b[0] for b in BAD])
def test_a_bad_file_or_setting_gets_one_line_and_exit_2(
    case: str, csv: Callable[[], str | bytes | None], toml: str | None, word: str, tmp_path: Path, capsys
) -> None:
    assert _compensate(tmp_path, csv(), toml) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("twin: "), err
    assert word.lower() in lines[0].lower(), err
    assert not (tmp_path / "out" / "summary.json").exists()


def _summary(tmp_path: Path, out: str = "out") -> dict:
    return json.loads((tmp_path / out / "summary.json").read_text())


@pytest.mark.parametrize(
    "bad",
    ["9=nan", "9=inf", "3=-inf", "1=nan", "9="],
    ids=["probe-nan", "probe-inf", "temp-inf", "temp-nan", "probe-empty"],
)
def test_rows_the_model_cannot_use_are_flagged_and_the_rest_computed(
    bad: str, tmp_path: Path, capsys
) -> None:
    assert (
        _compensate(tmp_path / "a", lab_csv(), GOOD_TOML) == 0 if (tmp_path / "a").mkdir() is None else False
    )
    clean = _summary(tmp_path / "a")
    (tmp_path / "b").mkdir()
    if bad.endswith("="):
        bad = bad + ""  # an empty field: not a number, refused (one line) unless flagged below
    rows = {17: bad, 250: bad}
    code = _compensate(tmp_path / "b", lab_csv(bad=rows), GOOD_TOML)
    if bad.endswith("="):
        assert code == 2  # an empty field is a malformed file, not a sensor's value
        return
    assert code == 0
    err = capsys.readouterr().err
    assert "2 row(s)" in err and "t = 170 s" in err
    summary = _summary(tmp_path / "b")
    assert summary["input_rows"] == {"used": 398, "flagged": 2, "flagged_times_s": [170.0, 2500.0]}
    for key in ("predicted", "probe"):
        assert np.isfinite(summary["drift_mm"][key])
        assert summary["drift_mm"][key] == pytest.approx(clean["drift_mm"][key], abs=2e-5)


def test_a_last_row_without_its_line_break_counts(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert _compensate(tmp_path / "a", lab_csv(), GOOD_TOML) == 0
    assert _compensate(tmp_path / "b", lab_csv(newline_at_end=False), GOOD_TOML) == 0
    a = (tmp_path / "a" / "out" / "errormodel.csv").read_bytes()
    b = (tmp_path / "b" / "out" / "errormodel.csv").read_bytes()
    assert a == b and a.count(b"\n") == 401  # header + every one of the 400 rows
