"""`twin compensate` with careless and hostile files (issue 13): one line and exit 2 for a file
or a setting it cannot use; rows it cannot use are left out, flagged (flagged_rows.csv), and the
rest computed with the numbers a clean file gives; a streamed file gives the numbers of the
whole record at once, across any chunk ends."""

from __future__ import annotations

import json
import warnings
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


def lab_csv(
    n: int = 400, *, bad: dict[int, str] | None = None, newline_at_end: bool = True, dt: float = 10.0
) -> str:
    t = np.arange(n) * dt
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


HEADER = "time," + ",".join(f"T{i}" for i in range(8)) + ",probe\n"


def _compensate(tmp_path: Path, csv: str | bytes | None, toml: str | None, out: str = "out") -> int:
    c = tmp_path / "lab.csv"
    if isinstance(csv, bytes):
        c.write_bytes(csv)
    elif csv == "<dir>":
        c.mkdir()
    elif csv is not None:
        c.write_text(csv)
    args = ["compensate", str(c), "--out", str(tmp_path / out)]
    if toml is not None:
        (tmp_path / "lab.toml").write_text(toml)
        args += ["--config", str(tmp_path / "lab.toml")]
    return main(args)


def _toml(**changes: str) -> str:
    """GOOD_TOML with lines added (key = value, as TOML text)."""
    return GOOD_TOML + "".join(f"{k} = {v}\n" for k, v in changes.items())


def _reading(value: str) -> str:
    """GOOD_TOML with ``reading`` set to ``value`` (TOML text)."""
    return GOOD_TOML.replace('reading = "probe"', f"reading = {value}")


