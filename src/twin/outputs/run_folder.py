"""The run folder: the files a run writes, their names, and the folder's life.

A run folder holds

====================  ==========================================================
``signals.csv``       every recorded row, streamed while the run goes (FMPy reads it)
``signals.mat``       the same as a MATLAB file, once the run is over (``--format mat``)
``fmi.log``           what the FMUs logged (``--fmi-logging``)
``recording.rrd``     the same rows and the error model's columns, for the rerun viewer
``errormodel.csv``    the error model's columns, once the run is over
``error_budget.png``  the predicted error and its parts beside the probe's drift
``summary.json``      the run's numbers; written last, so its presence means "over"
``run.json``          how the run was started (for ``twin resume``)
``checkpoint.npz``    the whole twin at the last checkpoint (with ``--checkpoint-every``)
====================  ==========================================================

This module is the one place that knows those names, makes the sinks that write them
(:meth:`RunFolder.run_sinks`, :meth:`RunFolder.result_sinks`) and reads and writes the
checkpoint. The checkpoint holds ``{"master", "recorder", "scenario", "fingerprint"}`` as data
that cannot run code, every part checked by its SHA-256 (:mod:`twin.outputs.checkpoint_file`);
the fingerprint of the scenario it was taken from makes a resume of an edited scenario refuse.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.errors import CheckpointError, ConfigError
from twin.files import write_text_atomic
from twin.outputs import checkpoint_file
from twin.outputs.guard import open_output, output_dir, read_text_capped, refuse_links

if TYPE_CHECKING:
    from twin.outputs.plot_process import PlotProcess
    from twin.outputs.plots import BudgetColumns
    from twin.outputs.scene3d import TesterScene
    from twin.outputs.sink import Sink
    from twin.signals.table import Signal

__all__ = [
    "CHECKPOINT_FILE",
    "ERRORMODEL_CSV",
    "ERROR_BUDGET_PNG",
    "FMI_LOG",
    "RECORDING",
    "RUN_FILE",
    "SIGNALS_CSV",
    "SIGNALS_MAT",
    "SUMMARY_JSON",
    "WEAR_PNG",
    "Checkpoint",
    "RunFolder",
    "RunMeta",
    "RunOutputs",
]

SIGNALS_CSV = "signals.csv"
SIGNALS_MAT = "signals.mat"
FMI_LOG = "fmi.log"
RECORDING = "recording.rrd"
ERRORMODEL_CSV = "errormodel.csv"
ERROR_BUDGET_PNG = "error_budget.png"
WEAR_PNG = "wear.png"
SUMMARY_JSON = "summary.json"
RUN_FILE = "run.json"
CHECKPOINT_FILE = "checkpoint.npz"
#: the pickled checkpoint of twins before 0.2: never read (a pickle can execute code)
LEGACY_CHECKPOINT = "checkpoint.pkl"
UNCERTAINTY_CSV = "uncertainty.csv"
#: the lock a run holds on its folder for as long as it writes there (fcntl, advisory)
LOCK_FILE = ".twin.lock"
#: every file a run writes: a new run in a used folder removes these first, so no file of an
#: earlier run stays beside the new run's (files twin does not write are left alone)
RUN_OUTPUTS = (
    "signals.csv",
    "signals.units.json",
    "signals.mat",
    "fmi.log",
    "recording.rrd",
    "errormodel.csv",
    "errormodel.units.json",
    "error_budget.png",
    "wear.png",
    "summary.json",
    "uncertainty.csv",
    "checkpoint.npz",
    "checkpoint.pkl",
    "checkpoint.npz.tmp",  # a checkpoint a kill interrupted (checkpoint_file.save)
)
#: where signals.csv's header line must end (a header of 10 000 long column names fits)
MAX_HEADER_BYTES = 16 * 2**20
#: file systems no run folder may be on
_SPECIAL_ROOTS = (Path("/proc"), Path("/sys"), Path("/dev"))


def output_folder(raw: str | None, default: Path, option: str = "--out") -> Path:
    """The output folder an option names (``default`` without it), checked by
    :func:`check_output_folder`; an empty name is refused, not taken as the default."""
    if raw is not None and not raw.strip():
        raise ConfigError("is empty: name a folder", source=option)
    path = Path(raw) if raw is not None else default
    check_output_folder(path, option)
    return path


def check_output_folder(path: Path, option: str) -> None:
    """Refuse an output folder no run can write (before anything runs): an empty name, an
    existing file, a folder on /proc, /sys or /dev, or one that is not writable."""
    if str(path) == "" or str(path).strip() == "":
        raise ConfigError("is empty: name a folder", source=option)
    resolved = path.resolve()
    if any(resolved == root or root in resolved.parents for root in _SPECIAL_ROOTS):
        raise ConfigError(
            f"{path} is on a special file system ({resolved.parts[1]}), not a folder for outputs",
            source=option,
        )
    if resolved.exists() and not resolved.is_dir():
        raise ConfigError(f"{path} is a file, expected a folder", source=option)
    existing = next(p for p in (resolved, *resolved.parents) if p.exists())
    if not existing.is_dir():
        raise ConfigError(f"{existing} is a file, so {path} cannot be a folder", source=option)
    read_only = (os.statvfs(existing).f_flag & os.ST_RDONLY) != 0
    if read_only or not os.access(existing, os.W_OK | os.X_OK):
        raise ConfigError(f"{existing} is not writable", source=option)


def check_output_file(path: Path, option: str, suffix: str, *, in_a_folder: bool = False) -> Path:
    """Refuse an output file no command can write (before anything is computed): a name without
    ``suffix``, something other than a regular file in its place, a place on /proc, /sys or
    /dev, or a folder that cannot be made or written. Missing folders above it are allowed
    (the command makes them), unless ``in_a_folder`` asks for an existing one (a file written
    beside itself, then renamed)."""
    if path.suffix != suffix:
        raise ConfigError(f"expected a file name ending in {suffix}, got {path}", source=option)
    resolved = path.resolve()
    if any(root in resolved.parents for root in _SPECIAL_ROOTS):
        raise ConfigError(
            f"{path} is on a special file system ({resolved.parts[1]}), not a place for outputs",
            source=option,
        )
    if resolved.exists() and not resolved.is_file():
        raise ConfigError(f"{path} exists and is not a file", source=option)
    existing = next(p for p in resolved.parents if p.exists())
    if not existing.is_dir():
        raise ConfigError(f"{existing} is a file, so {path} cannot be made", source=option)
    if in_a_folder and existing != resolved.parent:
        raise ConfigError(f"no folder {resolved.parent}", source=option)
    read_only = (os.statvfs(existing).f_flag & os.ST_RDONLY) != 0
    if read_only or not os.access(existing, os.W_OK | os.X_OK):
        raise ConfigError(f"{existing} is not writable", source=option)
    return path


@dataclass(frozen=True)
class RunOutputs:
    """What a run's outputs show: ``name`` names the recording and titles the plots;
    ``late_signals`` are the columns the error model adds after the run (declared to the
    recording up front), ``budget_view`` those of the recording's error-budget view; ``plot``
    what the plots draw; ``scene`` the recording's 3D view of the tester (none when None)."""

    name: str
    late_signals: tuple[Signal, ...]
    budget_view: tuple[str, ...]
    plot: BudgetColumns
    scene: TesterScene | None = None
    #: the columns signals.csv (and signals.mat) hold, in order (``--record``; None: every
    #: recorded column)
    signals: tuple[str, ...] | None = None
    #: signals.mat beside signals.csv (``--format mat``)
    mat: bool = False
    #: rows reach the recording while the run steps (a long run): rerun is loaded beside the
    #: co-simulation, not when the first rows come (:mod:`twin.outputs.recording_sink`)
    long: bool = False


