"""Recorders: where the master's rows go while a run goes.

:class:`RunFolderRecorder` streams every chunk to ``signals.csv`` and ``recording.rrd`` as it
arrives (rows flushed to disk chunk by chunk, so a killed run keeps what was recorded and
memory stays flat in run length) and keeps in memory only the columns the error model needs.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from twin.signals.table import Signal, SignalTable

#: rows are written to disk at least this often (rows) ...
FLUSH_ROWS = 4096
#: ... and at least this often (wall seconds): a killed run loses at most this much
FLUSH_SECONDS = 5.0


class RunFolderRecorder:
    """Tee of the rows to the run folder's CSV and rerun files, plus a kept subset in memory.

    Rows are buffered and written every :data:`FLUSH_ROWS` rows or :data:`FLUSH_SECONDS` of
    wall time, whichever comes first (each write to the recording costs per column, so
    writing every small batch would cost more than the simulation). ``extra_signals`` are
    declared to the recording up front (the error model's columns, sent after the run on the
    same timeline with :meth:`append_extra`).
    """

    def __init__(
        self,
        out_dir: Path,
        *,
        keep: Callable[[str], bool],
        recording_name: str,
        extra_signals: Sequence[Signal] = (),
        budget_columns: Sequence[str] | None = None,
    ) -> None:
        self.out_dir = out_dir
        self.keep = keep
        self.recording_name = recording_name
        self.extra_signals = list(extra_signals)
        self.budget_columns = budget_columns
        self.signals: list[Signal] = []
        self._csv = None
        self._rrd = None
        self._kept: list[int] = []
        self._times: list[np.ndarray] = []
        self._rows: list[np.ndarray] = []
        self._pending_t: list[np.ndarray] = []
        self._pending: list[np.ndarray] = []
        self._pending_n = 0
        self._last_flush = time.monotonic()
        self.write_s = 0.0  # wall time spent writing files

    def open(self, signals: list[Signal]) -> None:
        start = time.perf_counter()
        from twin.outputs import RecordingWriter, SignalsCsvWriter

        self.signals = list(signals)
        self._csv = SignalsCsvWriter.for_signals(self.out_dir / "signals.csv", self.signals)
        self._rrd = RecordingWriter(
            self.out_dir / "recording.rrd",
            [*self.signals, *self.extra_signals],
            recording_name=self.recording_name,
            budget_columns=self.budget_columns,
        )
        self._kept = [c for c, s in enumerate(self.signals) if self.keep(s.name)]
        self.write_s += time.perf_counter() - start

    def append(self, times: np.ndarray, rows: np.ndarray) -> None:
        self._pending_t.append(np.array(times))
        self._pending.append(np.array(rows))
        self._pending_n += len(times)
        self._times.append(np.array(times))
        self._rows.append(np.array(rows[:, self._kept]))
        if self._pending_n >= FLUSH_ROWS or time.monotonic() - self._last_flush >= FLUSH_SECONDS:
            self.flush()

    def flush(self) -> None:
        """Write the buffered rows to both files."""
        if not self._pending_n:
            return
        start = time.perf_counter()
        times = np.concatenate(self._pending_t)
        rows = np.concatenate(self._pending)
        columns = {s.name: rows[:, c] for c, s in enumerate(self.signals)}
        assert self._csv is not None and self._rrd is not None
        self._csv.append(times, columns)
        self._rrd.append(times, columns, partial=True)
        self._pending_t, self._pending, self._pending_n = [], [], 0
        self._last_flush = time.monotonic()
        self.write_s += time.perf_counter() - start

    def close(self) -> None:
        """Write what is buffered and close the CSV (the recording stays open for the error
        model's columns)."""
        if self._csv is not None:
            self.flush()
            start = time.perf_counter()
            self._csv.close()
            self.write_s += time.perf_counter() - start

    def append_extra(self, table: SignalTable, names: Sequence[str]) -> None:
        assert self._rrd is not None
        self._rrd.append(table.time, {n: table[n] for n in names}, partial=True)

    def finish(self) -> None:
        if self._rrd is not None:
            self._rrd.close()
            self._rrd = None

    def table(self) -> SignalTable:
        """The kept columns of every row recorded so far."""
        times = np.concatenate(self._times) if self._times else np.zeros(0)
        rows = np.concatenate(self._rows) if self._rows else np.zeros((0, len(self._kept)))
        table = SignalTable(times)
        for j, c in enumerate(self._kept):
            table.add(self.signals[c], rows[:, j])
        return table
