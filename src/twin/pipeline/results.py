"""The results table of a sweep: one row per point, inputs and outputs, on disk as it grows.

``results.parquet`` and ``results.csv`` (for spreadsheets) are rewritten whole, atomically
(temporary file, then :func:`os.replace`), at most about once a second while results arrive
and once at the end, so a killed sweep leaves a complete table of every point that finished
up to the last write, never half a file. Rewriting whole files keeps both formats plain
(no appended Parquet parts to merge); the interval grows with the time a write takes, so
writing never costs more than a small share of a long sweep.

``sweep.json`` records what the folder holds: the sweep file, and under ``inputs`` a digest
of everything that decides a row by name (:mod:`twin.pipeline.provenance`). ``--resume``
reads the table back and runs only the points it lacks, after checking every input is the
same (else one line names what changed) and that the table is this study's (a damaged
``sweep.json`` or table, a missing column, a point outside the design are each one line).

The rows are kept in memory column by column, numbers as packed 8-byte floats (not a dict
per row), so a 100 000-point sweep's client holds a few MB of them, not hundreds.

Columns: ``point`` (index), ``seed``, the design's keys, ``status`` (``ok``/``failed``),
``error`` (one line, empty when ok), then the figures in name order; failed points have NaN
figures. Rows are sorted by point, so two runs of a sweep give equal tables whatever the
number of workers or the order results came back in.
"""

from __future__ import annotations

import json
import math
import time
from array import array
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from twin.errors import ConfigError
from twin.files import write_atomic
from twin.pipeline.provenance import changed

TABLE = "results.parquet"
CSV = "results.csv"
META = "sweep.json"
FIXED_COLUMNS = ("point", "seed")
STATUS_COLUMNS = ("status", "error")
#: the longest sweep.json a resume reads (a record of a few hundred files is a few tens of KB)
MAX_META_BYTES = 4 * 2**20


class _Columns:
    """Rows stored column by column: floats packed in an :class:`array.array`, anything else
    in a list; a row's position by its point."""

    def __init__(self) -> None:
        self.pos: dict[int, int] = {}
        self.cols: dict[str, array[float] | list[Any]] = {}
        self.n = 0

    def put(self, row: dict[str, Any]) -> None:
        point = int(row["point"])
        at = self.pos.get(point)
        if at is None:
            at = self.pos[point] = self.n
            self.n += 1
            for col in self.cols.values():
                col.append(math.nan if isinstance(col, array) else None)
        for key, value in row.items():
            col = self.cols.get(key)
            if col is None:
                numeric = isinstance(value, float) or value is None
                col = array("d", [math.nan] * self.n) if numeric else [None] * self.n
                self.cols[key] = col
            if isinstance(col, array):
                if value is None:
                    value = math.nan
                elif not isinstance(value, float):
                    col = self.cols[key] = [None if math.isnan(v) else v for v in col]
            col[at] = value

    def value(self, point: int, key: str) -> Any:
        at = self.pos.get(point)
        col = self.cols.get(key)
        return None if at is None or col is None else col[at]

    def frame(self) -> pd.DataFrame:
        data = {
            k: np.frombuffer(c, dtype=float).copy() if isinstance(c, array) else list(c)
            for k, c in self.cols.items()
        }
        return pd.DataFrame(data)


