"""The one reader of a CSV of signals: a run's ``signals.csv`` or a lab's record, read in blocks.

The format (the FMI cross-check convention, which :func:`fmpy.util.read_csv` reads): a header
``time,<name>,...`` (names may be double-quoted; a byte-order mark and CRLF line ends are
accepted), then one row of numbers per line, times in seconds, finite and increasing.

:class:`CsvReader` reads it block by block (memory flat in the file's length) and hands on
the columns kept, as :class:`~twin.signals.table.Block` s. A lab's record (``twin compensate``)
is read leniently: a row it cannot use is flagged (left out, the rest computed, the row
listed); :func:`read_table` reads a whole file strictly (a row it cannot use is bad input).
What is refused (:class:`~twin.errors.ConfigError`: one line naming the file and the line,
exit code 2) and what is flagged:

* the file: missing, not a regular file, empty, a header that is not ``time,<name>,...``
  (incomplete, an empty name, a name twice, more than :data:`MAX_COLUMNS` columns), a line
  longer than :data:`LINE_BYTES`, a column the error model reads missing, fewer than
  two usable rows, bytes that are not UTF-8 text anywhere in the file: refused;
* the time column: a value that is not a finite number, or a time not at least
  :data:`MIN_TIME_STEP_S` after the one before (rows of the wrong length apart): refused, as
  the drift windows and the filter's order depend on it;
* a row: the wrong number of values (a torn line, a logger's restart), or a column kept holding
  anything but a finite number of at most :data:`MAX_MEASURED` (``nan``, ``inf``, empty,
  ``NA``, a word, a logger's overload value ``9.9e37``): flagged. Columns not kept are not
  looked at (a wide file's other columns may hold anything).

Blocks of about ``block_bytes`` are parsed by Arrow's C++ reader (correctly rounded, as
Python's ``float()``), only the columns kept; a block Arrow refuses, or one with a value to
flag or a time out of order, is read again line by line, which says which line and why. A last
line without its line break is a row like any other in a lab's record; in a run's own file it is
the partial row of a run that was killed while writing, dropped with a warning.
"""

from __future__ import annotations

import io
import math
import os
import stat
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.errors import ConfigError, did_you_mean
from twin.signals.table import Block, Signal, SignalTable

__all__ = ["BLOCK_BYTES", "TIME", "CsvReader", "Flag", "read_table"]

#: the first column of every signals CSV
TIME = "time"

#: bytes of the file parsed at a time
BLOCK_BYTES = 1 << 22
#: the header line may be this long (a file of one huge line is not a CSV of measurements)
HEADER_BYTES = 1 << 20
#: so may every other line: a row of MAX_COLUMNS numbers of 25 characters is 250 KB, and a
#: 1 GB line without a line break is refused when its first MB is read, not held in memory
LINE_BYTES = 1 << 20
#: the most columns a CSV of signals may have: hundreds of times the twin's own signals.csv
#: and any tester's logger; a wider header is a file that is no record of this tester (its
#: per-column work would cost minutes)
MAX_COLUMNS = 10_000
#: the least time between two rows (s): the twin's clock counts whole nanoseconds and no
#: logger samples faster than 1 GHz, so rows closer than this are not seconds of a record (a
#: time column in another unit, or garbage); the drift lines' least squares would also fail on
#: them (times 1e-160 s apart square to zero). Half a nanosecond, so a 1 GHz record's times,
#: rounded to floats (4e-9 - 3.0000000000000004e-9 < 1e-9), pass
MIN_TIME_STEP_S = 0.5e-9
#: the largest magnitude a column the error model reads may hold, in its SI unit (K, m, N, N.m,
#: rad): orders of magnitude beyond any sensor of a wear tester (a billion kelvin, metres,
#: newtons), and small enough that the model's products and squares stay finite. A value
#: beyond it is a sensor's overload or dropout code (DMMs write 9.9e37), flagged like ``inf``
MAX_MEASURED = 1e9


@dataclass(frozen=True)
class Flag:
    """A row left out: its line in the file (1 = the header) and why."""

    line: int
    reason: str


