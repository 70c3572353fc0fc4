"""``recording.rrd``: the run as a rerun recording (the module of the twin that writes with rerun;
a run's sink for it, which loads this module with its first rows, is
:mod:`twin.outputs.recording_sink`).

Layout of the recording:

* one timeline ``sim_time``, a *duration* timeline (simulation seconds shown as time since
  start, not as wall-clock dates); values are rounded to whole nanoseconds;
* one entity per signal, ``/<subsystem>/<variable>`` (``thermal.t_base`` of subsystem
  ``thermal`` -> ``/thermal/t_base``), holding ``Scalars`` sent column-wise: the Arrow
  arrays ``send_columns`` sends, built on the values' buffers and handed to rerun's native
  sender (one call per column and chunk, never one ``log`` per sample);
* lengths in µm: a signal in metres is recorded times 1e6 (the twin's lengths are microns of
  drift and wear; a view in metres shows 0.00001); every other signal in its own unit;
* static per entity: ``SeriesLines`` with the legend name ``"<variable> [<unit>]"`` (rerun
  has no unit field for scalars) and ``AnyValues`` with ``signal``, ``unit`` (as recorded),
  ``si_unit`` and ``to_si`` (the factor back to SI), ``description``;
* a default blueprint saved in the file when it is closed (when every series' magnitude is
  known): on top an "Error budget" time-series view (µm) with the ``budget_columns`` and, for
  a run of the tester, a 3D view of it (:mod:`twin.outputs.scene3d`, entities under
  ``/tester``); below, a grid with one time-series view per subsystem and unit (``thermal
  [K]``, ``thermal [J]``, ...), so no view mixes units, split further where a series' peak is
  more than :data:`MAGNITUDE_RATIO` times another's (``mechanics [N] up to 2e+05`` beside
  ``mechanics [N] up to 20.3``: on one axis the smaller would be a flat line); the budget's
  parts that small get views of their own, and the budget's columns are in no other view.

Written against rerun-sdk 0.41 (``rr.Scalars``, ``rr.SeriesLines``, ``rr.TimeColumn``,
``rerun.chunk.RrdReader``). No viewer is spawned and nothing goes over the network: the
stream's only sink is the file.
"""

from __future__ import annotations

import contextlib
import errno
import os
import uuid
from collections.abc import Mapping, Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

# rerun's file writer logs its own failed writes (three lines on stderr, read from RUST_LOG when
# rerun loads); the twin reports a failed recording in one line (RecordingWriter.close), so
# those two loggers keep quiet, unless the user sets RUST_LOG
os.environ.setdefault("RUST_LOG", "warn,re_log_encoding::rrd=off,re_sdk::recording_stream=off")

import rerun as rr  # after RUST_LOG is set
import rerun.blueprint as rrb

from twin.outputs.pandas_free import without_pandas
from twin.outputs.sink import ClosesOnExit
from twin.signals.table import Signal, SignalTable

if TYPE_CHECKING:
    from twin.outputs.scene3d import TesterScene

__all__ = [
    "BUDGET_VIEW_NAME",
    "SCENE_VIEW_NAME",
    "TIMELINE",
    "RecordingWriter",
    "entity_path",
    "read_recording",
    "recorded_unit",
    "write_recording",
]

TIMELINE = "sim_time"
BUDGET_VIEW_NAME = "Error budget"
SCENE_VIEW_NAME = "Tester (3D)"
#: units recorded in another unit: SI unit -> (recorded unit, factor from SI)
_DISPLAY_UNITS = {"m": ("µm", 1e6)}
#: a long chunk is sent in slices of this many rows (RecordingWriter.append), each written before
#: the next is sent, so that rerun never holds a whole long chunk encoded at once
CHUNK_ROWS = 8192


def _variable(signal: Signal) -> str:
    prefix = f"{signal.subsystem}."
    return signal.name[len(prefix) :] if signal.name.startswith(prefix) else signal.name


def entity_path(signal: Signal) -> str:
    """Entity path of a signal: ``/<subsystem>/<variable>``.

    ``<variable>`` is the name without its ``"<subsystem>."`` prefix; a name from another
    prefix keeps its full text (``/mechanics/loading.f_radial``) so paths cannot collide.
    Characters rerun treats specially (blanks, brackets) are escaped.
    """
    return str(rr.new_entity_path([signal.subsystem, _variable(signal)]))


