"""``recording.rrd`` as a run's sink; the file is written by :mod:`twin.outputs.rerun_rec`.

Importing rerun (its hundreds of modules) takes a noticeable part of a short run. This module
does not import it: :class:`RecordingSink` loads :mod:`twin.outputs.rerun_rec`, and with it
rerun, when the first rows reach it (or the run ends without any). ``twin run`` hands a short
run's rows on only after the error model has run and the plots are sent
(:func:`twin.pipeline.stages.simulate`'s ``hold_last_rows``), so rerun loads while the plots'
own process draws (:mod:`twin.outputs.plot_process`), not before. A long run's first rows come
while it runs: its sink (``preload``) begins the import in a thread of its own when the run
opens its outputs (after its checks and the FMUs' set-up: a run that fails those never pays
it), so that it goes on while the co-simulation steps (the native stepper leaves Python's lock
free) instead of holding up the first rows.

A short run's sink whose plots that process draws (``hold``) keeps the rows handed to it once
the run's outputs begin (:meth:`RecordingSink.begin`: the rows the run held for them) and
writes the file when it closes, after the plots (:meth:`twin.outputs.run_folder.RunFolder.run_sinks`
orders it so): rerun still loads beside the drawing, but the recording's own memory (rerun's
writer, buffers and arrays: about 25 MB for the paper's replay) is taken once the helper has
ended, not beside matplotlib's. That overlap was the default run's peak memory (issue 32).
Rows that came while the run went (a slow short run's, every :data:`~twin.signals.recorder.FLUSH_SECONDS`)
are written as they come, and so is the rest of its rows then. A run that fails before the
sink closes (a plot that cannot be drawn) still writes the held rows and the error model's
columns, as they were written before the plots; a full disk writes nothing more (the rows are
in signals.csv, and the space left is the failed summary's).
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING

from twin.outputs.guard import refuse_links
from twin.outputs.sink import DISK_FULL_ERRNOS, Outcome, Sink
from twin.signals.table import Block, Signal

if TYPE_CHECKING:
    from twin.outputs.rerun_rec import RecordingWriter
    from twin.outputs.scene3d import TesterScene

__all__ = ["RecordingSink"]


def _rerun_rec() -> ModuleType:
    """:mod:`twin.outputs.rerun_rec`, imported (rerun and pyarrow with it) on the first call;
    a call while :func:`_load_rerun`'s thread imports it waits for that import."""
    from twin.outputs import rerun_rec

    return rerun_rec


def _load_rerun() -> None:
    """Begin importing :mod:`twin.outputs.rerun_rec` in a thread of its own (see the module); an
    import that fails there fails again, and is reported, where the recording is written."""

    def load() -> None:
        with contextlib.suppress(Exception):
            _rerun_rec()

    if "twin.outputs.rerun_rec" not in sys.modules:
        threading.Thread(target=load, name="load rerun", daemon=True).start()