@dataclass(frozen=True)
class RunMeta:
    """``run.json``: how a run was started, so that ``twin resume`` can start it the same way."""

    scenario: str  # the scenario file, absolute
    overrides: tuple[str, ...] = ()
    loop: str = "fast"
    checkpoint_every_ns: int | None = None
    #: the command line's times and input file (twin.config.experiment.Experiment.to_json)
    experiment: Mapping[str, str] = field(default_factory=dict)
    #: the columns signals.csv holds (``--record``; None: all)
    record: tuple[str, ...] | None = None
    #: the signal files besides signals.csv (``--format``)
    formats: tuple[str, ...] = ()
    fmi_logging: bool = False


@dataclass(frozen=True)
class Checkpoint:
    """The whole twin at one instant: the master's state, where the recorder's files stand
    (``csv_position``) with the rows it keeps in memory, and the scenario's name."""

    master: dict[str, Any]
    recorder: dict[str, Any]
    scenario: str
    #: :func:`scenario_fingerprint` of the scenario the checkpoint was taken from
    fingerprint: str = ""


def scenario_fingerprint(scenario: object) -> str:
    """A hash of everything a loaded scenario holds (its frozen spec's repr: values, files'
    parameters, connections, events), so a scenario edited between a kill and a resume is seen."""
    import dataclasses

    # the file's path as typed (relative for `twin run`, absolute in run.json) is not content
    spec = dataclasses.replace(scenario, source_path="") if dataclasses.is_dataclass(scenario) else scenario
    return hashlib.sha256(repr(spec).encode("utf-8")).hexdigest()