def recorded_unit(signal: Signal) -> tuple[str, float]:
    """The unit a signal is recorded in and the factor from its own unit (µm and 1e6 for m)."""
    return _DISPLAY_UNITS.get(signal.unit, (signal.unit, 1.0))


def _series_label(signal: Signal) -> str:
    # Rerun scalars have no unit field: the legend carries it.
    unit = recorded_unit(signal)[0]
    return f"{_variable(signal)} [{unit}]" if unit else _variable(signal)


#: series whose magnitudes differ by more than this share no view: on one Y axis the smaller
#: is a flat line (a 200 kN load beside a 20 N force, a 4850 µm reading beside sub-µm vibration)
MAGNITUDE_RATIO = 100.0


def by_magnitude(names: Sequence[str], peaks: Mapping[str, float]) -> list[list[str]]:
    """``names`` in groups whose peaks (largest finite |value|) are within
    :data:`MAGNITUDE_RATIO` of the group's largest, largest group first, each in the order
    given. A series that never left zero (or was never sent) joins the smallest group: a flat
    zero line squashes nothing."""
    ranked = sorted((n for n in names if peaks.get(n, 0.0) > 0.0), key=lambda n: -peaks[n])
    groups: list[list[str]] = []
    for name in ranked:
        if groups and peaks[name] * MAGNITUDE_RATIO >= peaks[groups[-1][0]]:
            groups[-1].append(name)
        else:
            groups.append([name])
    zero = [n for n in names if peaks.get(n, 0.0) <= 0.0]
    if zero:
        if groups:
            groups[-1].extend(zero)
        else:
            groups.append(zero)
    order = {n: i for i, n in enumerate(names)}
    return [sorted(g, key=order.__getitem__) for g in groups]


def _peak(group: Sequence[str], peaks: Mapping[str, float]) -> float:
    return max(peaks.get(n, 0.0) for n in group)


def _view_name(base: str, unit: str, peak: float, split: bool) -> str:
    name = f"{base} [{unit}]" if unit else base
    return f"{name} up to {peak:.3g}" if split else name


def _blueprint(
    signals: Sequence[Signal],
    paths: Mapping[str, str],
    budget: Sequence[str],
    scene: bool,
    peaks: Mapping[str, float],
) -> rrb.Blueprint:
    units = {s.name: recorded_unit(s)[0] for s in signals}

    def view(name: str, group: list[str]) -> rrb.TimeSeriesView:
        return rrb.TimeSeriesView(origin="/", contents=[f"+ {paths[n]}" for n in group], name=name)

    def views(base: str, unit: str, members: list[str]) -> list[rrb.TimeSeriesView]:
        groups = by_magnitude(members, peaks)
        split = len(groups) > 1
        return [view(_view_name(base, unit, _peak(g, peaks), split), g) for g in groups]

    top: list[rrb.View] = []
    smaller: list[rrb.View] = []
    if budget:
        # the budget's largest parts are the top view; parts a hundred times smaller get views
        # of their own, first in the grid
        first, *rest = by_magnitude(list(budget), peaks)
        top.append(view(BUDGET_VIEW_NAME, first))
        smaller = [
            view(_view_name(f"{BUDGET_VIEW_NAME}, smaller parts", "µm", _peak(g, peaks), True), g)
            for g in rest
        ]
    # the budget's columns are in its views only, never again in the grid below
    groups: dict[tuple[str, str], list[str]] = {}
    for s in signals:
        if s.name not in budget:
            groups.setdefault((s.subsystem, units[s.name]), []).append(s.name)
    # one view per subsystem, unit and magnitude: a view's one Y axis never mixes K with J or
    # µm with N, nor a series with one a hundred times smaller
    per_unit = [v for (sub, unit), members in groups.items() for v in views(sub, unit, members)]
    grid = rrb.Grid(*smaller, *per_unit)
    if scene:
        from twin.outputs.scene3d import ROOT

        top.append(rrb.Spatial3DView(origin=ROOT, name=SCENE_VIEW_NAME))
    if top:
        # The error budget (and where it comes from) is what a run is for: first, 60 % of the height.
        first = top[0] if len(top) == 1 else rrb.Horizontal(*top, column_shares=[3, 2])
        root: rrb.Container = rrb.Vertical(first, grid, row_shares=[3, 2])
    else:
        root = grid
    return rrb.Blueprint(root, rrb.TimePanel(timeline=TIMELINE), collapse_panels=False)


