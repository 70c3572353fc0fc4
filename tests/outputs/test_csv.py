"""signals.csv: FMPy-readable, exact round trip, streaming, truncation, bad files."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from fmpy.util import read_csv

from twin.errors import ConfigError
from twin.outputs.csv import SignalsCsvWriter, read_signals_csv, units_sidecar_path, write_signals_csv
from twin.signals.table import Signal, SignalTable

from .sample import make_table


def _assert_tables_equal(a: SignalTable, b: SignalTable) -> None:
    assert a.names() == b.names()
    np.testing.assert_array_equal(a.time, b.time)
    for name in a.names():
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_fmpy_reads_names_with_dots_and_exact_values(table: SignalTable, tmp_path: Path) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    traj = read_csv(path)
    assert traj.dtype.names == ("time", *table.names())
    np.testing.assert_array_equal(traj["time"], table.time)
    for name in table.names():
        # repr formatting: every float64 reads back bit for bit, including 1e300-scale values.
        np.testing.assert_array_equal(traj[name], table[name], err_msg=name)


def test_header_is_time_then_signal_names(table: SignalTable, tmp_path: Path) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    header = path.read_text().splitlines()[0]
    assert header == "time," + ",".join(table.names())
    assert header.split(",")[1] == "thermal.t_base"


def test_read_signals_csv_round_trips_values_and_metadata(table: SignalTable, tmp_path: Path) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    back = read_signals_csv(path)
    _assert_tables_equal(back, table)
    assert back.meta == table.meta  # unit, subsystem and description via signals.units.json
    assert units_sidecar_path(path).name == "signals.units.json"


def test_non_finite_values_round_trip(tmp_path: Path) -> None:
    table = make_table(rows=5)
    table.columns["thermal.t_base"][1:4] = [np.nan, np.inf, -np.inf]
    path = write_signals_csv(table, tmp_path / "signals.csv")
    for values in (read_csv(path)["thermal.t_base"], read_signals_csv(path)["thermal.t_base"]):
        np.testing.assert_array_equal(values, table["thermal.t_base"])


def test_chunked_writing_equals_one_shot_byte_for_byte(table: SignalTable, tmp_path: Path) -> None:
    one_shot = write_signals_csv(table, tmp_path / "a.csv")
    signals = [table.meta[n] for n in table.names()]
    bounds = [0, 1, 101, 101, 350, 720, len(table)]  # includes an empty chunk and a 1-row chunk
    with SignalsCsvWriter(tmp_path / "b.csv", signals) as writer:
        for lo, hi in itertools.pairwise(bounds):
            writer.append(table.time[lo:hi], {n: v[lo:hi] for n, v in table.columns.items()})
    assert writer.rows == len(table)
    assert (tmp_path / "b.csv").read_bytes() == one_shot.read_bytes()
    assert (tmp_path / "b.units.json").read_bytes() == (tmp_path / "a.units.json").read_bytes()


def test_a_chunk_is_formatted_in_pieces_and_flushed_in_slices_of_whole_rows(
    table: SignalTable, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # what a full disk can leave is cut back to the last flushed slice: each must end a row,
    # and the position a resumed run continues from is that of the last one
    import twin.outputs.csv as csv_module

    one_shot = write_signals_csv(table, tmp_path / "a.csv").read_bytes()
    monkeypatch.setattr(csv_module, "_SLICE_BYTES", 300)
    monkeypatch.setattr(csv_module, "_FORMAT_BYTES", 5000)
    flushed: list[tuple[int, float]] = []
    real = SignalsCsvWriter._flush

    def flush(self: SignalsCsvWriter) -> None:
        real(self)
        flushed.append((self._file.tell(), self._last_time))  # type: ignore[union-attr]

    monkeypatch.setattr(SignalsCsvWriter, "_flush", flush)
    with SignalsCsvWriter(tmp_path / "b.csv", [table.meta[n] for n in table.names()]) as writer:
        writer.append(table.time, table.columns)
        assert writer.position() == (len(one_shot), float(table.time[-1]))
    assert (tmp_path / "b.csv").read_bytes() == one_shot
    assert len(flushed) > len(one_shot) // 1000  # many slices, not one
    for (size, _), (_, last) in itertools.pairwise(flushed):
        assert one_shot[size - 1 : size] == b"\n"  # a whole row
        # the slice flushed next starts after the row at the time recorded with it
        assert (
            one_shot[:size].count(b"\n") - 1 == int(np.searchsorted(table.time, last)) + 1 or last == -np.inf
        )


def test_same_input_gives_identical_bytes(tmp_path: Path) -> None:
    a = write_signals_csv(make_table(), tmp_path / "a.csv").read_bytes()
    b = write_signals_csv(make_table(), tmp_path / "b.csv").read_bytes()
    assert a == b
    assert a != write_signals_csv(make_table(seed=8), tmp_path / "c.csv").read_bytes()


def test_rows_are_on_disk_after_each_append(table: SignalTable, tmp_path: Path) -> None:
    # A run killed after an append keeps those rows: read while the writer is still open.
    path = tmp_path / "signals.csv"
    signals = [table.meta[n] for n in table.names()]
    with SignalsCsvWriter(path, signals) as writer:
        assert read_signals_csv(path).time.size == 0  # header only
        writer.append(table.time[:10], {n: v[:10] for n, v in table.columns.items()})
        partial = read_signals_csv(path)
        np.testing.assert_array_equal(partial.time, table.time[:10])
        np.testing.assert_array_equal(partial["probe.reading"], table["probe.reading"][:10])


@pytest.mark.parametrize("cut", [1, 2, 7, -1])
def test_truncated_last_line_is_ignored_with_a_warning(table: SignalTable, tmp_path: Path, cut: int) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    data = path.read_bytes()
    last_line_len = len(data) - data.rstrip(b"\n").rfind(b"\n") - 1
    # cut bytes off the end; -1 keeps only the first character of the last row
    n = last_line_len - 1 if cut == -1 else cut
    path.write_bytes(data[:-n])
    with pytest.warns(RuntimeWarning, match="incomplete last line"):
        back = read_signals_csv(path)
    assert len(back) == len(table) - 1
    np.testing.assert_array_equal(back.time, table.time[:-1])
    np.testing.assert_array_equal(back["errormodel.e_total"], table["errormodel.e_total"][:-1])


def test_file_cut_at_a_row_boundary_reads_without_warning(
    table: SignalTable, tmp_path: Path, recwarn
) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    lines = path.read_bytes().splitlines(keepends=True)
    path.write_bytes(b"".join(lines[:51]))  # header + 50 rows
    back = read_signals_csv(path)
    assert len(back) == 50
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]


def test_user_measurement_without_sidecar(tmp_path: Path) -> None:
    # Spreadsheet export: BOM, quoted names, CRLF, a name without an instance prefix.
    path = tmp_path / "bench.csv"
    path.write_bytes(b'\xef\xbb\xbf"time","probe.reading","t_room"\r\n0,1e-3,20.5\r\n60,1.002e-3,20.75\r\n')
    table = read_signals_csv(path)
    assert table.names() == ["probe.reading", "t_room"]
    np.testing.assert_array_equal(table.time, [0.0, 60.0])
    np.testing.assert_array_equal(table["t_room"], [20.5, 20.75])
    assert table.meta["probe.reading"].subsystem == "probe"
    assert table.meta["t_room"].subsystem == "measured"
    assert table.meta["t_room"].unit == ""


@pytest.mark.parametrize(
    ("content", "problem"),
    [
        ("", "empty file"),
        ("t,x.a\n0,1\n", "first column must be 'time'"),
        ("time,x.a,x.a\n0,1,2\n", "column(s) ['x.a'] appear twice"),
        ("time,x.a,\n0,1,2\n", "empty column name"),
        ("time,x.a\n0,1\n1,2,3\n", "line 3: 3 values, the header has 2 columns"),
        ("time,x.a\n0,1\n1,abc\n", "line 3: column 'x.a': 'abc' is not a number"),
        ("time,x.a\n0,1\n2,1\n1,1\n", "line 4: time 1.0 s is not after 2.0 s"),
        ("time,x.a\n0,1\nnan,1\n", "line 3: time 'nan' is not a finite number"),
        ("time,x.a", "the header has no line break after it"),
    ],
)
def test_bad_csv_raises_config_error_naming_file_and_problem(
    tmp_path: Path, content: str, problem: str
) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(ConfigError) as info:
        read_signals_csv(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    assert problem in message
    assert info.value.source == str(path)


def test_missing_file_raises_config_error(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read: No such file"):
        read_signals_csv(tmp_path / "nope.csv")


def test_corrupt_sidecar_raises_config_error(table: SignalTable, tmp_path: Path) -> None:
    path = write_signals_csv(table, tmp_path / "signals.csv")
    units_sidecar_path(path).write_text("{not json")
    with pytest.raises(ConfigError, match="units sidecar"):
        read_signals_csv(path)


@pytest.mark.parametrize("name", ["a,b", 'a"b', "a b", "time", ""])
def test_writer_refuses_names_fmpy_cannot_read(tmp_path: Path, name: str) -> None:
    with pytest.raises(ValueError):
        SignalsCsvWriter(tmp_path / "s.csv", [Signal(name, "m", "x")])


def test_writer_refuses_time_going_back_across_chunks(tmp_path: Path) -> None:
    with SignalsCsvWriter(tmp_path / "s.csv", [Signal("x.a", "m", "x")]) as writer:
        writer.append(np.array([0.0, 1.0]), {"x.a": np.array([1.0, 2.0])})
        with pytest.raises(ValueError, match="strictly increasing"):
            writer.append(np.array([1.0, 2.0]), {"x.a": np.array([1.0, 2.0])})
        with pytest.raises(ValueError, match="missing"):
            writer.append(np.array([3.0]), {})
    with pytest.raises(ValueError, match="closed"):
        writer.append(np.array([3.0]), {"x.a": np.array([1.0])})