BAD: list[tuple[str, Callable[[], str | bytes | None], str | None, str]] = [
    # (id, the CSV, the config, a word of the one line)
    # -- the file
    ("csv-missing", lambda: None, GOOD_TOML, "cannot read"),
    ("csv-a-folder", lambda: "<dir>", GOOD_TOML, "folder"),
    ("csv-empty", lambda: "", GOOD_TOML, "empty"),
    ("csv-blank-lines-only", lambda: "\n\n\n", GOOD_TOML, "empty"),
    ("csv-header-only", lambda: HEADER, GOOD_TOML, "two samples"),
    ("csv-header-and-blank-lines", lambda: HEADER + "\n\n", GOOD_TOML, "two samples"),
    ("csv-one-row", lambda: lab_csv(1), GOOD_TOML, "two samples"),
    ("csv-header-without-line-break", lambda: HEADER.rstrip("\n"), GOOD_TOML, "line break"),
    ("csv-header-longer-than-1-MB", lambda: "time," + "x" * (1 << 21) + "\n", GOOD_TOML, "1 MB"),
    ("csv-first-column-not-time", lambda: "t,a\n0,1\n1,2\n", GOOD_TOML, "time"),
    ("csv-empty-column-name", lambda: HEADER.replace(",probe", ",,probe"), GOOD_TOML, "empty column"),
    ("csv-duplicate-column", lambda: "time,a,a\n0,1,1\n1,2,2\n", GOOD_TOML, "twice"),
    ("csv-duplicate-read-column", lambda: lab_csv().replace(",T1,", ",T0,", 1), GOOD_TOML, "twice"),
    ("csv-missing-reading-column", lambda: lab_csv().replace(",probe", ",probe_mm", 1), GOOD_TOML, "reading"),
    (
        "csv-missing-temperature",
        lambda: lab_csv().replace(",T3,", ",Tx,", 1),
        GOOD_TOML,
        "temperatures.t_plate",
    ),
    ("csv-a-csv-of-something-else", lambda: "time,a,b\n0,1,2\n1,2,3\n", GOOD_TOML, "the error model reads"),
    ("csv-semicolons", lambda: lab_csv().replace(",", ";"), GOOD_TOML, "time"),
    ("csv-not-utf8-in-a-row", lambda: lab_csv().encode().replace(b"\n4", b"\n\xff4", 1), GOOD_TOML, "UTF-8"),
    ("csv-header-not-utf8", lambda: b"time,\xff\n0,1\n1,2\n", GOOD_TOML, "UTF-8"),
    (
        "csv-latin1-degree-sign",
        lambda: HEADER.replace("T0", "T0 \xb0C").encode("latin-1"),
        GOOD_TOML,
        "UTF-8",
    ),
    ("csv-utf16", lambda: lab_csv(5).encode("utf-16"), GOOD_TOML, "UTF-8"),
    ("csv-binary", lambda: bytes(range(256)) * 8, GOOD_TOML, "line 1"),
    # -- the time column: a row's place in the record
    ("csv-time-not-increasing", lambda: lab_csv(bad={5: "0=0.0"}), GOOD_TOML, "time must increase"),
    ("csv-time-repeated", lambda: lab_csv(bad={5: "0=40.0"}), GOOD_TOML, "time must increase"),
    ("csv-time-nan", lambda: lab_csv(bad={5: "0=nan"}), GOOD_TOML, "time"),
    ("csv-time-inf", lambda: lab_csv(bad={5: "0=inf"}), GOOD_TOML, "time"),
    ("csv-time-empty", lambda: lab_csv(bad={5: "0="}), GOOD_TOML, "time"),
    ("csv-time-a-date", lambda: lab_csv(bad={5: "0=2024-01-01T10:00"}), GOOD_TOML, "time"),
    ("csv-time-backwards-late", lambda: lab_csv(3000, bad={2500: "0=10.0"}), GOOD_TOML, "line 2502"),
    # times closer than a logger's: not seconds (the drift lines' least squares fail on them)
    ("csv-time-steps-of-1e-170-s", lambda: lab_csv(dt=1e-170), GOOD_TOML, "line 3: time 1e-170 s is less"),
    ("csv-time-steps-of-1e-12-s", lambda: lab_csv(dt=1e-12), GOOD_TOML, "0.5 ns"),
    ("csv-time-one-step-too-close", lambda: lab_csv(bad={5: "0=40.0000000001"}), GOOD_TOML, "line 7"),
    (
        "csv-every-row-flagged",
        lambda: lab_csv(3, bad={0: "9=nan", 1: "9=nan", 2: "9=nan"}),
        GOOD_TOML,
        "two samples",
    ),
    ("csv-every-row-short", lambda: HEADER + "0,1\n1,2\n", GOOD_TOML, "two samples"),
    # -- the configuration (every key of [errormodel], wrong type or value)
    ("toml-missing", lab_csv, None, "not found"),  # replaced below by a missing --config file
    ("toml-errormodel-number", lab_csv, "errormodel = 5\n", "expected a table"),
    ("toml-errormodel-string", lab_csv, 'errormodel = "x"\n', "expected a table"),
    ("toml-errormodel-list", lab_csv, "errormodel = [1]\n", "expected a table"),
    ("toml-unknown-table", lab_csv, GOOD_TOML + "[extra]\na = 1\n", "unknown"),
    ("toml-unknown-key", lab_csv, _toml(readng='"probe"'), "readng"),
    ("toml-drift-window-zero", lab_csv, _toml(drift_window='"0 s"'), "positive"),
    ("toml-drift-window-number-zero", lab_csv, _toml(drift_window="0"), "positive"),
    ("toml-drift-window-negative", lab_csv, _toml(drift_window='"-5 min"'), "drift_window"),
    ("toml-drift-window-word", lab_csv, _toml(drift_window='"long"'), "drift_window"),
    ("toml-drift-window-bool", lab_csv, _toml(drift_window="true"), "drift_window"),
    ("toml-drift-window-list", lab_csv, _toml(drift_window='["5 min"]'), "drift_window"),
    ("toml-drift-window-absurd", lab_csv, _toml(drift_window='"1e400 s"'), "drift_window"),
    ("toml-factors-unknown", lab_csv, GOOD_TOML.replace('["thermal"]', '["heat"]'), "factors"),
    ("toml-factors-string", lab_csv, GOOD_TOML.replace('["thermal"]', '"thermal"'), "factors"),
    ("toml-factors-empty", lab_csv, GOOD_TOML.replace('["thermal"]', "[]"), "factors"),
    ("toml-factors-number", lab_csv, GOOD_TOML.replace('["thermal"]', "[1]"), "factors"),
    ("toml-factors-nested-list", lab_csv, GOOD_TOML.replace('["thermal"]', "[[1]]"), "factors"),
    ("toml-factors-table", lab_csv, GOOD_TOML.replace('["thermal"]', "[{a = 1}]"), "factors"),
    ("toml-factors-twice", lab_csv, GOOD_TOML.replace('["thermal"]', '["thermal", "thermal"]'), "twice"),
    ("toml-reading-number", lab_csv, _reading("5"), "errormodel.reading"),
    ("toml-reading-list", lab_csv, _reading('["probe"]'), "errormodel.reading"),
    ("toml-reading-table", lab_csv, _reading("{ a = 1 }"), "errormodel.reading"),
    ("toml-reading-empty", lab_csv, _reading('""'), "empty name"),
    ("toml-reading-time", lab_csv, _reading('"time"'), "time axis"),
    ("toml-true-wear-number", lab_csv, _toml(true_wear="5"), "errormodel.true_wear"),
    ("toml-load-number", lab_csv, _toml(load="5"), "errormodel.load"),
    ("toml-torque-bool", lab_csv, _toml(torque="true"), "errormodel.torque"),
    ("toml-angle-table", lab_csv, _toml(angle="{ a = 1 }"), "errormodel.angle"),
    ("toml-vibration-list", lab_csv, _toml(vibration="[]"), "errormodel.vibration"),
    (
        "toml-temperatures-list",
        lab_csv,
        '[errormodel]\nreading = "probe"\ntemperatures = [1, 2]\n',
        "temperatures",
    ),
    (
        "toml-temperatures-number",
        lab_csv,
        '[errormodel]\nreading = "probe"\ntemperatures = 5\n',
        "temperatures",
    ),
    ("toml-temperature-number", lab_csv, GOOD_TOML.replace('room = "T7"', "room = 7"), "temperatures.room"),
    ("toml-temperature-empty", lab_csv, GOOD_TOML.replace('room = "T7"', 'room = ""'), "temperatures.room"),
    (
        "toml-temperature-unknown-point",
        lab_csv,
        GOOD_TOML.replace('room = "T7"', 'room = "T7", roof = "T8"'),
        "roof",
    ),
    ("toml-coefficients-unknown", lab_csv, _toml(coefficients="{ no_such = 1.0 }"), "no_such"),
    ("toml-coefficients-number", lab_csv, _toml(coefficients="5"), "coefficients"),
    ("toml-coefficients-list", lab_csv, _toml(coefficients="[]"), "coefficients"),
    (
        "toml-coefficients-missing-file",
        lab_csv,
        _toml(coefficients='"no_such.toml"'),
        "lab.toml: errormodel.coefficients: no_such.toml: file not found",
    ),
    (
        "toml-coefficients-a-folder",
        lab_csv,
        _toml(coefficients='"."'),
        "errormodel.coefficients: .: is a directory",
    ),
    (
        "toml-coefficients-dev-zero",
        lab_csv,
        _toml(coefficients='"/dev/zero"'),
        "errormodel.coefficients: /dev/zero: is not a regular file",
    ),
    ("toml-syntax", lab_csv, "[errormodel\n", "syntax"),
    ("toml-huge-int", lab_csv, _toml(factors2="99999999999999999999999"), "64-bit"),
    ("toml-deep", lab_csv, "x = " + "[" * 3000 + "]" * 3000 + "\n", "nested"),
    ("toml-not-utf8", lab_csv, b'[errormodel]\nreading = "\xff"\n'.decode("latin-1"), "errormodel"),
]


