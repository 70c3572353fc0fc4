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
        resume: dict | None = None,
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
        self.resume = resume  # a checkpoint's recorder part: continue the files it describes

    def open(self, signals: list[Signal]) -> None:
        start = time.perf_counter()
        from twin.outputs import RecordingWriter, SignalsCsvWriter

        self.signals = list(signals)
        resume = self.resume
        csv_path = self.out_dir / "signals.csv"
        if resume is not None:
            # the CSV is cut back to the checkpoint and continued; the recording (whose footer a
            # killed run never wrote) is written anew from the CSV's rows up to the checkpoint
            self._csv = SignalsCsvWriter.for_signals(
                csv_path, self.signals, resume_at=tuple(resume["csv_position"])
            )
        else:
            self._csv = SignalsCsvWriter.for_signals(csv_path, self.signals)
        self._rrd = RecordingWriter(
            self.out_dir / "recording.rrd",
            [*self.signals, *self.extra_signals],
            recording_name=self.recording_name,
            budget_columns=self.budget_columns,
        )
        self._kept = [c for c, s in enumerate(self.signals) if self.keep(s.name)]
        if resume is not None:
            from twin.outputs import read_signals_csv

            before = read_signals_csv(csv_path)
            self._rrd.append(before.time, {s.name: before[s.name] for s in self.signals}, partial=True)
            self._times = [np.array(resume["kept_time"])]
            self._rows = [np.array(resume["kept_rows"])]
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

    def checkpoint(self) -> dict:
        """Flush and describe where the files stand (a checkpoint's recorder part)."""
        self.flush()
        assert self._csv is not None
        table = self.table()
        return {
            "csv_position": list(self._csv.position()),
            "kept_time": table.time,
            "kept_rows": np.column_stack([table[n] for n in table.names()])
            if table.names()
            else np.zeros((len(table), 0)),
        }

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
