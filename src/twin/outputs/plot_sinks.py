"""The run's plots as sinks: ``error_budget.png`` and ``wear.png``, drawn when the run is over.

Each is drawn by the run's plot helper (:class:`~twin.outputs.plot_process.PlotProcess`, a
second process that imports matplotlib while the run goes) when the run has one, else in the
run's own process; the drawing itself is :func:`twin.outputs.plots.draw` either way.
"""

from __future__ import annotations

import dataclasses
from abc import abstractmethod
from pathlib import Path

from twin.errors import RunError
from twin.outputs.plot_process import PlotProcess, columns_json, thinned
from twin.outputs.plots import BudgetColumns, checked, draw
from twin.outputs.sink import Outcome, OutcomeSink
from twin.signals.table import Signal, SignalTable

__all__ = ["ErrorBudgetSink", "WearPlotSink"]


class _PlotSink(OutcomeSink):
    """A PNG drawn from the outcome's table when the run is over, into ``path``; by the run's
    :class:`~twin.outputs.plot_process.PlotProcess` when given one (``twin run`` starts it
    with the command; else it starts when the run opens its outputs), else in process.

    :meth:`begin` sends the plot to that process as soon as the outcome is known, so it is
    drawn while the outputs before it close; :meth:`close` waits for it. Subclasses say what
    they draw (:meth:`_job`) and its :attr:`kind`.
    """

    #: a run interrupted after its co-simulation leaves out the plots not already sent to the
    #: plot process (they only draw what the CSV files hold, and drawing in the run's process
    #: means importing matplotlib)
    skippable = True
    #: the plot's kind (twin.outputs.plots.KINDS)
    kind = ""

    def __init__(
        self, path: Path, columns: BudgetColumns, title: str, process: PlotProcess | None = None
    ) -> None:
        self.path = path
        self.columns = columns
        self.title = title
        self.process = process.use() if process is not None else None

    def open(self, signals: list[Signal]) -> None:
        """The run starts: so does the plot process, which imports matplotlib meanwhile."""
        if self.process is not None:
            self.process.start()

    def begin(self, outcome: Outcome) -> bool:
        """The outcome is known: hand the plot to the plot process, which draws it while the
        outputs before this one close. True when sent (then :meth:`close` waits for it, even
        if a stop comes in between); False when it is left to :meth:`close` (no process, one
        plot in its hands already, or nothing to draw)."""
        try:
            job = self._job(outcome)
        except KeyError:  # raised again by close, in its turn: the files before it are written
            return False
        if job is None or self.process is None:
            return False
        table, columns, names = job
        return self._send(table, columns, names)

    def close(self, outcome: Outcome) -> None:
        try:
            super().close(outcome)
        finally:
            self._release()

    def fail(self, error: BaseException) -> None:
        """The run broke: nothing new is written. A plot already handed to the plot process
        (:meth:`begin`) is abandoned: the process is stopped at once and what it wrote of the
        plot removed (the run removed any earlier run's file when it started)."""
        if self._in_hand():
            assert self.process is not None
            self.process.abandon()
            self.path.unlink(missing_ok=True)
            for tmp in self.path.parent.glob(f".{self.path.name}.*.tmp"):
                tmp.unlink(missing_ok=True)
        self._release()

    def write_outcome(self, outcome: Outcome) -> None:
        if self._in_hand():
            assert self.process is not None
            if self.process.answer():
                return
        job = self._job(outcome)
        if job is None:
            return
        table, columns, names = job
        if not self._send(table, columns, names) or not self.process or not self.process.answer():
            try:
                draw(self.kind, table, columns, self.title, self.path)
            except OSError:
                raise  # the file could not be written (a full disk): the run says which
            except Exception as exc:  # as the plot process reports it (plot_process.main)
                raise RunError(f"{self.path.name}: the plot failed: {type(exc).__name__}: {exc}") from exc

    @abstractmethod
    def _job(self, outcome: Outcome) -> tuple[SignalTable, BudgetColumns, list[str]] | None:
        """The table, the columns and the names of the columns the plot draws; None when the
        outcome has nothing for it. Raises ``KeyError`` naming a column the table lacks."""

    def _in_hand(self) -> bool:
        """Whether the plot process has this plot in hand (sent, not yet answered)."""
        return self.process is not None and self.process.pending == self.path

    def _release(self) -> None:
        process, self.process = self.process, None
        if process is not None:
            process.release()

    def _send(self, table: SignalTable, columns: BudgetColumns, names: list[str]) -> bool:
        """Whether the plot process took it (False: draw it here)."""
        if self.process is None or not self.process.running:
            return False
        # the only sink left drawing through the process sends its last plot
        return self.process.send(
            self.kind,
            self.path,
            thinned(table, names),
            columns_json(columns),
            self.title,
            last=self.process.users == 1,
        )


class ErrorBudgetSink(_PlotSink):
    """``error_budget.png`` as a sink.

    Only when the error model ran (the plot shows its prediction); temperatures the table
    lacks are left out rather than failing the plot.
    """

    kind = "budget"

    def _job(self, outcome: Outcome) -> tuple[SignalTable, BudgetColumns, list[str]] | None:
        table = outcome.table
        if table is None:
            return None
        present = {k: v for k, v in self.columns.temperature_columns().items() if v in table}
        columns = dataclasses.replace(self.columns, temperatures=present)
        if columns.compensated and columns.compensated not in table:
            columns = dataclasses.replace(columns, compensated=None)
        checked(table, columns)
        return table, columns, columns.budget_names()


class WearPlotSink(_PlotSink):
    """``wear.png``: wear against swing cycles with the wear limit (only for a run whose table
    has the true wear, the compensated wear and the cycles)."""

    kind = "wear"

    def _job(self, outcome: Outcome) -> tuple[SignalTable, BudgetColumns, list[str]] | None:
        table = outcome.table
        wear = self.columns.wear_columns()
        if table is None or wear is None or any(c not in table for c in (*wear, self.columns.reading)):
            return None
        return table, self.columns, self.columns.wear_names()
