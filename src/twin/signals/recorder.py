"""The recorder the master writes a run's rows to: a tee over sinks, plus the kept columns.

:class:`TeeRecorder` hands every chunk of rows to each of its sinks (signals.csv and
recording.rrd for a run folder, none for a sweep point) as it arrives, so a killed run keeps
what was recorded and memory stays flat in run length, and keeps in memory only the columns
the error model reads (``keep``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol

import numpy as np

from twin.signals.table import Block, Signal, SignalTable

__all__ = ["FLUSH_ROWS", "FLUSH_SECONDS", "RowSink", "TeeRecorder"]

#: rows are written to disk at least this often (rows) ...
FLUSH_ROWS = 4096
#: ... and at least this often (wall seconds): a killed run loses at most this much
FLUSH_SECONDS = 5.0


class RowSink(Protocol):
    """What the recorder hands rows to: the first two events of a run's sink
    (:class:`twin.outputs.sink.Sink` adds how the run ends)."""

    def open(self, signals: list[Signal]) -> None:
        """The recorded columns, before the first block."""
        ...

    def write(self, block: Block) -> None:
        """Rows of every recorded column, in time order."""
        ...

    def checkpoint(self) -> dict[str, Any]:
        """Where its file stands, for a run resumed from a checkpoint (empty: nothing to say)."""
        ...


def _keep_nothing(name: str) -> bool:
    return False


class TeeRecorder:
    """Rows to every sink, in chunks, and the kept columns in memory (:meth:`table`).

    Rows are buffered and handed on every :data:`FLUSH_ROWS` rows or :data:`FLUSH_SECONDS`
    of wall time, whichever comes first (each write to the recording costs per column, so
    writing every small batch would cost more than the simulation). ``resume`` is a
    checkpoint's recorder part: the kept rows up to the checkpoint (the sinks were made to
    continue their files). :attr:`write_s` is the wall time the sinks took.

    The sinks are opened here and handed rows, but not closed: :meth:`close` (the master's
    end of the run) only hands on what is buffered, the sinks close with the run's outcome.
    While the run goes, a chunk is written by a thread of its own (:meth:`append`), so that
    formatting and sending it goes on while the co-simulation steps (the compiled stepper and
    Arrow's CSV writer leave Python's lock free): one chunk at a time, the one before waited
    for (and its error raised, the rows after it dropped, as a write that failed at once
    would leave them) before the next is handed on. :meth:`flush` and :meth:`checkpoint`
    write every row before they return, and so does :meth:`close` without ``hold_last``, so a
    sink is never asked where it stands while a chunk is being written, nor closed or failed
    after a flush.

    With ``hold_last``, :meth:`close` of a run none of whose rows went to the sinks yet (all
    of them came within :data:`FLUSH_ROWS` and :data:`FLUSH_SECONDS`: a short run, like the
    paper's replay) keeps them for the caller's :meth:`flush` instead: ``twin run`` hands
    them on once the error model has run and the plots are sent, so that writing them, and
    loading rerun with the first of them (:mod:`twin.outputs.recording_sink`), overlaps the
    drawing. A longer run's files are open by then and its last rows cheap to write: they are
    handed on at once, not held beside the error model's columns (which would raise a long
    run's peak memory), and written by the thread while the error model runs; the caller's
    :meth:`flush` (before any sink closes, and on the way out of a failure) waits for them.
    """

    def __init__(
        self,
        sinks: Sequence[RowSink] = (),
        *,
        keep: Callable[[str], bool] = _keep_nothing,
        resume: Mapping[str, Any] | None = None,
        hold_last: bool = False,
    ) -> None:
        self.sinks = list(sinks)
        self.keep = keep
        self.resume = resume
        self.hold_last = hold_last
        self.signals: list[Signal] = []
        self.write_s = 0.0
        self._kept: list[int] = []
        self._times: list[np.ndarray] = []
        self._rows: list[np.ndarray] = []
        self._pending_t: list[np.ndarray] = []
        self._pending: list[np.ndarray] = []
        self._pending_n = 0
        self._last_flush = time.monotonic()
        self._handed_on = False
        #: the thread writing the chunk handed on last (append), and what it raised
        self._writer: threading.Thread | None = None
        self._write_error: BaseException | None = None

    def open(self, signals: list[Signal]) -> None:
        """The master's columns: open every sink with them, pick the kept ones."""
        start = time.perf_counter()
        self.signals = list(signals)
        for sink in self.sinks:
            sink.open(self.signals)
        self._kept = [c for c, s in enumerate(self.signals) if self.keep(s.name)]
        if self.resume is not None:
            self._times = [np.array(self.resume["kept_time"])]
            self._rows = [np.array(self.resume["kept_rows"])]
        self.write_s += time.perf_counter() - start

    def append(self, times: np.ndarray, rows: np.ndarray) -> None:
        """One batch of rows from the master (its arrays are reused: copy what is kept)."""
        if self.sinks:
            self._pending_t.append(np.array(times))
            self._pending.append(np.array(rows))
            self._pending_n += len(times)
        self._times.append(np.array(times))
        self._rows.append(np.array(rows[:, self._kept]))
        if self._pending_n >= FLUSH_ROWS or time.monotonic() - self._last_flush >= FLUSH_SECONDS:
            self._hand_on(wait=False)

    def flush(self) -> None:
        """Hand the buffered rows to every sink as one block, written when this returns (once:
        a sink that fails on it is not handed it again by the next flush)."""
        self._hand_on(wait=True)

    def _hand_on(self, *, wait: bool) -> None:
        """The buffered rows to the sinks: in a thread (``wait`` False; see the class), or
        here. Either way the chunk written before is waited for first."""
        start = time.perf_counter()
        try:
            self._settle()
            if not self._pending_n:
                return
            block = self._block()
            self._handed_on = True
            if wait:
                try:
                    self._write(block)
                finally:
                    self._last_flush = time.monotonic()
                return
            self._writer = threading.Thread(
                target=self._write_caught, args=(block,), name="write rows", daemon=True
            )
            self._writer.start()
        finally:
            self.write_s += time.perf_counter() - start

    def _block(self) -> Block:
        rows = np.concatenate(self._pending)
        block = Block(
            np.concatenate(self._pending_t), {s.name: rows[:, c] for c, s in enumerate(self.signals)}
        )
        self._pending_t, self._pending, self._pending_n = [], [], 0
        return block

    def _write(self, block: Block) -> None:
        for sink in self.sinks:
            sink.write(block)

    def _write_caught(self, block: Block) -> None:
        """:meth:`_write` in the writer thread: what it raises is raised by :meth:`_settle`."""
        try:
            self._write(block)
        except BaseException as exc:  # handed to the main thread as it is
            self._write_error = exc
        finally:
            self._last_flush = time.monotonic()

    def _settle(self) -> None:
        """Wait for the chunk being written; raise what its writing raised, the rows buffered
        since dropped (a run whose write failed writes nothing after it)."""
        writer, self._writer = self._writer, None
        if writer is not None:
            writer.join()
        error, self._write_error = self._write_error, None
        if error is not None:
            self._pending_t, self._pending, self._pending_n = [], [], 0
            raise error

    def close(self) -> None:
        """The master is done: hand on what is buffered (the sinks stay open for the outcome),
        unless ``hold_last`` holds it for the caller's :meth:`flush` (see the class). With
        ``hold_last`` the caller flushes before it closes the sinks in any case: a run whose
        rows went to the sinks already has its last ones written meanwhile, in the thread."""
        if not self.hold_last:
            self.flush()
        elif self._handed_on:
            # a long run's last rows: written by the writer thread while the caller goes on
            # (the error model); the caller's flush() waits for them before the sinks close
            self._hand_on(wait=False)

    def checkpoint(self) -> dict[str, Any]:
        """Flush, and describe where every file stands and the kept rows (a checkpoint's
        recorder part): each sink that can continue its file says where it stands."""
        self.flush()
        part: dict[str, Any] = {}
        for sink in self.sinks:
            part.update(sink.checkpoint())
        table = self.table()
        part["kept_time"] = table.time
        part["kept_rows"] = (
            np.column_stack([table[n] for n in table.names()]) if table.names() else np.zeros((len(table), 0))
        )
        return part

    def table(self) -> SignalTable:
        """The kept columns of every row recorded so far (views of the recorder's own copy,
        which is kept as one piece from now: the run's kept rows are in memory once)."""
        times = np.concatenate(self._times) if self._times else np.zeros(0)
        rows = np.concatenate(self._rows) if self._rows else np.zeros((0, len(self._kept)))
        self._times, self._rows = [times], [rows]
        table = SignalTable(times)
        for j, c in enumerate(self._kept):
            table.add(self.signals[c], rows[:, j])
        return table
