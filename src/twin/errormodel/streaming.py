"""The error model on a record fed chunk by chunk: the same numbers as the whole record at once.

:func:`~twin.errormodel.evaluate.evaluate` holds every row and every result of a record in
memory. :class:`StreamingEvaluation` holds only what its numbers need:

* the rows of the robust (Hampel) filter's reach: a sample's cleaned value depends on the
  ``2 half_window`` samples either side (a moving median of deviations from a moving median), so
  each chunk is filtered with that many rows of the chunk before and the rows its windows
  reach past the end wait for the next chunk;
* the record's first row: every series is taken relative to it, so each chunk is evaluated
  with that row put in front (:func:`~twin.errormodel.evaluate.evaluate_rows`), which gives
  every row the numbers of the whole record;
* the load's history (:class:`~twin.errormodel.sources.LoadHistory`: the liner's creep
  depends on the whole load history, not on the first row only), carried from chunk to chunk;
* the rows within the drift window of the start and of the (current) end: the drifts are
  least-squares lines through exactly those rows (:func:`~twin.errormodel.factors.endpoints`),
  fitted when the record is over;
* running sums (each part's mean square, the spike count), and for the error-budget plot the
  extremes of each of at most :data:`PLOT_ROWS` buckets of rows (a stride that doubles as the
  record grows), so no spike is lost to the thinning;
* with a true-wear column, the four series the compensation's indexes read whole (time,
  reading change, compensated wear, true wear: 32 bytes a row), as the Frechet distance and the
  Ra fluctuation need every sample.

The per-sample numbers are bit for bit those of ``evaluate``, the drifts too; each part's RMS
differs from the whole record's only in the last bits (a running sum instead of numpy's
pairwise one).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin.errormodel.evaluate import (
    EvaluationConfig,
    compensation_summary,
    evaluate_rows,
    evaluation_signals,
    summarize,
)
from twin.errormodel.factors import FACTORS, Contribution, Measured
from twin.errormodel.sources import LoadHistory, hampel
from twin.errormodel.tester import tester_model
from twin.errors import ConfigError
from twin.signals.decimate import extreme_rows
from twin.signals.table import Block, Signal, SignalTable

__all__ = ["PLOT_ROWS", "Block", "StreamingEvaluation"]

#: the plot's rows are kept in at most this many buckets, of a stride that doubles
PLOT_ROWS = 2000
#: rows evaluated at a time (the input is collected to this many first): ~5 MB of arrays
CHUNK_ROWS = 1 << 14

Columns = dict[str, np.ndarray]


@dataclass
class _Ends:
    """The rows within ``window_s`` of the record's first time and of its latest time: the
    only rows the drifts' lines go through."""

    window_s: float
    head: list[Block] = field(default_factory=list)
    head_done: bool = False
    tail: Block | None = None
    t0: float | None = None

    def add(self, block: Block) -> None:
        if self.t0 is None:
            self.t0 = float(block.time[0])
        if not self.head_done:
            # the rows endpoints() takes for the start: t <= t[0] + window
            k = int(np.searchsorted(block.time, self.t0 + self.window_s, side="right"))
            if k:
                self.head.append(block.rows(slice(0, k)))
            self.head_done = k < len(block)
        joined = block if self.tail is None else Block.join([self.tail, block])
        # ... and for the end: t >= t[-1] - window (copies: the chunk's arrays are let go)
        k = int(np.searchsorted(joined.time, joined.time[-1] - self.window_s, side="left"))
        kept = joined.rows(slice(k, None))
        self.tail = Block(kept.time.copy(), {n: v.copy() for n, v in kept.columns.items()})

    def rows(self) -> Block:
        """Head and tail without the rows they share (a record shorter than two windows)."""
        head = Block.join(self.head)
        assert self.tail is not None
        after = self.tail.rows(self.tail.time > head.time[-1])
        return Block.join([head, after]) if len(after) else head