class RunFolder:
    """One run's folder (``path``) and the files in it."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._lock_fd: int | None = None

    def file(self, name: str) -> Path:
        """The path of one of the folder's files (a name of this module)."""
        return self.path / name

    # -- the folder's life ---------------------------------------------------------------

    def make(self) -> None:
        """Make the folder (and its parents) if it is not there."""
        output_dir(self.path)

    def refuse_links(self) -> None:
        """A symbolic link planted where the run writes a file is refused (one line, exit 2)
        before anything runs: the twin never writes through one (:mod:`twin.files`)."""
        refuse_links(self.path, (LOCK_FILE, RUN_FILE, *RUN_OUTPUTS))

    def lock(self) -> None:
        """Hold the folder's lock until :meth:`unlock` (or the process ends): a second twin
        process on the same folder is refused with :class:`ConfigError` (exit 2) instead of
        interleaving its rows with this one's. A command takes it once, when it prepares its
        run (:func:`twin.pipeline.prepare.prepare`), for its whole life."""
        import fcntl

        if self._lock_fd is not None:
            return
        self.make()
        self.refuse_links()
        lock = open_output(self.file(LOCK_FILE), "r+")  # never through a planted link
        fd = os.dup(lock.fileno())
        lock.close()
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            holder = os.read(fd, 32).decode("ascii", "replace").strip() or "?"
            os.close(fd)
            raise ConfigError(
                f"run folder {self.path} is in use by another twin process (pid {holder})"
            ) from None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        self._lock_fd = fd

    def unlock(self) -> None:
        """Release the folder's lock (idempotent)."""
        fd, self._lock_fd = self._lock_fd, None
        if fd is not None:
            os.close(fd)  # closing the descriptor releases the flock

    def start(self, meta: RunMeta) -> None:
        """Make the folder for a new run: remove every output of an earlier run (and its
        checkpoint), write ``run.json``."""
        self.make()
        for name in RUN_OUTPUTS:
            self.file(name).unlink(missing_ok=True)
        # what a kill left of an atomic write (twin.files' hidden temporary files)
        for name in (*RUN_OUTPUTS, RUN_FILE):
            for tmp in self.path.glob(f".{name}.*.tmp"):
                tmp.unlink(missing_ok=True)
        text = json.dumps(
            {
                "scenario": meta.scenario,
                "overrides": list(meta.overrides),
                "loop": meta.loop,
                "checkpoint_every_ns": meta.checkpoint_every_ns,
                "experiment": dict(meta.experiment),
                "record": list(meta.record) if meta.record is not None else None,
                "formats": list(meta.formats),
                "fmi_logging": meta.fmi_logging,
            },
            indent=2,
        )
        write_text_atomic(self.file(RUN_FILE), text, sync=True)

    def resumable(self) -> RunMeta:
        """``run.json`` of a folder that can be resumed; :class:`ConfigError` if it cannot."""
        where = str(self.path)
        if not self.file(RUN_FILE).is_file():
            raise ConfigError(f"no {RUN_FILE}: not a run folder", source=where)
        if self.file(LEGACY_CHECKPOINT).exists() and not self.file(CHECKPOINT_FILE).exists():
            raise CheckpointError(
                f"{LEGACY_CHECKPOINT} is a pickle (an older twin's format, which can execute code): "
                "not read; run the scenario again",
                source=where,
            )
        if not self.file(CHECKPOINT_FILE).is_file():
            raise ConfigError(
                f"no {CHECKPOINT_FILE}: the run saved no checkpoint (use --checkpoint-every)", source=where
            )
        return _run_meta(self.file(RUN_FILE))

    # -- the checkpoint ------------------------------------------------------------------

    def save_checkpoint(self, checkpoint: Checkpoint) -> None:
        """Write the checkpoint atomically: a kill never leaves half of one."""
        data = {
            "master": checkpoint.master,
            "recorder": checkpoint.recorder,
            "scenario": checkpoint.scenario,
            "fingerprint": checkpoint.fingerprint,
        }
        checkpoint_file.save(self.file(CHECKPOINT_FILE), data)

    def load_checkpoint(self, scenario: str, fingerprint: str, kept_columns: int) -> Checkpoint:
        """The folder's checkpoint, which must have been taken from the scenario named
        ``scenario`` as it is now (``fingerprint``), with signals.csv still holding its rows
        and its recorder part what a run keeping ``kept_columns`` columns writes. Nothing of
        the folder is changed here (see :meth:`run_sinks`)."""
        path = self.file(CHECKPOINT_FILE)
        data = checkpoint_file.load(path)
        master, recorder = data.get("master"), data.get("recorder")
        if (
            not isinstance(master, dict)
            or not isinstance(recorder, dict)
            or not isinstance(data.get("scenario"), str)
        ):
            raise CheckpointError("malformed checkpoint (master, recorder, scenario)", source=str(path))
        if data["scenario"] != scenario:
            raise CheckpointError("the checkpoint belongs to another scenario", source=str(path))
        if data.get("fingerprint") != fingerprint:
            raise CheckpointError(
                "the scenario (its file, an included file or --set) changed since the checkpoint: "
                "resuming would mix two scenarios",
                source=str(path),
            )
        self._check_kept(recorder, kept_columns, str(path))
        self._check_csv(recorder, str(path))
        return Checkpoint(master, recorder, data["scenario"], fingerprint)

    def refuse_completed(self) -> None:
        """A run whose summary.json says it completed has nothing to resume: refused (exit 2)
        rather than run again from its last checkpoint, rewriting a finished run's files."""
        path = self.file(SUMMARY_JSON)
        try:
            status = json.loads(read_text_capped(path, 2**20)).get("status")
        except (OSError, ValueError, AttributeError):
            return  # no summary (killed) or an unreadable one: the resume writes it anew
        if status == "completed":
            raise ConfigError(
                "the run completed (summary.json): nothing to resume; `twin run --force` runs it again",
                source=str(self.path),
            )

    @staticmethod
    def _check_kept(recorder: dict[str, Any], kept_columns: int, source: str) -> None:
        """The rows the run keeps in memory: float64, one time per row, ``kept_columns`` wide."""
        t, rows = recorder.get("kept_time"), recorder.get("kept_rows")
        if not isinstance(t, np.ndarray) or t.dtype != np.float64 or t.ndim != 1:
            raise CheckpointError("expected a float64 vector", source=source, key="recorder.kept_time")
        if (
            not isinstance(rows, np.ndarray)
            or rows.dtype != np.float64
            or rows.shape != (len(t), kept_columns)
        ):
            got = f"{rows.dtype} {rows.shape}" if isinstance(rows, np.ndarray) else type(rows).__name__
            raise CheckpointError(
                f"expected float64 of shape ({len(t)}, {kept_columns}), got {got}",
                source=source,
                key="recorder.kept_rows",
            )

    def _check_csv(self, recorder: dict[str, Any], source: str) -> None:
        """csv_position is ``[bytes, last time]``: a line end of signals.csv past its header
        (0 would empty the file, -1 or beyond its end cannot be continued)."""
        position = recorder.get("csv_position")
        key = "recorder.csv_position"
        if (
            not isinstance(position, list)
            or len(position) != 2
            or type(position[0]) is not int
            or type(position[1]) not in (int, float)
            or not math.isfinite(position[1])
        ):
            raise CheckpointError(
                "expected [bytes, last time] (an integer and a finite number)", source=source, key=key
            )
        csv = self.file(SIGNALS_CSV)
        offset = position[0]
        try:
            fd = os.open(csv, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError as exc:
            raise CheckpointError(
                f"{SIGNALS_CSV} cannot be read ({exc.strerror})", source=source, key=key
            ) from None
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise CheckpointError(f"{SIGNALS_CSV} is not a regular file", source=source, key=key)
            size = st.st_size
            header = f.read(min(size, MAX_HEADER_BYTES)).find(b"\n") + 1
            if not header <= offset <= size:
                raise CheckpointError(
                    f"{offset} is not within {SIGNALS_CSV}'s rows (bytes {header} to {size}): "
                    "the file was cut or replaced, or the checkpoint crafted",
                    source=source,
                    key=key,
                )
            f.seek(offset - 1)
            if f.read(1) != b"\n":
                raise CheckpointError(
                    f"{offset} is not at the end of a row of {SIGNALS_CSV}", source=source, key=key
                )

    # -- the sinks -----------------------------------------------------------------------

    def run_sinks(
        self, outputs: RunOutputs, resume: Checkpoint | None = None, plot_process: PlotProcess | None = None
    ) -> list[Sink]:
        """Every output of a twin run, in the order they close: what ``outputs`` says they
        show, the plots drawn by ``plot_process`` (in this process when None). With
        ``resume``, signals.csv is cut back to the checkpoint and continued, and the recording
        is written anew from the rows the CSV kept.
        """
        from twin.outputs.csv import SignalsCsvSink
        from twin.outputs.recording_sink import RecordingSink

        csv_path = self.file(SIGNALS_CSV)
        position = None
        if resume is not None:
            # cut back when the CSV's sink opens, which is after the master has restored every
            # FMU's state: a resume the FMUs refuse leaves signals.csv as it was
            position = tuple(resume.recorder["csv_position"])
        from twin.outputs.mat import SignalsMatSink

        mat = [SignalsMatSink(self.file(SIGNALS_MAT), csv_path)] if outputs.mat else []
        recording = RecordingSink(
            self.file(RECORDING),
            recording_name=outputs.name,
            late_signals=outputs.late_signals,
            budget_columns=outputs.budget_view,
            replay=csv_path if resume is not None else None,
            scene=outputs.scene,
        )
        recording.preload = outputs.long
        results = self.result_sinks(name=outputs.name, plot=outputs.plot, plot_process=plot_process)
        signals: list[Sink] = [SignalsCsvSink(csv_path, resume_at=position, columns=outputs.signals), *mat]
        if outputs.long or plot_process is None:
            return [*signals, recording, *results]
        # a short run's recording is written once its plots are drawn, before summary.json:
        # its memory then comes after the plot helper's (twin.outputs.recording_sink)
        recording.hold = True
        return [*signals, *results[:-1], recording, results[-1]]

    def result_sinks(
        self, *, name: str, plot: BudgetColumns, plot_process: PlotProcess | None = None
    ) -> list[Sink]:
        """The outputs written once the error model has run: errormodel.csv, the plot
        (titled after ``name``; drawn by ``plot_process`` when given) and summary.json, last."""
        from twin.outputs.csv import DerivedCsvSink
        from twin.outputs.plot_sinks import ErrorBudgetSink, WearPlotSink
        from twin.outputs.summary import SummarySink

        process = plot_process
        sinks: list[Sink] = [
            DerivedCsvSink(self.file(ERRORMODEL_CSV)),
            ErrorBudgetSink(
                self.file(ERROR_BUDGET_PNG), plot, f"{name}: predicted error and its parts", process
            ),
        ]
        if plot.wear_columns() is not None:
            sinks.append(
                WearPlotSink(self.file(WEAR_PNG), plot, f"{name}: wear against swing cycles", process)
            )
        return [*sinks, SummarySink(self.file(SUMMARY_JSON))]


def _run_meta(path: Path) -> RunMeta:
    """Read ``run.json``; a malformed one is one line per problem, exit code 2."""
    from twin.config.reader import Problems

    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ConfigError(f"unreadable: {type(exc).__name__}: {exc}", source=str(path)) from None
    p = Problems(str(path))
    if not isinstance(data, dict):
        p.add(
            "", "malformed: expected an object with scenario (a path), overrides, loop, checkpoint_every_ns"
        )
        p.check()
    if not isinstance(data.get("scenario"), str):
        p.add("scenario", "malformed: expected the scenario file's path")
    overrides = p.strings(data, "overrides", "")
    if data.get("loop", "fast") not in ("fast", "python"):
        p.add("loop", f"malformed: expected 'fast' or 'python', got {data.get('loop')!r}")
    every = data.get("checkpoint_every_ns")
    if every is not None and type(every) is not int:
        p.add("checkpoint_every_ns", f"malformed: expected null or an integer, got {every!r}")
    experiment = data.get("experiment") or {}
    if not isinstance(experiment, dict) or not all(isinstance(v, str) for v in experiment.values()):
        p.add("experiment", "malformed: expected an object of strings")
    record = data.get("record")
    if record is not None:
        record = p.strings(data, "record", "")
    formats = p.strings(data, "formats", "") if "formats" in data else ()
    fmi_logging = data.get("fmi_logging", False)
    if not isinstance(fmi_logging, bool):
        p.add("fmi_logging", f"malformed: expected true or false, got {fmi_logging!r}")
    p.check()
    return RunMeta(
        data["scenario"],
        overrides,
        data.get("loop", "fast"),
        every,
        experiment,
        tuple(record) if record is not None else None,
        tuple(formats),
        fmi_logging,
    )