def _to_duration(time_s: np.ndarray) -> np.ndarray:
    # Round to whole ns: rerun's own float conversion truncates (0.3 s -> 299999999 ns).
    return np.rint(np.asarray(time_s, dtype=np.float64) * 1e9).astype(np.int64).astype("timedelta64[ns]")


def _bindings() -> ModuleType | None:
    """rerun's native module: what ``rr.send_columns`` hands its Arrow arrays to; None where
    this rerun has no ``send_arrow_chunk`` there (it is not rerun's public API: a release that
    moves it leaves the recording to ``send_columns``, slower, the same file)."""
    try:
        import rerun_bindings
    except ImportError:
        return None
    return rerun_bindings if hasattr(rerun_bindings, "send_arrow_chunk") else None


def _scalars_descriptor() -> rr.ComponentDescriptor:
    """The descriptor of ``rr.Scalars``' scalars, as ``rr.Scalars.columns`` gives it."""
    (column,) = rr.Scalars.columns(scalars=np.zeros(1))
    return column.component_descriptor()


def _offsets(n: int) -> pa.Array:
    """The offsets of ``n`` one-value lists (0, 1, ..., n), as an Arrow int32 array."""
    return pa.Array.from_buffers(pa.int32(), n + 1, [None, pa.py_buffer(np.arange(n + 1, dtype=np.int32))])


def _scalars(offsets: pa.Array, values: np.ndarray) -> pa.ListArray:
    """One series' values as ``rr.Scalars.columns(scalars=values)`` sends them: a list of one
    float64 per row (the same Arrow array, built on the values' buffer without a copy per
    row and without rerun's conversions, which cost more than the sending)."""
    data = np.ascontiguousarray(values, dtype=np.float64)
    return pa.ListArray.from_arrays(
        offsets, pa.Array.from_buffers(pa.float64(), data.size, [None, pa.py_buffer(data)])
    )