@dataclass
class _Thinned:
    """What the plot draws of the record, whatever its length: per bucket of ``stride`` rows
    (by index) its first and last row and every column's extremes
    (:func:`twin.signals.decimate.extreme_rows`; a spike between two rows of an even stride
    was lost). More than :data:`PLOT_ROWS` buckets double the stride: the extremes of two
    buckets joined are among the rows kept of each."""

    stride: int = 1
    kept: Block | None = None
    index: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def add(self, start: int, block: Block) -> None:
        idx = np.arange(start, start + len(block), dtype=np.int64)
        take = extreme_rows(idx // self.stride, block.columns.values())
        new = block.rows(take)
        new = Block(new.time.copy(), {n: v.copy() for n, v in new.columns.items()})
        self.kept = new if self.kept is None else Block.join([self.kept, new])
        self.index = np.concatenate([self.index, idx[take]])
        while self.index.size and int(self.index[-1]) // self.stride >= PLOT_ROWS:
            self.stride *= 2
            take = extreme_rows(self.index // self.stride, self.kept.columns.values())
            self.kept, self.index = self.kept.rows(take), self.index[take]

    def rows(self) -> Block:
        assert self.kept is not None
        return self.kept


class StreamingEvaluation:
    """The error model over a record fed in chunks (:meth:`feed`), its results given back in
    chunks as soon as they are final, and the summary at :meth:`finish`.

    ``signals`` are the input columns the error model reads that the record has (time apart),
    with their metadata; every fed chunk has exactly these. ``chunk_rows`` is how many rows are
    evaluated at a time (small in tests, to cross many chunk ends).
    """

    def __init__(self, cfg: EvaluationConfig, signals: list[Signal], *, chunk_rows: int = CHUNK_ROWS) -> None:
        self.cfg = cfg
        self.signals = {s.name: s for s in signals}
        self.model = tester_model()
        self.chunk_rows = max(1, chunk_rows)
        self.with_wear = bool(cfg.true_wear) and cfg.true_wear in self.signals
        self.outputs = evaluation_signals(with_true_wear=self.with_wear)
        self._reach = cfg.filter_reach  # rows either side a cleaned sample depends on
        self._pending: list[Block] = []
        self._pending_rows = 0
        self._buffer: Block | None = None  # rows filtered but not final, and their context
        self._at_start = True  # the buffer starts at the record's first row
        self._first: tuple[Block, np.ndarray, np.ndarray] | None = None  # row 0, its cleaned, spike
        self._done = 0  # rows evaluated
        self._ends = _Ends(cfg.window_s)
        self._thinned = _Thinned()
        self._squares = {f.name: 0.0 for f in FACTORS}
        self._spikes = 0
        self._wear: list[Block] = []
        self._history = LoadHistory() if cfg.load in self.signals and cfg.factor_on("loading") else None

    @property
    def rows(self) -> int:
        """Rows evaluated so far."""
        return self._done

    def feed(self, block: Block) -> Iterator[Block]:
        """Take rows of the record (times increasing); yields the result rows now final (time and
        the ``errormodel.*`` columns)."""
        if len(block):
            self._pending.append(block)
            self._pending_rows += len(block)
        if self._pending_rows >= self.chunk_rows:
            yield from self._filter(final=False)

    def finish(self) -> Iterator[Block]:
        """The last result rows; then :meth:`summary` is ready."""
        yield from self._filter(final=True)

    def _filter(self, *, final: bool) -> Iterator[Block]:
        parts = ([self._buffer] if self._buffer is not None else []) + self._pending
        self._pending, self._pending_rows = [], 0
        if not parts:
            return
        buf = Block.join(parts)
        cfg, reach = self.cfg, self._reach
        lo = 0 if self._at_start else reach
        hi = len(buf) if final else len(buf) - reach
        if not final and (hi <= lo or hi < reach):
            self._buffer = buf  # not enough rows yet to finish any
            return
        # the filter's windows are padded with the end values: right only at the record's ends,
        # elsewhere the rows outside [lo, hi) are context and their own values are not kept
        cleaned, spikes = hampel(
            buf.columns[cfg.reading], cfg.spike_half_window, cfg.spike_sigmas, cfg.spike_min
        )
        rows = buf.rows(slice(lo, hi))
        yield from self._evaluate(rows, cleaned[lo:hi], spikes[lo:hi])
        self._buffer = None if final else buf.rows(slice(hi - reach, None))
        self._at_start = False

    def _evaluate(self, rows: Block, cleaned: np.ndarray, spikes: np.ndarray) -> Iterator[Block]:
        for a in range(0, len(rows), self.chunk_rows):
            sl = slice(a, a + self.chunk_rows)
            yield self._evaluate_chunk(rows.rows(sl), cleaned[sl], spikes[sl])

    def _evaluate_chunk(self, rows: Block, cleaned: np.ndarray, spikes: np.ndarray) -> Block:
        if self._first is None:
            self._first = (rows.rows(slice(0, 1)), cleaned[:1].copy(), spikes[:1].copy())
        first, c0, s0 = self._first
        # the record's first row in front: each series is taken relative to it
        with_first = Block.join([first, rows])
        table = SignalTable(time=with_first.time)
        for name, values in with_first.columns.items():
            table.add(self.signals[name], values)
        history = None
        if self._history is not None:
            # the rows' history carried on from the chunk before; the first row's is zero (the
            # creep starts at the zero)
            h = self._history.feed(rows.time, rows.columns[self.cfg.load])
            history = np.concatenate([np.zeros((h.shape[0], 1)), h], axis=1)
        m = Measured.read(table, self.cfg, self.model, (np.r_[c0, cleaned], np.r_[s0, spikes]), history)
        contributions, columns = evaluate_rows(m)
        results = Block(rows.time, {f"errormodel.{k}": v[1:] for k, v in columns.items()})
        self._account(rows, cleaned, spikes, contributions, results)
        self._done += len(rows)
        return results

    def _account(
        self,
        rows: Block,
        cleaned: np.ndarray,
        spikes: np.ndarray,
        contributions: dict[str, Contribution],
        results: Block,
    ) -> None:
        """What the summary and the plot keep of these rows."""
        for name, c in contributions.items():
            self._squares[name] += float(np.sum(c.e_z[1:] ** 2))
        self._spikes += int(spikes.sum())
        kept = {**rows.columns, **results.columns, "_cleaned": cleaned, "_spikes": spikes.astype(float)}
        self._ends.add(Block(rows.time, kept))
        plotted = {n: v for n, v in kept.items() if n in self._plot_columns}
        self._thinned.add(self._done, Block(rows.time, plotted))
        if self.with_wear:
            wear = rows.columns[self.cfg.true_wear] - self._first_value(self.cfg.true_wear)
            cols = results.columns
            self._wear.append(
                Block(
                    rows.time,
                    {
                        "raw": cols["errormodel.reading_change"],
                        "comp": cols["errormodel.wear_compensated"],
                        "wear": wear,
                    },
                )
            )

    def _first_value(self, name: str) -> np.float64:
        assert self._first is not None
        return self._first[0].columns[name][0]

    @property
    def _plot_columns(self) -> set[str]:
        return {
            self.cfg.reading,
            "errormodel.e_z",
            "errormodel.wear_compensated",  # what a lab wants of its record: the wear, compensated
            *(f.column for f in FACTORS),
            *self.cfg.temperatures.values(),
        }

    def plot_table(self) -> SignalTable:
        """What the error-budget plot draws: the extremes of each bucket of rows (see
        :class:`_Thinned`)."""
        rows = self._thinned.rows()
        meta = {s.name: s for s in [*self.signals.values(), *self.outputs]}
        table = SignalTable(time=rows.time)
        for name, values in rows.columns.items():
            table.add(meta[name], values)
        return table

    def summary(self) -> dict[str, Any]:
        """The numbers :func:`~twin.errormodel.evaluate.evaluate` gives, of the whole record."""
        if self._done < 2:
            raise ConfigError("the error model needs at least two samples", source="errormodel")
        ends = self._ends.rows()
        table = SignalTable(time=ends.time)
        for name in self.signals:
            table.add(self.signals[name], ends.columns[name])
        m = Measured.read(
            table, self.cfg, self.model, (ends.columns["_cleaned"], ends.columns["_spikes"] > 0)
        )
        contributions = {
            f.name: Contribution(
                ends.columns[f.column],
                {b: ends.columns[f"errormodel.{f.name}.{b}"] for b in self.model.bodies} if f.by_body else {},
            )
            for f in FACTORS
        }
        rms = {name: float(np.sqrt(s / self._done)) for name, s in self._squares.items()}
        out = summarize(m, contributions, ends.columns["errormodel.e_z"], rms=rms, spikes=self._spikes)
        if self.with_wear:
            w = Block.join(self._wear)
            out.update(
                compensation_summary(
                    w.time, self.cfg.ra_window_s, w.columns["raw"], w.columns["comp"], w.columns["wear"]
                )
            )
        return out