@pytest.mark.parametrize(("case", "csv", "toml", "word"), BAD, ids=[b[0] for b in BAD])
def test_a_bad_file_or_setting_gets_one_line_and_exit_2(
    case: str, csv: Callable[[], str | bytes | None], toml: str | None, word: str, tmp_path: Path, capsys
) -> None:
    if case == "toml-missing":
        (tmp_path / "lab.csv").write_text(lab_csv())
        code = main(
            [
                "compensate",
                str(tmp_path / "lab.csv"),
                "--config",
                str(tmp_path / "no.toml"),
                "--out",
                str(tmp_path / "out"),
            ]
        )
    else:
        code = _compensate(tmp_path, csv(), toml)
    assert code == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("twin: "), err
    assert word.lower() in lines[0].lower(), err
    # nothing of this command's is left: no summary, no half-written errormodel.csv
    assert not (tmp_path / "out" / "summary.json").exists()
    assert not (tmp_path / "out" / "errormodel.csv").exists()
    assert not (tmp_path / "out" / "flagged_rows.csv").exists()


def _summary(tmp_path: Path, out: str = "out") -> dict:
    return json.loads((tmp_path / out / "summary.json").read_text())


def _rows(path: Path) -> dict[float, list[str]]:
    """errormodel.csv's rows by time (the text of each value)."""
    lines = path.read_text().splitlines()[1:]
    return {float(line.split(",", 1)[0]): line.split(",")[1:] for line in lines}


FLAGGED = {
    "probe-nan": {17: "9=nan", 250: "9=nan"},
    "probe-inf": {17: "9=inf", 250: "9=-inf"},
    "temp-nan": {17: "1=NaN", 250: "1=nan"},
    "probe-empty": {17: "9=", 250: "9="},
    "probe-NA": {17: "9=NA", 250: "9=N/A"},
    "probe-a-word": {17: "9=ERR", 250: "9=overload"},
    "temp-a-word": {17: "3=warm", 250: "3=--"},
    "probe-underscore": {17: "9=1_0", 250: "9=0x10"},
    # beyond any sensor of a tester: an overload code, not a measurement (flagged like inf)
    "probe-overload": {17: "9=1e308", 250: "9=-9.9e37"},
    "temp-overload": {17: "1=1e300", 250: "8=1.0000001e9"},
}


