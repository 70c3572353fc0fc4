"""The run's plots drawn by a second Python process, started when the run starts.

Importing matplotlib and drawing the error budget take about as long as a short run's whole
co-simulation and error model (docs/performance/bench_phases.md measures it). A
:class:`PlotProcess` starts ``python -m twin.outputs.plot_process`` when the run starts
(``twin run`` starts it before anything else); that process imports matplotlib (and draws a
throw-away figure, which loads the fonts) on the machine's other core while the run goes, then
draws each plot it is sent.

What it is sent is only what a plot draws: the plot's columns at the rows the plot draws
(:func:`thinned`: each bucket's extremes, a few thousand rows), as one JSON line (the job: kind, file, title, columns)
followed by raw little-endian float64. Nothing it reads executes code: no pickle. It answers
each job with one JSON line. The same drawing code on the same samples gives the same bytes as
drawing in the run's own process (tests/outputs/test_plot_process.py).

A plot is sent as soon as the run's outcome is known (:meth:`PlotProcess.send`, from the plot
sink's ``begin``; written to the helper by a thread, so a helper still importing matplotlib
does not hold the run) and drawn while the run finishes its other files; one at a time. The
run waits for each PNG (:meth:`PlotProcess.answer`) before summary.json, so every file it
lists exists, and for the helper to end (it leaves at once, without the interpreter's
teardown). If the process cannot be started, or dies, the plot is drawn in the run's own
process instead: a missing second core or a killed helper costs time, never a plot. A plot that fails to draw
raises :class:`~twin.errors.RunError` with the helper's message. The helper ends when its
input closes: when the run closes it, and when the run's process dies; a helper never sent a
plot (bad input, a failed run) is killed at once.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Mapping
from dataclasses import asdict
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from twin.errors import RunError

if TYPE_CHECKING:
    from twin.signals.table import SignalTable

# numpy, the plots and the table are imported where used: ``twin run`` starts the helper
# (:meth:`PlotProcess.started`) before it imports numpy, so that the helper's own imports
# overlap the run's

__all__ = ["PlotProcess", "main", "thinned"]

#: seconds the run waits for the helper to end once its input is closed
_EXIT_WAIT_S = 5.0


def thinned(table: SignalTable, names: list[str]) -> SignalTable:
    """The columns ``names`` of ``table`` at the rows a plot of them draws
    (:func:`twin.outputs.plots.drawn_rows`: every bucket's extremes). Picking again from these
    rows gives these rows, so the plot of the thinned table draws exactly the samples it would
    draw from the whole table."""
    import numpy as np

    from twin.outputs import plots
    from twin.signals.table import Signal, SignalTable

    rows = plots.drawn_rows(table, names)
    out = SignalTable(np.ascontiguousarray(table.time[rows]))
    for name in names:
        out.add(Signal(name, "", ""), np.ascontiguousarray(table[name][rows]))
    return out


class PlotProcess:
    """A helper process that draws the run's plots (see the module); one per run, shared by
    its plot sinks (:meth:`use` each, :meth:`release` each when done)."""

    def __init__(self) -> None:
        self._proc: subprocess.Popen[bytes] | None = None
        self._users = 0
        self._started = False
        self._sent = False
        self._pending: Path | None = None
        self._feeder: threading.Thread | None = None

    @classmethod
    def started(cls) -> PlotProcess | None:
        """A started helper where the machine has a second core for it, else None (one core
        would only take turns: the plots are then drawn in the run's process)."""
        cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
        if cores < 2:
            return None
        process = cls()
        process.start()
        return process

    def use(self) -> PlotProcess:
        """One more sink draws through this process."""
        self._users += 1
        return self

    def start(self) -> None:
        """Start the helper (once; idempotent). Where it cannot start, plots are drawn in process."""
        if self._started:
            return
        self._started = True
        try:
            # the same interpreter and environment, so the same twin and matplotlib; a helper
            # that cannot import them ends at once, and the plots are drawn in process
            self._proc = subprocess.Popen(
                [sys.executable, "-m", "twin.outputs.plot_process"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
            )
        except OSError:
            self._proc = None

    @property
    def running(self) -> bool:
        """Whether the helper is up (started and not ended)."""
        return self._proc is not None and self._proc.poll() is None

    @property
    def users(self) -> int:
        """The sinks that draw through this process and have not released it."""
        return self._users

    def send(
        self,
        kind: str,
        path: Path,
        table: SignalTable,
        columns: Mapping[str, Any],
        title: str,
        *,
        last: bool = False,
    ) -> bool:
        """Hand the helper a plot to draw and return while it draws (:meth:`answer` waits for
        it). False when the helper is not there, died, or has a plot in hand already (one at
        a time); the caller then draws in process, or sends again once answered. The ``last``
        plot closes the helper's input behind it: the helper ends as soon as it has answered,
        instead of holding matplotlib's memory beside the run's until the run's outputs are
        all written (the paper replay's recording imports rerun meanwhile: the two processes'
        peaks fell together).

        The job is written to the helper's input by a thread: a helper still importing
        matplotlib does not read it yet, and the pipe holds only 64 KiB of the job's few
        hundred, so writing it here would hold this process until the helper is ready. A
        helper that dies meanwhile is found by :meth:`answer` (no answer: drawn in process).
        """
        proc = self._proc
        if self._pending or proc is None or proc.stdin is None or not self.running:
            return False
        import numpy as np

        names = list(table.columns)
        header = {"kind": kind, "path": str(path), "title": title, "columns": dict(columns)}
        header |= {"n": len(table.time), "names": names}
        data = np.stack([table.time, *(table[n] for n in names)]).astype("<f8", copy=False)
        job = json.dumps(header).encode("utf-8") + b"\n" + np.ascontiguousarray(data).tobytes()
        self._feeder = threading.Thread(
            target=_feed, args=(proc.stdin, job, last), name="plot job", daemon=True
        )
        self._feeder.start()
        self._sent = True
        self._pending = path
        return True

    @property
    def pending(self) -> Path | None:
        """The file of the plot sent and not yet answered, if any."""
        return self._pending

    def answer(self) -> bool:
        """Wait for the plot sent last. True when drawn; False when the helper died before
        answering (the caller draws in process). A plot the helper could not draw raises
        :class:`RunError` with its message. The plot stays in hand while this waits: an
        interrupt meanwhile leaves it to :meth:`abandon`."""
        path = self._pending
        self._fed()
        proc = self._proc
        if path is None or proc is None or proc.stdout is None:
            self._pending = None
            return False
        try:
            line = proc.stdout.readline()
        except OSError:
            line = b""
        self._pending = None
        if not line:
            self._end()
            return False
        try:
            answer = json.loads(line)
        except ValueError:
            self._end()
            return False
        if not answer.get("ok"):
            raise RunError(f"{path.name}: the plot failed: {answer.get('error', 'no reason given')}")
        return True

    def abandon(self) -> None:
        """The run broke while a plot was in hand: stop the helper at once (SIGKILL, as it
        ignores the run's signals) instead of waiting for the plot."""
        if self._pending is not None and self._proc is not None:
            self._proc.kill()
        self._end()

    def release(self) -> None:
        """One sink is done; the last one ends the helper."""
        self._users -= 1
        if self._users <= 0:
            self._end()

    def close(self) -> None:
        """End the helper whoever still uses it (idempotent): the run is over."""
        self._end()

    def _fed(self) -> None:
        """Wait for the job's writing thread (it ends once the job is in the pipe, or the
        helper is gone)."""
        feeder, self._feeder = self._feeder, None
        if feeder is not None:
            feeder.join()

    def _end(self) -> None:
        self._pending = None
        proc, self._proc = self._proc, None
        if proc is None:
            return
        if not self._sent:
            # never given a plot (bad input, a failed run): the helper has nothing to finish,
            # and closing its input would wait for its import of matplotlib
            proc.kill()
        self._fed()
        try:
            if proc.stdin is not None:
                proc.stdin.close()
        except OSError:
            pass
        try:
            proc.wait(timeout=_EXIT_WAIT_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        if proc.stdout is not None:
            proc.stdout.close()


def _feed(stdin: IO[bytes], job: bytes, last: bool) -> None:
    """Write one job to the helper's input (the thread of :meth:`PlotProcess.send`), and
    close that input behind the ``last`` one."""
    try:
        stdin.write(job)
        stdin.flush()
        if last:
            stdin.close()
    except (OSError, ValueError):  # the helper died (BrokenPipeError), or its input was closed
        pass


# ----------------------------------------------------------------------------- the helper


def _read_exact(stream: IO[bytes], size: int) -> bytes:
    chunks, left = [], size
    while left:
        chunk = stream.read(left)
        if not chunk:
            raise EOFError(f"input ended {left} bytes short")
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def _read_job(line: bytes, stream: IO[bytes]) -> tuple[dict[str, Any], SignalTable]:
    """One job's header and samples. Raises ValueError (or EOFError) on anything else: the
    stream is then out of step, and the helper ends."""
    import numpy as np

    from twin.outputs import plots
    from twin.signals.table import Signal, SignalTable

    header = json.loads(line)
    if not isinstance(header, dict) or header.get("kind") not in plots.KINDS:
        raise ValueError("a job is a JSON object with kind 'budget' or 'wear'")
    n, names = header.get("n"), header.get("names")
    if not (
        isinstance(n, int) and n >= 0 and isinstance(names, list) and all(isinstance(x, str) for x in names)
    ):
        raise ValueError("a job's n is a count and its names a list of strings")
    if not isinstance(header.get("columns"), dict):
        raise ValueError("a job's columns are a JSON object")
    raw = _read_exact(stream, (len(names) + 1) * n * 8)
    data = np.frombuffer(raw, dtype="<f8").reshape(len(names) + 1, n)
    table = SignalTable(data[0].copy())
    for i, name in enumerate(names):
        table.add(Signal(name, "", ""), data[i + 1].copy())
    return header, table


def _draw(header: Mapping[str, Any], table: SignalTable) -> None:
    from twin.outputs import plots

    columns = plots.BudgetColumns(**header["columns"])
    plots.draw(str(header["kind"]), table, columns, str(header["title"]), Path(str(header["path"])))


def main() -> int:
    """The helper: import matplotlib, then draw each job from standard input until it ends."""
    # a Ctrl-C on the terminal, or a batch system's SIGTERM, reaches the whole process group:
    # the run handles it (its plots are skipped, or drawn, as it decides) and then closes this
    # helper's input; a helper that died of it would leave its plot to the run's process
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    from twin.outputs import plots

    stdin, stdout = sys.stdin.buffer, sys.stdout
    # the fonts are loaded ahead only while no plot waits: a plot sent during matplotlib's
    # import (the paper replay's comes first) loads them itself, and the run waits less
    if not _waiting(stdin):
        plots.warm_up()
    while line := stdin.readline():
        try:
            header, table = _read_job(line, stdin)
        except (ValueError, EOFError) as exc:
            stdout.write(json.dumps({"ok": False, "error": f"unreadable job: {exc}"}) + "\n")
            stdout.flush()
            return 2
        try:
            _draw(header, table)
            answer: dict[str, Any] = {"ok": True}
        except Exception as exc:
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        stdout.write(json.dumps(answer) + "\n")
        stdout.flush()
    return 0


def _waiting(stream: IO[bytes]) -> bool:
    """Whether the helper's input has something to read now (a job, or its end)."""
    import select

    try:
        return bool(select.select([stream], [], [], 0)[0])
    except (OSError, ValueError):
        return False


def columns_json(columns: Any) -> dict[str, Any]:
    """A :class:`~twin.outputs.plots.BudgetColumns` as JSON-able fields (mappings as dicts)."""
    fields = asdict(columns)
    for key in ("parts", "temperatures", "disabled"):
        value = fields[key]
        fields[key] = dict(value) if isinstance(value, Mapping) else list(value)
    return fields


if __name__ == "__main__":
    code = main()
    # Every PNG is written and closed and every answer flushed: nothing is left to clean up,
    # and tearing down matplotlib's interpreter is time the run waits for (it waits for the helper to end, so none outlives it).
    sys.stdout.flush()
    os._exit(code)