class RecordingWriter(ClosesOnExit):
    """Stream a run to an ``.rrd`` file chunk by chunk (memory flat in run length).

    The blueprint needs every signal up front, hence ``signals``; each :meth:`append`
    sends one chunk per column. :meth:`close` (or leaving the ``with`` block) flushes and
    writes the file's footer; until then the file is incomplete. The footer's chunk index
    is the only state that grows with the run (a few dozen bytes per column and append).
    """

    def __init__(
        self,
        path: str | os.PathLike[str],
        signals: Sequence[Signal],
        *,
        app_id: str = "twin",
        recording_name: str | None = None,
        budget_columns: Sequence[str] | None = None,
        scene: TesterScene | None = None,
    ) -> None:
        self.path = Path(path)
        self.signals = list(signals)
        self.scene = scene
        self.scale = {s.name: recorded_unit(s)[1] for s in self.signals}
        self.paths = {s.name: entity_path(s) for s in self.signals}
        owner: dict[str, str] = {}
        for name, path_ in self.paths.items():
            if path_ in owner:
                raise ValueError(
                    f"signals '{owner[path_]}' and '{name}' both map to the rerun entity {path_}"
                )
            owner[path_] = name
        budget = list(budget_columns or [])
        unknown = [n for n in budget if n not in self.paths]
        if unknown:
            raise ValueError(f"budget columns {unknown} are not among the signals")
        self.rows = 0
        #: whether rows were sent that rerun may not have written yet (see append)
        self._unwritten = False
        # An explicit stream (not rr.init's global one) with a fresh id: several recordings
        # can be written from one process without mixing.
        self._rec: rr.RecordingStream | None = rr.RecordingStream(app_id, recording_id=uuid.uuid4())
        self.budget = budget
        #: each signal's largest finite |value| sent (as recorded): the blueprint, sent when
        #: the recording closes, keeps series of different magnitudes apart
        self.peaks = {name: 0.0 for name in self.paths}
        self._rec.save(self.path)
        # rerun's conversions to Arrow, here and in append and close, without pandas
        with without_pandas():
            #: the component every series is sent as (that of ``rr.Scalars.columns``)
            self._scalars = _scalars_descriptor()
            self._describe(recording_name)

    def _describe(self, recording_name: str | None) -> None:
        """The recording's name, and each entity's legend and description (static)."""
        assert self._rec is not None
        name = recording_name or self.path.resolve().parent.name or self.path.stem
        self._rec.send_recording_name(name)
        for s in self.signals:
            path_ = self.paths[s.name]
            unit, scale = recorded_unit(s)
            self._rec.log(
                path_,
                rr.SeriesLines(names=_series_label(s)),
                rr.AnyValues(
                    signal=s.name, unit=unit, si_unit=s.unit, to_si=1.0 / scale, description=s.description
                ),
                static=True,
                strict=True,
            )

    def append(
        self, time_chunk: np.ndarray, columns_chunk: Mapping[str, np.ndarray], *, partial: bool = False
    ) -> None:
        """Send one chunk: ``time_chunk`` (s) and one array per signal name.

        With ``partial``, the chunk may carry only some of the signals (e.g. the error model's
        columns, computed after the run, sent on the same timeline). A chunk longer than
        :data:`CHUNK_ROWS` goes in slices of that many rows: the arrow copies rerun makes stay
        bounded, and so does the time rerun's writer spends on one slice without writing
        (:func:`_flush` reads a file that stops growing as a writer that stopped).

        Before a slice is sent, what was sent before it is waited for (written to the file):
        rerun queues what it is sent without a bound, so a run whose rows come faster than
        rerun's writer encodes them (about 20 bytes kept per recorded value until written)
        would otherwise hold its recording in memory. Within a run the previous rows were
        written while the co-simulation went on, and the wait is none.
        """
        if self._rec is None:
            raise ValueError(f"{self.path} is closed")
        t = np.asarray(time_chunk, dtype=np.float64)
        arrays = self._checked(t, columns_chunk, partial)
        if t.size == 0:
            return
        with without_pandas():
            self._send(t, arrays)

    def _send(self, t: np.ndarray, arrays: Mapping[str, np.ndarray]) -> None:
        """The checked chunk to rerun, in slices (see :meth:`append`)."""
        assert self._rec is not None
        for name, values in arrays.items():
            finite = np.abs(values[np.isfinite(values)])
            if finite.size:
                self.peaks[name] = max(self.peaks[name], float(finite.max()))
        bindings = _bindings()
        native = self._rec.to_native() if bindings is not None and hasattr(self._rec, "to_native") else None
        for start in range(0, t.size, CHUNK_ROWS):
            part = slice(start, start + CHUNK_ROWS)
            if self._unwritten:
                self._settle(self._rec)
            # One time column shared by every entity of the slice, made once
            index = rr.TimeColumn(TIMELINE, duration=_to_duration(t[part]))
            timelines = {TIMELINE: index.as_arrow_array()}
            offsets = _offsets(t[part].size)
            for name, path_ in self.paths.items():
                if name not in arrays:
                    continue
                if bindings is None or native is None:
                    columns = rr.Scalars.columns(scalars=arrays[name][part])
                    self._rec.send_columns(path_, indexes=[index], columns=columns, strict=True)
                    continue
                bindings.send_arrow_chunk(
                    path_,
                    timelines=timelines,
                    components={self._scalars: _scalars(offsets, arrays[name][part])},
                    recording=native,
                )
            self._unwritten = True
        self.rows += t.size

    def _checked(
        self, t: np.ndarray, columns_chunk: Mapping[str, np.ndarray], partial: bool
    ) -> dict[str, np.ndarray]:
        """The chunk's columns as recorded (float64, in the recorded unit), every one checked
        before any is sent, so a bad chunk leaves the recording untouched."""
        if t.ndim != 1:
            raise ValueError(f"time chunk must be 1-D, got shape {t.shape}")
        missing = [] if partial else [n for n in self.paths if n not in columns_chunk]
        extra = [n for n in columns_chunk if n not in self.paths]
        if missing or extra:
            raise ValueError(f"chunk columns do not match the signals: missing {missing}, unexpected {extra}")
        arrays = {
            name: np.asarray(columns_chunk[name], dtype=np.float64)
            for name in self.paths
            if name in columns_chunk
        }
        arrays = {name: v * self.scale[name] if self.scale[name] != 1.0 else v for name, v in arrays.items()}
        for name, values in arrays.items():
            if values.shape != t.shape:
                raise ValueError(f"column '{name}' has shape {values.shape}, time has {t.shape}")
        return arrays

    def close(self) -> None:
        """Flush and finalize the file (idempotent). A write that failed (a full disk) raises
        :class:`OSError` naming the file; what rerun wrote before it stays."""
        if self._rec is not None:
            with without_pandas():
                self._finish()

    def _finish(self) -> None:
        """The scene and the blueprint sent, everything written, the file's footer."""
        if self._rec is not None:
            rec, self._rec = self._rec, None
            if self.scene is not None:
                self.scene.send(rec, TIMELINE)
            # the default blueprint, now that every series' magnitude is known
            blueprint = _blueprint(self.signals, self.paths, self.budget, self.scene is not None, self.peaks)
            rec.send_blueprint(blueprint, make_active=True, make_default=True)
            self._settle(rec)
            # disconnect() closes the file sink, which writes the footer `rerun rrd verify` checks.
            rec.disconnect()

    def _settle(self, rec: rr.RecordingStream) -> None:
        """Wait until rerun has written everything sent so far (:func:`_flush`). A write that
        failed closes the writer and raises :class:`OSError` naming the file."""
        try:
            _flush(rec, self.path)
        except _Stuck as stuck:
            self._rec = None
            _abandon(rec)
            raise stuck.error from None
        except RuntimeError as exc:
            # rerun writes from its own thread and reports a failed write only as
            # "File-writer thread shut down prematurely"
            self._rec = None
            with contextlib.suppress(RuntimeError):
                rec.disconnect()
            raise _write_error(self.path, exc) from None
        self._unwritten = False