class CsvReader:
    """The rows of ``path`` in :class:`~twin.signals.table.Block` s of the ``keep`` columns
    present (time first; None: every column), flagged rows left out and given to ``on_flag``.

    ``required`` are the columns that must be present, each with the key of the configuration
    that names it, and the configuration's name (for the message). Opening reads and checks the
    header; :meth:`blocks` reads the rest. ``partial_last_line``: a last line without its line
    break is the partial row of an interrupted write, dropped with a warning (a run's own file),
    instead of a row like any other (a lab's).
    """

    def __init__(
        self,
        path: Path,
        required: tuple[dict[str, str], str],
        keep: set[str] | None,
        *,
        on_flag: Callable[[Flag], None],
        block_bytes: int = BLOCK_BYTES,
        time_column: str = TIME,
    ) -> None:
        self.path, self.source = path, str(path)
        #: the time axis's column: the first of a signals CSV, any one a lab's LAB.toml names
        self.time_column = time_column
        self.block_bytes = max(1, block_bytes)
        self.on_flag = on_flag
        self.partial_last_line = False
        #: the values are measurements (a lab's record): each a finite number of at most
        #: MAX_MEASURED; else (a run's own file) any number, nan and inf included
        self.measured = True
        #: a time may be given twice in a row: a jump of an input file, whose later value
        #: holds from that time on (as fmpy reads an input file); else times increase strictly
        self.jumps = False
        self._jumped = False  # the last row repeated the time before it
        self.read_rows = 0  # data rows seen (blank lines apart)
        self.flagged = 0
        self._last_time = -math.inf
        self._file = _open_regular(path)
        try:
            self.header = self._read_header()
            _check_required(self.header, *required, self.source)
        except BaseException:
            self._file.close()
            raise
        at = self.header.index(time_column)
        # the time first, whatever its place in the file: every block hands it on as its axis
        self.kept = [at, *(j for j, h in enumerate(self.header) if j != at and (keep is None or h in keep))]
        self.names = [self.header[j] for j in self.kept]

    def close(self) -> None:
        self._file.close()

    def _read_header(self) -> list[str]:
        raw = self._file.readline(HEADER_BYTES)
        if not raw.strip():
            raise ConfigError(f"empty file, expected a header '{TIME},<name>,...'", source=self.source)
        if not raw.endswith(b"\n"):
            raise ConfigError(
                "line 1: the header has no line break after it (or is longer than 1 MB)", source=self.source
            )
        try:
            text = raw.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise ConfigError(
                f"line 1: not UTF-8 text (byte {raw[exc.start]:#04x})", source=self.source
            ) from None
        header = [h.strip().strip('"').strip() for h in text.rstrip("\r\n").split(",")]
        if self.time_column == TIME and header[0] != TIME:
            raise ConfigError(f"line 1: first column must be '{TIME}', got {header[0]!r}", source=self.source)
        if self.time_column not in header:
            raise ConfigError(
                f"line 1: no time column {self.time_column!r} (the record's time axis, [errormodel] "
                f"time of its LAB.toml){did_you_mean(self.time_column, header)}",
                source=self.source,
            )
        if len(header) > MAX_COLUMNS:
            raise ConfigError(
                f"line 1: {len(header)} columns, more than the {MAX_COLUMNS} a CSV of signals may have",
                source=self.source,
            )
        if not all(header):
            raise ConfigError("line 1: empty column name", source=self.source)
        seen: set[str] = set()
        twice = sorted({h for h in header if h in seen or seen.add(h)})  # linear in the columns
        if twice:
            raise ConfigError(f"line 1: column(s) {twice} appear twice", source=self.source)
        return header

    def blocks(self) -> Iterator[Block]:
        """The usable rows, block by block (times finite and strictly increasing)."""
        line = 2  # of the block's first byte
        rest = b""
        while True:
            data = self._file.read(self.block_bytes)
            if not data:
                break
            data = rest + data
            cut = data.rfind(b"\n") + 1
            block, rest = data[:cut], data[cut:]
            if block:
                yield from self._block(block, line)
                line += block.count(b"\n")
            if len(rest) > LINE_BYTES:
                raise ConfigError(
                    f"line {line}: longer than {LINE_BYTES // 2**20} MB without a line break",
                    source=self.source,
                )
        if rest.strip() and self.partial_last_line:
            warnings.warn(
                f"{self.source}: ignored incomplete last line {line} (no line break: interrupted write?)",
                RuntimeWarning,
                stacklevel=4,  # the caller of read_table
            )
        elif rest.strip():  # a last line without its line break: a row like any other
            yield from self._block(rest + b"\n", line)

    def _block(self, data: bytes, line: int) -> Iterator[Block]:
        if not data.isascii():
            try:
                data.decode("utf-8")
            except UnicodeDecodeError as exc:
                at = line + data.count(b"\n", 0, exc.start)
                raise ConfigError(
                    f"line {at}: not UTF-8 text (byte {data[exc.start]:#04x})", source=self.source
                ) from None
        parsed = self._fast(data)
        if parsed is None:
            parsed = self._careful(data, line)
        elif len(parsed):
            self.read_rows += len(parsed)
            self._last_time = float(parsed.time[-1])
            self._jumped = False  # Arrow's rows increase strictly
        if len(parsed):
            yield parsed

    def _fast(self, data: bytes) -> Block | None:
        """The block by Arrow, when every row is well formed, usable and in order; else None."""
        import pyarrow as pa
        import pyarrow.csv as pacsv

        ncol = len(self.header)
        names = [f"c{j}" for j in range(ncol)]
        try:
            table = pacsv.read_csv(
                io.BytesIO(data),
                read_options=pacsv.ReadOptions(column_names=names),
                convert_options=pacsv.ConvertOptions(
                    include_columns=[names[j] for j in self.kept],
                    column_types={names[j]: pa.float64() for j in self.kept},
                ),
            )
        except (pa.ArrowInvalid, pa.ArrowException):
            return None
        cols = [_floats(table.column(names[j])) for j in self.kept]
        if any(c is None for c in cols):
            return None  # a null ("nan", "", "NA"): a row to flag, or a NaN the careful reader reads
        time = cols[0]
        if time.size and (
            not time[0] - self._last_time >= MIN_TIME_STEP_S or not np.all(np.diff(time) >= MIN_TIME_STEP_S)
        ):
            return None
        if not np.isfinite(time).all():  # inf
            return None
        # False for inf and NaN too: one pass over each column
        if self.measured and not all((np.abs(c) <= MAX_MEASURED).all() for c in cols[1:]):
            return None
        return Block(time, dict(zip(self.names[1:], cols[1:], strict=True)))

    def _careful(self, data: bytes, first_line: int) -> Block:
        """The block line by line: each flagged row and each refusal with its line number."""
        ncol = len(self.header)
        rows: list[list[float]] = []
        for lineno, raw in enumerate(data.decode("utf-8").split("\n")[:-1], start=first_line):
            if not raw.strip():
                continue
            self.read_rows += 1
            fields = raw.split(",")
            if len(fields) != ncol:
                self._flag(lineno, f"{len(fields)} values, the header has {ncol} columns")
                continue
            t = self._time(fields[self.kept[0]], lineno)
            row, bad = [t], None
            for j in self.kept[1:]:
                value = _number(fields[j])
                if value is not None and not self.measured:
                    row.append(value)
                    continue
                if value is None and not self.measured:
                    bad = f"column '{self.header[j]}': {fields[j].strip()!r} is not a number"
                    break
                if value is None or not math.isfinite(value):
                    bad = f"column '{self.header[j]}': {fields[j].strip()!r} is not a finite number"
                    break
                if abs(value) > MAX_MEASURED:
                    bad = (
                        f"column '{self.header[j]}': {fields[j].strip()!r} is beyond "
                        f"+-{MAX_MEASURED:g} (a sensor's overload value, not a measurement)"
                    )
                    break
                row.append(value)
            if bad is not None:
                self._flag(lineno, bad)
                continue
            rows.append(row)
        values = np.array(rows, dtype=np.float64).reshape(len(rows), len(self.kept))
        return Block(
            np.ascontiguousarray(values[:, 0]),
            {n: np.ascontiguousarray(values[:, k]) for k, n in enumerate(self.names[1:], start=1)},
        )

    def _time(self, text: str, lineno: int) -> float:
        t = _number(text)
        if t is None or not math.isfinite(t):
            raise ConfigError(
                f"line {lineno}: time {text.strip()!r} is not a finite number (a row's place in "
                "the record cannot be flagged away)",
                source=self.source,
            )
        if self.jumps and t == self._last_time and not self._jumped:
            self._jumped = True
            return t
        self._jumped = False
        if t <= self._last_time:
            raise ConfigError(
                f"line {lineno}: time {t!r} s is not after {self._last_time!r} s (time must increase)",
                source=self.source,
            )
        if t - self._last_time < MIN_TIME_STEP_S:
            raise ConfigError(
                f"line {lineno}: time {t!r} s is less than {MIN_TIME_STEP_S * 1e9:g} ns after "
                f"{self._last_time!r} s (the time column must be seconds, or LAB.toml give its "
                "unit; no logger samples faster than 1 GHz)",
                source=self.source,
            )
        self._last_time = t
        return t

    def _flag(self, line: int, reason: str) -> None:
        self.flagged += 1
        self.on_flag(Flag(line, reason))