class RecordingSink(Sink):
    """``recording.rrd`` as a sink: the recorded rows streamed as the run goes, then the
    columns derived after it (the error model's) on the same timeline.

    The file is created, and rerun loaded, with the first rows written (or when the run
    closes or fails before any: a run always leaves a recording). ``late_signals`` are the
    derived columns, declared up front because the blueprint needs every entity when the file
    is created; ``budget_columns`` go to the error-budget view. ``replay`` (a resumed run's
    signals.csv, already cut back to its checkpoint) is sent first, at :meth:`open`: a killed
    run never wrote its recording's footer, so the recording is written anew from the rows the
    CSV kept (a resumed run loads rerun when it opens its outputs). With :attr:`preload` set the
    import of rerun begins, in a thread, when the run opens its outputs (a long run: see the
    module).
    """

    def __init__(
        self,
        path: Path,
        *,
        recording_name: str,
        late_signals: Sequence[Signal] = (),
        budget_columns: Sequence[str] | None = None,
        replay: Path | None = None,
        scene: TesterScene | None = None,
    ) -> None:
        self.path = path
        self.scene = scene
        #: a long run's sink: rerun's import begins when the run opens its outputs (the module)
        self.preload = False
        #: a short run's sink, closed after the plots: the rows handed to it once the outputs
        #: begin are kept until then (the module); they are the rows the run held for its
        #: outputs, not a copy
        self.hold = False
        self._held: list[Block] = []
        #: the run's outcome while rows are held (from :meth:`begin`), else None
        self._holding: Outcome | None = None
        self.recording_name = recording_name
        self.late_signals = list(late_signals)
        self.budget_columns = budget_columns
        self.replay = replay
        self._signals: list[Signal] | None = None
        self._writer: RecordingWriter | None = None
        self._closed = False

    def open(self, signals: list[Signal]) -> None:
        names = {s.name for s in [*signals, *self.late_signals]}
        unknown = [n for n in self.budget_columns or () if n not in names]
        if unknown:  # checked now, not when the first rows come
            raise ValueError(f"budget columns {unknown} are not among the signals")
        self._signals = list(signals)
        if self.preload:
            _load_rerun()
        if self.replay is not None:
            # now, while signals.csv holds just the rows up to the checkpoint: the CSV's sink
            # comes first and would have added the first new block by the first write
            self._started()

    def _started(self) -> RecordingWriter:
        """The writer, made (file, blueprint, a resumed run's rows) on the first call."""
        if self._writer is not None:
            return self._writer
        if self._signals is None or self._closed:
            raise ValueError(f"{self.path}: written before open or after close")
        signals = self._signals
        # rerun opens the file by name, following a link: one planted there is refused, and an
        # earlier file removed, so that rerun makes a new one (twin.files)
        refuse_links(self.path.parent, [self.path.name])
        self.path.unlink(missing_ok=True)
        self._writer = _rerun_rec().RecordingWriter(
            self.path,
            [*signals, *self.late_signals],
            recording_name=self.recording_name,
            budget_columns=self.budget_columns,
            scene=self.scene,
        )
        if self.replay is not None:
            from twin.outputs.csv import read_signals_csv

            before = read_signals_csv(self.replay)
            # a run that recorded some columns only (--record) replays those
            columns = {s.name: before[s.name] for s in signals if s.name in before}
            self._writer.append(before.time, columns, partial=True)
            if self.scene is not None:
                self.scene.collect(before.time, columns)
        held, self._held = self._held, []
        for block in held:
            self._send(self._writer, block)
        return self._writer

    def begin(self, outcome: Outcome) -> bool:
        # the outputs begin: a held sink with no file yet keeps the rows from now on
        if self.hold and self._writer is None and not self._closed:
            self._holding = outcome
        return False

    def write(self, block: Block) -> None:
        if self._holding is not None and self._writer is None:
            _rerun_rec()  # loaded now, beside the plots' drawing; the file is written at close
            self._held.append(block)
            return
        self._send(self._started(), block)

    def _send(self, writer: RecordingWriter, block: Block) -> None:
        writer.append(block.time, block.columns, partial=True)
        if self.scene is not None:
            self.scene.collect(block.time, block.columns)

    def close(self, outcome: Outcome) -> None:
        if self._signals is None or self._closed:
            return
        self._derived(self._started(), outcome)
        self._release()

    @staticmethod
    def _derived(writer: RecordingWriter, outcome: Outcome) -> None:
        """The columns derived after the run (the error model's), on the rows' timeline."""
        if outcome.table is not None:
            table = outcome.table
            writer.append(table.time, {n: table[n] for n in outcome.columns}, partial=True)

    def fail(self, error: BaseException) -> None:
        if self._signals is not None and not self._closed and self._writer is None:
            holding, self._holding = self._holding, None
            if self._held and isinstance(error, OSError) and error.errno in DISK_FULL_ERRNOS:
                self._held.clear()  # a full disk: nothing more is written (the module)
                self._closed = True
                return
            try:
                # a run that broke before its first rows still leaves its recording, and one
                # that broke while its rows were held (a plot failed) leaves them in it, with
                # the error model's columns, as a recording written before the plots has them
                writer = self._started()
                if holding is not None:
                    self._derived(writer, holding)
            finally:
                self._release()
            return
        self._release()

    def _release(self) -> None:
        # closing writes the footer: what was sent stays a valid recording
        self._closed = True
        if self._writer is not None:
            writer, self._writer = self._writer, None
            writer.close()
