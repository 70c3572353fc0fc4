"""Where the recorded rows go (libcosim's observers): the :class:`Recorder` protocol and the
in-memory recorder, and the row buffer of one batch."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, Protocol

import numpy as np

from twin.config.spec import NS_PER_S
from twin.cosim.plan import Plan
from twin.signals.table import Signal as SignalMeta
from twin.signals.table import SignalTable


class Recorder(Protocol):
    """Where recorded rows go, chunk by chunk, while the run goes."""

    def open(self, signals: list[SignalMeta]) -> None: ...
    def append(self, times: np.ndarray, rows: np.ndarray) -> None: ...
    def close(self) -> None: ...


class MemoryRecorder:
    """Keeps every row in memory (tests, short runs); :meth:`table` gives the SignalTable."""

    def __init__(self) -> None:
        self.signals: list[SignalMeta] = []
        self._times: list[np.ndarray] = []
        self._rows: list[np.ndarray] = []

    def open(self, signals: list[SignalMeta]) -> None:
        self.signals = list(signals)

    def append(self, times: np.ndarray, rows: np.ndarray) -> None:
        self._times.append(np.array(times, dtype=np.float64))
        self._rows.append(np.array(rows, dtype=np.float64))

    def close(self) -> None:
        pass

    def table(self) -> SignalTable:
        n = len(self.signals)
        times = np.concatenate(self._times) if self._times else np.zeros(0)
        rows = np.concatenate(self._rows) if self._rows else np.zeros((0, n))
        table = SignalTable(times)
        for c, meta in enumerate(self.signals):
            table.add(meta, rows[:, c])
        return table


@contextmanager
def batch_rows(plan: Plan, recorder: Recorder, counters: Any, k0: int, k1: int) -> Iterator[np.ndarray]:
    """A row buffer for the output ticks among ``k0`` to ``k1 - 1``; the rows the loop recorded
    in it (``counters.rows``) go to ``recorder`` afterwards, also when the loop failed."""
    out_every, n_cols = plan.out_every, len(plan.columns)
    first_row = -(-k0 // out_every)
    n_rows = max(0, -(-k1 // out_every) - first_row)
    rows = np.zeros((max(n_rows, 1), max(n_cols, 1)))
    counters.rows = 0
    try:
        yield rows
    finally:
        done = int(counters.rows)
        if done:
            ticks = first_row + np.arange(done, dtype=np.int64)
            recorder.append(ticks * plan.scenario.output_interval_ns / NS_PER_S, rows[:done, :n_cols])


__all__ = ["MemoryRecorder", "Recorder", "batch_rows"]
