"""``signals.csv``: the signal table as a CSV file that FMPy reads.

Format (the FMI cross-check convention that :func:`fmpy.util.read_csv` parses):

* first line ``time,<name>,<name>,...``; the names are the signal names as they are
  (``thermal.t_base``): fmpy splits the header on commas only and numpy accepts dots in
  field names, so no quoting or renaming is needed. Names holding a comma, a quote, a
  space or a line break are refused because fmpy could not read them back;
* one row per time, values in SI units, written with ``repr`` (shortest text that reads
  back to the identical float64), so the file round-trips exactly and identical inputs give
  byte-identical files; NaN and infinities are written ``nan``/``inf``;
* every row ends with ``\\n``. A run killed mid-write leaves at most one partial last line
  without its ``\\n``; :func:`read_signals_csv` drops that line (with a warning), so the file
  stays readable up to its last complete row.

Units, subsystems and descriptions go to a small sidecar ``<stem>.units.json`` next to the
CSV (fmpy ignores it) so :func:`read_signals_csv` can rebuild the full table.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from twin.errors import ConfigError
from twin.outputs.guard import open_output
from twin.outputs.sink import ClosesOnExit, OutcomeSink, Sink
from twin.outputs.summary import write_summary
from twin.signals.csv import TIME, _default_subsystem, read_table
from twin.signals.table import Block, Signal, SignalTable

if TYPE_CHECKING:
    from twin.outputs.sink import Outcome

__all__ = [
    "DerivedCsvSink",
    "SignalsCsvSink",
    "SignalsCsvWriter",
    "read_signals_csv",
    "units_sidecar_path",
    "write_signals_csv",
]

_FORBIDDEN = frozenset(",\"'\n\r \t")
# Subsystem given to a column whose name has no "<instance>." prefix and no sidecar entry,
# e.g. a column of a user's own measurement file.
DEFAULT_SUBSYSTEM = "measured"


def units_sidecar_path(csv_path: str | os.PathLike[str]) -> Path:
    """Where the units sidecar of ``csv_path`` lives: ``signals.csv`` -> ``signals.units.json``."""
    return Path(csv_path).with_suffix(".units.json")


def _check_names(names: Sequence[str]) -> None:
    seen: set[str] = set()
    for name in names:
        if not name or _FORBIDDEN.intersection(name):
            raise ValueError(
                f"signal name {name!r} cannot be a CSV column (empty, or holds , \" ' or blanks)"
            )
        if name == TIME:
            raise ValueError("'time' is the time column and cannot also be a signal name")
        if name in seen:
            raise ValueError(f"signal name {name!r} appears twice")
        seen.add(name)


#: bytes of text written and flushed at a time
_SLICE_BYTES = 1 << 18
#: about the bytes of text formatted at a time (a value takes up to 24 characters): Arrow's
#: working memory is a few times this, and 1 MiB formats as fast as 4 (the paper's replay)
_FORMAT_BYTES = 1 << 20


class SignalsCsvWriter(ClosesOnExit):
    """Stream a run's signals to ``path`` chunk by chunk.

    The header (and the units sidecar) are written on construction; each :meth:`append`
    writes its rows and flushes them to the OS, so a killed run keeps every appended row.
    Use as a context manager or call :meth:`close`.

    With ``fsync=True`` each append also waits for the disk (survives a power cut, costs time).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        signals: Sequence[Signal],
        *,
        sidecar: bool = True,
        fsync: bool = False,
        resume_at: tuple[int, float] | None = None,
    ) -> None:
        """The columns, units and subsystems come from ``signals`` (in order). ``resume_at =
        (byte offset, last time)`` continues a file written before (a resumed run): it is cut
        back to that offset, and rows are appended after it."""
        self.path = Path(path)
        self.signals = list(signals)
        self.names = [s.name for s in self.signals]
        _check_names(self.names)
        self._name_set = frozenset(self.names)
        self._fsync = fsync
        self._last_time = -math.inf
        self.rows = 0
        # The rows' numbers go through Arrow's C++ CSV writer (:func:`_csv_rows`): the
        # shortest text that reads back to the same double, without a Python call per number.
        if resume_at is not None:
            offset, self._last_time = resume_at
            self._file: IO[bytes] | None = open_output(self.path, "r+")  # never through a link
            self._file.truncate(offset)
            self._file.seek(offset)
            self._good = offset
            return
        if sidecar:
            write_units_sidecar(self.path, self.signals)
        # binary, lines ending in "\n": the same bytes on every platform (deterministic files)
        self._file = open_output(self.path)
        self._file.write((",".join([TIME, *self.names]) + "\n").encode("utf-8"))
        self._flush()
        self._good = self._file.tell()

    def position(self) -> tuple[int, float]:
        """(bytes written, last time): where a resumed run continues."""
        assert self._file is not None
        self._file.flush()
        return self._file.tell(), self._last_time

    def append(self, time_chunk: np.ndarray, columns_chunk: Mapping[str, np.ndarray]) -> None:
        """Write the rows of one chunk: ``time_chunk`` (s) and one array per signal name.

        Times must be finite and strictly increasing, also across chunks (readers rely on it).
        """
        if self._file is None:
            raise ValueError(f"{self.path} is closed")
        t = np.asarray(time_chunk, dtype=np.float64)
        if t.ndim != 1:
            raise ValueError(f"time chunk must be 1-D, got shape {t.shape}")
        missing = [n for n in self.names if n not in columns_chunk]
        extra = [n for n in columns_chunk if n not in self._name_set]
        if missing or extra:
            raise ValueError(f"chunk columns do not match the header: missing {missing}, unexpected {extra}")
        if t.size == 0:
            return
        if not np.all(np.isfinite(t)) or np.any(np.diff(t) <= 0) or t[0] <= self._last_time:
            raise ValueError(
                f"times must be finite and strictly increasing (after t = {self._last_time!r} s)"
            )
        columns = [np.ascontiguousarray(t)]
        for name in self.names:
            values = np.ascontiguousarray(columns_chunk[name], dtype=np.float64)
            if values.shape != t.shape:
                raise ValueError(f"column '{name}' has shape {values.shape}, time has {t.shape}")
            columns.append(values)
        # formatted in large pieces (Arrow's cost per call is that of many rows), written in
        # slices of whole rows, each flushed: a write that fails (a full disk) loses at most
        # one slice, and abandon() cuts the file back to the last whole one
        rows = max(1, _FORMAT_BYTES // (24 * len(columns)))
        for i in range(0, t.size, rows):
            self._write_rows(_csv_rows([c[i : i + rows] for c in columns]), t[i : i + rows])
        _give_back_arrow_memory()

    def _write_rows(self, text: bytes, t: np.ndarray) -> None:
        """Write ``text`` (the rows at times ``t``) in slices of about :data:`_SLICE_BYTES`,
        each ending with a row's line end and flushed."""
        assert self._file is not None
        view = memoryview(text)
        start = done = 0
        while start < len(text):
            # the line end at or after the slice's size (the text ends with one)
            end = text.find(b"\n", min(start + _SLICE_BYTES, len(text)) - 1) + 1 or len(text)
            try:
                self._file.write(view[start:end])
                self._flush()
            except OSError as exc:
                exc.filename = exc.filename or str(self.path)
                raise
            rows = text.count(b"\n", start, end)
            done += rows
            self._good = self._file.tell()
            self._last_time = float(t[done - 1])
            self.rows += rows
            start = end

    def abandon(self) -> None:
        """Close after a failed write (a full disk): the file is cut back to its last whole
        row, so what it holds stays readable. Closing cannot fail here: the unflushed rest
        of the failed chunk is dropped."""
        if self._file is None:
            return
        # the buffer may not flush: those bytes are the ones cut off below
        with contextlib.suppress(OSError):
            self._file.close()
        self._file = None
        with open_output(self.path, "r+") as f:
            f.truncate(self._good)  # truncation frees space, it needs none

    def _flush(self) -> None:
        assert self._file is not None
        self._file.flush()
        if self._fsync:
            os.fsync(self._file.fileno())

    def close(self) -> None:
        """Close the file (idempotent)."""
        if self._file is not None:
            self._file.close()
            self._file = None


def _csv_rows(columns: Sequence[np.ndarray]) -> bytes:
    """Rows of float columns (contiguous, of one length) as CSV text: each number the
    shortest text that reads back to the same double (Arrow's writer: ``0.00001``, ``1e+22``,
    ``nan``, ``-0``), each row ending with ``\\n``."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    n = columns[0].shape[0]
    # zero-copy Arrow arrays on the columns' buffers (pa.array() would import pandas)
    arrays = [pa.Array.from_buffers(pa.float64(), n, [None, pa.py_buffer(c)]) for c in columns]
    table = pa.Table.from_arrays(arrays, names=[f"c{j}" for j in range(len(columns))])
    sink = pa.BufferOutputStream()
    pacsv.write_csv(table, sink, pacsv.WriteOptions(include_header=False, quoting_style="none"))
    return sink.getvalue().to_pybytes()


def _give_back_arrow_memory() -> None:
    """Arrow's allocator (mimalloc) keeps what it freed for its next call: given back once a
    chunk is written, the run's memory stays lower while rerun loads beside the plot helper
    (issue 32: 13 MB in the paper's replay). Microseconds; the next chunk's pages are new."""
    import pyarrow as pa

    pa.default_memory_pool().release_unused()


def write_units_sidecar(csv_path: str | os.PathLike[str], signals: Sequence[Signal]) -> Path:
    """Write ``<stem>.units.json``: name -> {unit, subsystem, description}, time first."""
    data: dict[str, dict[str, str]] = {TIME: {"unit": "s", "subsystem": "", "description": "simulation time"}}
    for s in signals:
        data[s.name] = {"unit": s.unit, "subsystem": s.subsystem, "description": s.description}
    return write_summary(units_sidecar_path(csv_path), data)


def write_signals_csv(table: SignalTable, path: str | os.PathLike[str], *, sidecar: bool = True) -> Path:
    """Write a whole :class:`SignalTable` to ``path`` (and its units sidecar); returns ``path``."""
    signals = [table.meta[n] for n in table.names()]
    with SignalsCsvWriter(path, signals, sidecar=sidecar) as writer:
        writer.append(table.time, table.columns)
    return Path(path)


class SignalsCsvSink(Sink):
    """``signals.csv`` as a sink: every recorded row, appended block by block as the run goes.

    ``resume_at`` (a checkpoint's ``csv_position``) continues the file of a resumed run;
    ``columns`` are the only columns it holds, in that order (``twin run --record``; None:
    every recorded column).
    """

    def __init__(
        self,
        path: Path,
        *,
        resume_at: tuple[int, float] | None = None,
        columns: Sequence[str] | None = None,
    ) -> None:
        self.path = path
        self.resume_at = resume_at
        self.columns = tuple(columns) if columns is not None else None
        self._writer: SignalsCsvWriter | None = None

    def open(self, signals: list[Signal]) -> None:
        if self.columns is not None:
            by_name = {s.name: s for s in signals}
            signals = [by_name[n] for n in self.columns]
        self._writer = SignalsCsvWriter(self.path, signals, resume_at=self.resume_at)

    def write(self, block: Block) -> None:
        assert self._writer is not None, "write before open"
        columns = block.columns
        if self.columns is not None:
            columns = {n: columns[n] for n in self.columns}
        self._writer.append(block.time, columns)

    def checkpoint(self) -> dict[str, Any]:
        """Where the file stands: (bytes written, last time), for a resumed run to continue."""
        assert self._writer is not None, "checkpoint before open"
        return {"csv_position": list(self._writer.position())}

    def close(self, outcome: Outcome) -> None:
        if self._writer is not None:
            self._writer.close()

    def fail(self, error: BaseException) -> None:
        # every whole appended row is already flushed to the OS; a failed write may have left
        # part of a chunk behind it, which abandon() cuts off
        if self._writer is not None:
            self._writer.abandon()


class DerivedCsvSink(OutcomeSink):
    """A CSV of the columns derived once the run is over (``errormodel.csv``: the error model's).

    Written whole when the sink closes, and only when the outcome has such columns.
    """

    def __init__(self, path: Path) -> None:
        self.path = path

    def write_outcome(self, outcome: Outcome) -> None:
        if outcome.table is not None:
            write_signals_csv(outcome.table.subset(outcome.columns), self.path)


def _read_sidecar(csv_path: Path) -> dict[str, dict[str, str]]:
    side = units_sidecar_path(csv_path)
    if not side.is_file():
        return {}
    try:
        data = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ConfigError(f"unreadable units sidecar: {exc}", source=str(side)) from None
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise ConfigError(
            "units sidecar must map each name to {unit, subsystem, description}", source=str(side)
        )
    return data


def read_signals_csv(path: str | os.PathLike[str]) -> SignalTable:
    """Read a signals CSV (ours, or a user's measurement in the same format) into a table, with
    the one CSV reader (:func:`twin.signals.csv.read_table`: strict, a partial last line of an
    interrupted run dropped with a warning). Units and subsystems come from the
    ``<stem>.units.json`` sidecar when present, else the unit is ``""`` and the subsystem the
    name's prefix before the first dot. Raises :class:`~twin.errors.ConfigError` (one line:
    file, line number, problem) on a bad file."""
    path = Path(path)
    sidecar = _read_sidecar(path)
    signals = {
        name: Signal(
            name=name,
            unit=str(info.get("unit", "")),
            subsystem=str(info.get("subsystem") or _default_subsystem(name)),
            description=str(info.get("description", "")),
        )
        for name, info in sidecar.items()
    }
    return read_table(path, signals)