#: seconds one flush of a recording waits before the disk is looked at (a healthy flush of a
#: slice is far quicker; a longer one only costs a look) ...
FLUSH_CHECK_S = 1.0
#: ... and seconds the file may then go without growing before rerun's writer is taken for
#: one that stopped (it writes a slice of CHUNK_ROWS rows in milliseconds)
STALL_S = 8.0


class _Stuck(Exception):
    """rerun stopped writing a recording and will not say so; ``error`` names why."""

    def __init__(self, error: OSError) -> None:
        super().__init__(str(error))
        self.error = error


def _flush(rec: rr.RecordingStream, path: Path) -> None:
    """``rec.flush()`` that does not wait forever on a full disk.

    rerun-sdk 0.41 waits forever when its file writer stops on a failed write (a full disk)
    just after a flush was queued to it: that flush is never answered, and a second one may
    not even be queued. Found with gdb on runs whose disk filled while the recording's rows
    were written (about half of them hung at some disk sizes, whatever the order the twin
    wrote in). So the flush waits :data:`FLUSH_CHECK_S`; unanswered, the disk is asked
    without touching the recording (:func:`_full`: a file at the process's size limit, or a
    disk that refuses one byte of a new file beside it): a disk that can take nothing more
    means the flush can never be answered, and :class:`_Stuck` says why. Otherwise the flush
    is waited for again while the file grows. A file that did not grow for :data:`STALL_S`
    more is one nothing writes now, and one byte appended to it ourselves (cut off again)
    tells whether it can grow: if not, :class:`_Stuck`. A file that takes the byte is not that
    case (a process stopped and continued, a writer slow for another reason): the flush is
    waited for as rerun's always was, without a limit.
    """
    while True:
        try:
            size = path.stat().st_size
        except OSError:  # the file is gone (its folder moved): nothing to look at
            rec.flush()
            return
        try:
            rec.flush(timeout_sec=FLUSH_CHECK_S)
            return
        except RuntimeError as exc:
            if "timed out" not in str(exc):
                raise
        full = _full(path)
        if full is not None:
            raise _Stuck(full)
        if _grows(path, size, STALL_S):
            continue
        full = _probe(path)
        if full is None:
            rec.flush()
            return
        raise _Stuck(full)


def _grows(path: Path, size: int, within_s: float) -> bool:
    """Whether ``path`` is (or becomes, within ``within_s``) larger or smaller than ``size``."""
    import time

    deadline = time.monotonic() + within_s
    while True:
        try:
            if path.stat().st_size != size:
                return True
        except OSError:
            return True  # gone: not a writer stuck on a full disk
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)


