"""The results table of a sweep: one row per point, inputs and outputs, on disk as it grows.

``results.parquet`` and ``results.csv`` (for spreadsheets) are rewritten whole, atomically
(temporary file, then :func:`os.replace`), at most about once a second while results arrive
and once at the end, so a killed sweep leaves a complete table of every point that finished
up to the last write, never half a file. Rewriting whole files keeps both formats plain
(no appended Parquet parts to merge); the interval grows with the time a write takes, so
writing never costs more than a small share of a long sweep.

``sweep.json`` records what the folder holds (the sweep file and a fingerprint of its
design); ``--resume`` reads the table back and runs only the points it lacks, after checking
the design is the same one.

Columns: ``point`` (index), ``seed``, the design's keys, ``status`` (``ok``/``failed``),
``error`` (one line, empty when ok), then the figures in name order; failed points have NaN
figures. Rows are sorted by point, so two runs of a sweep give equal tables whatever the
number of workers or the order results came back in.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import pandas as pd

from twin.errors import ConfigError
from twin.files import write_atomic

TABLE = "results.parquet"
CSV = "results.csv"
META = "sweep.json"
FIXED_COLUMNS = ("point", "seed")
STATUS_COLUMNS = ("status", "error")


class ResultStore:
    """The rows of one sweep folder, kept in memory and written out as they arrive."""

    def __init__(self, out: Path, names: Iterable[str], meta: dict[str, Any], *, resume: bool) -> None:
        self.out = out
        self.names = list(names)
        self.meta = meta
        self.rows: dict[int, dict[str, Any]] = {}
        self.write_s = 0.0
        self._dirty = False
        self._last = 0.0
        self._interval = 1.0
        self._read(resume)

    def _read(self, resume: bool) -> None:
        """The rows already there (``--resume``); refuses a folder holding another sweep."""
        meta_path = self.out / META
        if not meta_path.is_file():
            return
        if not resume:
            raise ConfigError(
                "already holds a sweep: --resume completes it, or choose another --out",
                source=str(self.out),
            )
        old = json.loads(meta_path.read_text(encoding="utf-8"))
        if old.get("fingerprint") != self.meta["fingerprint"]:
            raise ConfigError(
                "holds another design (the sweep file or its base changed): choose another --out",
                source=str(self.out),
            )
        if (self.out / TABLE).is_file():
            for row in pd.read_parquet(self.out / TABLE).to_dict("records"):
                self.rows[int(row["point"])] = row

    def start(self) -> None:
        """Create the folder and ``sweep.json`` (once the points can run)."""
        self.out.mkdir(parents=True, exist_ok=True)
        text = json.dumps(self.meta, indent=2) + "\n"
        write_atomic(self.out / META, lambda p: p.write_text(text, encoding="utf-8"))

    @property
    def done(self) -> set[int]:
        """Indices of the points already in the table (ok or failed)."""
        return set(self.rows)

    def add(self, row: dict[str, Any]) -> None:
        """One point's row; written with the next :meth:`flush`."""
        self.rows[int(row["point"])] = row
        self._dirty = True

    def flush(self, *, force: bool = False) -> None:
        """Write the table if something changed and the interval has passed (or ``force``)."""
        now = time.perf_counter()
        if not self._dirty or (not force and now - self._last < self._interval):
            return
        table = self.table()
        write_atomic(self.out / TABLE, lambda p: table.to_parquet(p, index=False))
        write_atomic(self.out / CSV, lambda p: table.to_csv(p, index=False))
        took = time.perf_counter() - now
        self.write_s += took
        self._last = time.perf_counter()
        self._interval = max(1.0, 10.0 * took)  # writing stays under ~10 % of the time
        self._dirty = False

    def table(self) -> pd.DataFrame:
        """Every row so far, sorted by point, columns in their fixed order."""
        records = [self.rows[i] for i in sorted(self.rows)]
        frame = pd.DataFrame.from_records(records)
        if frame.empty:
            return pd.DataFrame(columns=[*FIXED_COLUMNS, *self.names, *STATUS_COLUMNS])
        fixed = [*FIXED_COLUMNS, *self.names, *STATUS_COLUMNS]
        figures = sorted(c for c in frame.columns if c not in fixed)
        frame = frame.reindex(columns=[*fixed, *figures])
        frame["error"] = frame["error"].fillna("").astype(str)
        for c in figures:
            frame[c] = frame[c].astype("float64")
        return frame.reset_index(drop=True)