def _floats(column: Any) -> np.ndarray | None:
    """An Arrow float64 column as one numpy array, None if it holds a null. From the buffers:
    Arrow's own to_numpy() would import pandas."""
    parts = []
    for chunk in column.chunks:
        if chunk.null_count:
            return None
        data = np.frombuffer(chunk.buffers()[1], dtype=np.float64)
        parts.append(data[chunk.offset : chunk.offset + len(chunk)])
    if not parts:
        return np.empty(0)
    return np.concatenate(parts) if len(parts) > 1 else parts[0].copy()


def _number(text: str) -> float | None:
    """The number in a field as Arrow reads it (blanks and double quotes around it allowed),
    or None. Python's float() alone would also take ``1_000``, which Arrow does not."""
    text = text.strip().strip('"')
    if "_" in text:
        return None
    try:
        return float(text)
    except ValueError:
        return None


def _open_regular(path: Path) -> io.BufferedReader:
    """``path`` opened for reading, refused in one line unless it is a regular file (a folder,
    a device or a FIFO could block or never end)."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror or exc}", source=str(path)) from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        what = "a folder" if stat.S_ISDIR(mode) else "not a regular file (a device, FIFO or socket)"
        raise ConfigError(f"cannot read: is {what}, expected a CSV file", source=str(path))
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


def _check_required(header: Sequence[str], required: dict[str, str], config: str, source: str) -> None:
    """Every column the error model needs is in the header; else one line naming each missing
    column, the key of ``config`` that names it, and a close match."""
    import difflib

    missing = [c for c in required if c not in header]
    if not missing:
        return
    hints = []
    for c in missing:
        close = difflib.get_close_matches(c, header[1:], n=1)
        hints.append(f"'{c}' ({required[c]}" + (f"; did you mean '{close[0]}'?)" if close else ")"))
    # the key facts first, and at most three columns named: a one-line message is shortened past
    # 500 characters, and a file with none of the columns would otherwise lose the config's name
    more = f" and {len(hints) - 3} more" if len(hints) > 3 else ""
    raise ConfigError(
        f"no column {', '.join(hints[:3])}{more}, as [errormodel] in {config} names them; "
        f"the error model reads {TIME}, {', '.join(required)}",
        source=source,
    )


def _refuse(source: str) -> Callable[[Flag], None]:
    def refuse(flag: Flag) -> None:
        raise ConfigError(f"line {flag.line}: {flag.reason}", source=source)

    return refuse


def read_table(path: Path, signals: Mapping[str, Signal] | None = None) -> SignalTable:
    """A whole CSV of signals as a table, strictly: any row it cannot use is bad input (a run's
    own file, or a lab's in the same format), a partial last line dropped with a warning.
    ``signals`` gives a column's unit, subsystem and description (else no unit, and the name's
    prefix before the first dot as its subsystem)."""
    reader = CsvReader(path, ({}, ""), None, on_flag=_refuse(str(path)))
    reader.partial_last_line, reader.measured = True, False
    try:
        blocks = list(reader.blocks())
    finally:
        reader.close()
    names = reader.names[1:]
    data = Block.join(blocks) if blocks else Block(np.empty(0), {n: np.empty(0) for n in names})
    table = SignalTable(time=data.time)
    for name in names:
        meta = (signals or {}).get(name) or Signal(name, "", _default_subsystem(name))
        table.add(meta, data.columns[name])
    return table


def _default_subsystem(name: str) -> str:
    """The subsystem of a column without a sidecar: its name's prefix before the first dot."""
    return name.split(".", 1)[0] if "." in name else "measured"