def _abandon(rec: rr.RecordingStream) -> None:
    """Never flush the stuck ``rec`` again (see :func:`_flush`): each flush would wait forever.
    Its finalizer flushes it, and rerun's exit handler flushes every stream, so ``rec`` is
    kept alive to the end of the process (one reference that is never given back) and the
    exit handler is taken off (the process's other rerun streams are not flushed at exit
    either: better than an exit that never comes)."""
    import ctypes

    ctypes.pythonapi.Py_IncRef(ctypes.py_object(rec))
    rr.unregister_shutdown()


def _full(path: Path) -> OSError | None:
    """The error a write to ``path`` would end in now, found without writing into it (rerun
    may still be writing it): EFBIG for a file at the process's file-size limit, or the error
    of one byte written to a new file beside it and synced (ENOSPC, EDQUOT: a full disk); None
    when neither says the disk is full."""
    import resource

    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    try:
        if limit != resource.RLIM_INFINITY and path.stat().st_size >= limit:
            return _probe(path)  # a file at the limit cannot take the byte: nothing is written
    except OSError:
        return None
    beside = path.with_name(f".{path.name}.probe-{os.getpid()}")
    try:
        fd = os.open(beside, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        try:
            os.write(fd, b"\0")
            os.fsync(fd)
        finally:
            os.close(fd)
    except OSError as found:
        if found.errno in (errno.ENOSPC, errno.EDQUOT):
            found.filename = str(path)
            return found
        return None
    finally:
        with contextlib.suppress(OSError):
            beside.unlink()
    return None


def _probe(path: Path) -> OSError | None:
    """The error of a write to ``path`` now: one byte appended and cut off again (None when it
    could be written). Only where rerun does not write the file meanwhile."""
    try:
        size = path.stat().st_size
        with open(path, "ab") as f:
            f.write(b"\0")
            f.flush()
        os.truncate(path, size)
    except OSError as found:
        found.filename = str(path)
        return found
    return None


def _write_error(path: Path, exc: RuntimeError) -> OSError:
    """The OS error behind rerun's failed write (:func:`_probe`, its writer having stopped),
    since rerun's message does not carry it. A full disk or a file-size limit fails that byte
    too; anything else is reported with rerun's words."""
    return _probe(path) or OSError(errno.EIO, f"rerun could not write the recording ({exc})", str(path))


def write_recording(
    table: SignalTable,
    path: str | os.PathLike[str],
    *,
    app_id: str = "twin",
    recording_name: str | None = None,
    budget_columns: Sequence[str] | None = None,
) -> Path:
    """Write a whole :class:`SignalTable` to an ``.rrd`` file; returns ``path``."""
    signals = [table.meta[n] for n in table.names()]
    with RecordingWriter(
        path, signals, app_id=app_id, recording_name=recording_name, budget_columns=budget_columns
    ) as writer:
        writer.append(table.time, dict(table.columns))  # in slices of CHUNK_ROWS
    return Path(path)


def read_recording(path: str | os.PathLike[str]) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Read the scalar series of an ``.rrd`` back: entity path -> (sim_time in s, values as
    recorded: lengths in µm, see :func:`recorded_unit`).

    Meant for tests and quick checks (it loads everything); rows are sorted by time.
    """
    from rerun.chunk import RrdReader

    parts: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        if chunk.is_static or TIMELINE not in chunk.timeline_names:
            continue
        batch = chunk.to_record_batch()
        if "Scalars:scalars" not in batch.schema.names:
            continue
        ns = batch.column(TIMELINE).cast("int64").to_numpy(zero_copy_only=False)
        # Each row holds a list of scalars (one per series); ours hold exactly one.
        values = batch.column("Scalars:scalars").flatten().to_numpy(zero_copy_only=False)
        parts.setdefault(chunk.entity_path, []).append((ns / 1e9, np.asarray(values, dtype=np.float64)))
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for entity, pieces in parts.items():
        t = np.concatenate([p[0] for p in pieces])
        v = np.concatenate([p[1] for p in pieces])
        order = np.argsort(t, kind="stable")
        out[entity] = (t[order], v[order])
    return out