class ResultStore:
    """The rows of one sweep folder, kept in memory and written out as they arrive.

    ``size`` is the number of points of the study (a resumed table holding a point outside
    ``range(size)`` is not its table); ``meta["inputs"]`` the study's record of what decides
    its rows (:mod:`twin.pipeline.provenance`)."""

    def __init__(
        self, out: Path, names: Iterable[str], meta: dict[str, Any], *, resume: bool, size: int | None = None
    ) -> None:
        self.out = out
        self.names = list(names)
        self.meta = meta
        self.size = size
        self._rows = _Columns()
        self.write_s = 0.0
        self._dirty = False
        self._last = 0.0
        self._interval = 1.0
        #: the folder held this study already (``--resume``): its outputs were checked then
        self.resumed = False
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
        old = _read_meta(meta_path)
        if "inputs" in self.meta:
            what = changed(old.get("inputs"), self.meta["inputs"])
            if what is None and old.get("fingerprint") != self.meta.get("fingerprint"):
                what = "the design changed since it ran"
        else:
            what = None if old.get("fingerprint") == self.meta.get("fingerprint") else "its inputs changed"
        if what is not None:
            raise ConfigError(
                f"holds another study ({what}): resume it with its own inputs, or choose another --out",
                source=str(self.out),
                key="--resume",
            )
        self.resumed = True
        if (self.out / TABLE).is_file():
            for row in self._read_table().to_dict("records"):
                self._rows.put(row)

    def _read_table(self) -> pd.DataFrame:
        """The table a resume continues, checked: this study's columns and points."""
        path = self.out / TABLE
        try:
            table = pd.read_parquet(path)
        except Exception as exc:  # pyarrow raises its own kinds for every damage
            raise ConfigError(
                f"not a results table ({type(exc).__name__}): remove it to run every point again",
                source=str(path),
            ) from None
        missing = [c for c in (*FIXED_COLUMNS, *STATUS_COLUMNS) if c not in table.columns]
        if missing:
            raise ConfigError(f"no {missing[0]!r} column: not a sweep's results table", source=str(path))
        points = pd.to_numeric(table["point"], errors="coerce")
        bad = points.isna() | (points != points.round()) | (points < 0)
        if self.size is not None:
            bad |= points >= self.size
        if bad.any():
            shown = table["point"][bad].tolist()[0]
            bound = f"0 to {self.size - 1}" if self.size is not None else "a whole number >= 0"
            raise ConfigError(f"point {shown!r} is not a point of this study ({bound})", source=str(path))
        if points.duplicated().any():
            raise ConfigError(
                f"point {int(points[points.duplicated()].iloc[0])} appears twice", source=str(path)
            )
        status = table["status"]
        if not status.isin(["ok", "failed"]).all():
            shown = status[~status.isin(["ok", "failed"])].tolist()[0]
            raise ConfigError(f"status {shown!r} is neither 'ok' nor 'failed'", source=str(path))
        table["point"] = points.astype("int64")
        return table

    def start(self) -> None:
        """Create the folder and ``sweep.json`` (once the points can run)."""
        self.out.mkdir(parents=True, exist_ok=True)
        text = json.dumps(self.meta, indent=2) + "\n"
        write_atomic(self.out / META, lambda p: p.write_text(text, encoding="utf-8"))

    def discard(self) -> None:
        """Remove what :meth:`start` and :meth:`flush` wrote into a fresh folder (a sweep
        refused after it started leaves nothing that blocks the corrected one); a resumed
        folder is left as it is."""
        if self.resumed:
            return
        for name in (META, TABLE, CSV):
            (self.out / name).unlink(missing_ok=True)
        self._rows = _Columns()
        self._dirty = False

    @property
    def done(self) -> set[int]:
        """Indices of the points already in the table (ok or failed)."""
        return set(self._rows.pos)

    def __len__(self) -> int:
        return self._rows.n

    def status(self, point: int) -> str | None:
        """Point ``point``'s status (``ok``/``failed``), None when it has no row."""
        return self._rows.value(point, "status")

    def count_failed(self) -> int:
        """The rows whose status is not ``ok``."""
        return sum(1 for s in self._rows.cols.get("status", []) if s != "ok")

    def add(self, row: dict[str, Any]) -> None:
        """One point's row; written with the next :meth:`flush`."""
        self._rows.put(row)
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
        fixed = [*FIXED_COLUMNS, *self.names, *STATUS_COLUMNS]
        if self._rows.n == 0:
            return pd.DataFrame(columns=fixed)
        frame = self._rows.frame().sort_values("point", kind="stable")
        figures = sorted(c for c in frame.columns if c not in fixed)
        frame = frame.reindex(columns=[*fixed, *figures])
        frame["point"] = frame["point"].astype("int64")
        frame["error"] = frame["error"].fillna("").astype(str)
        for c in figures:
            frame[c] = frame[c].astype("float64")
        return frame.reset_index(drop=True)


def _read_meta(path: Path) -> dict[str, Any]:
    """A folder's ``sweep.json``, checked to be a JSON object (else one line naming it)."""
    try:
        if path.stat().st_size > MAX_META_BYTES:
            raise ValueError(f"larger than {MAX_META_BYTES // 2**20} MB")
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ConfigError(f"not a sweep's record ({str(exc)[:120]})", source=str(path)) from None
    if not isinstance(data, dict):
        raise ConfigError(
            f"not a sweep's record (a JSON {type(data).__name__}, not an object)", source=str(path)
        )
    return data