@pytest.mark.parametrize("case", list(FLAGGED))
def test_rows_the_model_cannot_use_are_flagged_and_the_rest_computed(
    case: str, tmp_path: Path, capsys
) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    rows = FLAGGED[case]
    assert _compensate(tmp_path / "a", lab_csv(), GOOD_TOML) == 0
    assert _compensate(tmp_path / "b", lab_csv(bad=rows), GOOD_TOML) == 0
    err = capsys.readouterr().err
    assert "2 row(s) flagged" in err and "line 19" in err and "flagged_rows.csv" in err
    summary = _summary(tmp_path / "b")
    assert summary["input_rows"]["read"] == 400
    assert summary["input_rows"]["used"] == 398 and summary["input_rows"]["flagged"] == 2
    assert summary["input_rows"]["flagged_rows"] == "flagged_rows.csv"
    assert [s.split(":")[0] for s in summary["input_rows"]["first_flagged"]] == ["line 19", "line 252"]
    flagged = (tmp_path / "b" / "out" / "flagged_rows.csv").read_text().splitlines()
    assert flagged[0] == "line,reason" and [f.split(",")[0] for f in flagged[1:]] == ["19", "252"]
    # the good rows' values are a clean file's: every result row of the other rows is the same
    clean, dirty = (
        _rows(tmp_path / "a" / "out" / "errormodel.csv"),
        _rows(tmp_path / "b" / "out" / "errormodel.csv"),
    )
    assert set(clean) - set(dirty) == {170.0, 2500.0}
    for t, values in dirty.items():
        assert np.allclose(np.array(values, float), np.array(clean[t], float), rtol=0, atol=1e-15), t
    # the drift's start line goes through one point fewer (t = 170 s is in the first 5 min)
    for key in ("predicted", "probe"):
        assert summary["drift_mm"][key] == pytest.approx(_summary(tmp_path / "a")["drift_mm"][key], rel=1e-3)


def test_rows_of_the_wrong_length_are_flagged(tmp_path: Path, capsys) -> None:
    lines = lab_csv().splitlines(keepends=True)
    lines[30] = "290.0,1\n"  # a torn row
    lines[40] = lines[40].rstrip("\n") + ",7\n"  # one value too many
    assert _compensate(tmp_path, "".join(lines), GOOD_TOML) == 0
    summary = _summary(tmp_path)
    assert summary["input_rows"]["flagged"] == 2 and summary["input_rows"]["used"] == 398
    assert "2 values, the header has 10 columns" in summary["input_rows"]["first_flagged"][0]
    assert "line 31" in capsys.readouterr().err


def test_columns_the_model_does_not_read_may_hold_anything(tmp_path: Path) -> None:
    lines = lab_csv().splitlines()
    lines[0] += ",note"
    lines[1:] = [f"{line},{'ok' if k % 2 else ''}" for k, line in enumerate(lines[1:])]
    assert _compensate(tmp_path, "\n".join(lines) + "\n", GOOD_TOML) == 0
    assert _summary(tmp_path)["input_rows"] == {
        "read": 400, "used": 400, "flagged": 0, "flagged_rows": None, "first_flagged": []
    }  # fmt: skip


def test_a_later_clean_file_removes_the_earlier_flag_list(tmp_path: Path) -> None:
    assert _compensate(tmp_path, lab_csv(bad={17: "9=nan"}), GOOD_TOML) == 0
    assert (tmp_path / "out" / "flagged_rows.csv").exists()
    assert _compensate(tmp_path, lab_csv(), GOOD_TOML) == 0
    assert not (tmp_path / "out" / "flagged_rows.csv").exists()


def test_a_last_row_without_its_line_break_counts(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert _compensate(tmp_path / "a", lab_csv(), GOOD_TOML) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no RuntimeWarning either
        assert _compensate(tmp_path / "b", lab_csv(newline_at_end=False), GOOD_TOML) == 0
    a = (tmp_path / "a" / "out" / "errormodel.csv").read_bytes()
    b = (tmp_path / "b" / "out" / "errormodel.csv").read_bytes()
    assert a == b and a.count(b"\n") == 401  # header + every one of the 400 rows
    assert _summary(tmp_path / "b")["input_rows"]["used"] == 400


def test_crlf_line_ends_and_a_byte_order_mark_are_a_lab_file_like_any_other(tmp_path: Path) -> None:
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    assert _compensate(tmp_path / "a", lab_csv(), GOOD_TOML) == 0
    windows = b"\xef\xbb\xbf" + lab_csv().replace("\n", "\r\n").encode()
    assert _compensate(tmp_path / "b", windows, GOOD_TOML) == 0
    assert (tmp_path / "a" / "out" / "errormodel.csv").read_bytes() == (
        tmp_path / "b" / "out" / "errormodel.csv"
    ).read_bytes()


def test_a_record_at_1_ghz_is_seconds_still(tmp_path: Path) -> None:
    """The least time step refused is below a 1 GHz logger's, float rounding included."""
    assert _compensate(tmp_path, lab_csv(dt=1e-9), GOOD_TOML) == 0
    assert _summary(tmp_path)["input_rows"]["used"] == 400
