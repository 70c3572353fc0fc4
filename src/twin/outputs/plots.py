"""The plots of a run (PNG): the error budget, and wear against cycles for an endurance test.

``error_budget.png`` has three panels sharing the time axis: the probe reading's drift with the
predicted error (and the compensated wear), the five parts of the prediction as stacked areas
(positive parts stacked up from zero, negative ones down), and the temperature rises. Every
axis names its quantity and unit, every curve has a human name, and the legends sit to the right
of the panels, outside the curves. All lengths are in µm.

``wear.png`` (a run whose error model reads the true wear and whose tester counts its swing
cycles) draws the true, the measured and the compensated wear against the cycles, with the
scenario's wear limit (the MIL-spec 0.152 mm of facts 4 for the endurance test) as a line.

Drawn on a bare :class:`~matplotlib.figure.Figure` with the Agg canvas, not through ``pyplot``:
no display is needed, no global backend is switched under the caller, and no figure is left
open. The figures are built by :func:`budget_figure` and :func:`wear_figure` (tests read their
artists); fixed size, dpi and fonts and no ``Software`` metadata make the bytes reproducible.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from abc import abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.errors import RunError
from twin.outputs.atomic import write_atomic
from twin.outputs.sink import OutcomeSink
from twin.signals.table import SignalTable

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from twin.outputs.plot_process import PlotProcess
    from twin.outputs.sink import Outcome
    from twin.signals.table import Signal

__all__ = [
    "DPI",
    "FIGSIZE_IN",
    "WEAR_FIGSIZE_IN",
    "BudgetColumns",
    "ErrorBudgetSink",
    "WearPlotSink",
    "budget_figure",
    "error_budget_png",
    "human_name",
    "save_png",
    "warm_up",
    "wear_figure",
]

FIGSIZE_IN = (11.0, 8.5)
WEAR_FIGSIZE_IN = (10.0, 5.0)
DPI = 100  # 1100 x 850 pixels
_UM_PER_M = 1e6
# The parts' colours leave out black, red and green, which mark the measured drift, the
# prediction and the compensated wear.
_PART_COLORS = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:cyan", "tab:olive", "tab:pink")
#: most points drawn per curve: the figure is about 1000 px wide, and drawing every sample of a
#: long run costs seconds without changing a pixel of the trends
_MAX_POINTS = 2000


#: measuring points whose name is not just their key with spaces
_POINT_NAMES = {"t_plate": "T-plate"}


def human_name(column: str) -> str:
    """A column's name as a person reads it: ``sensors.t_bearing_block_meas`` -> ``bearing
    block``, ``thermal.t_base`` -> ``base`` (instance prefix, ``t_`` and ``_meas``/``_true``
    dropped, underscores as spaces)."""
    name = column.rsplit(".", 1)[-1]
    for prefix in ("t_",):
        name = name.removeprefix(prefix)
    for suffix in ("_meas", "_true", "_measured"):
        name = name.removesuffix(suffix)
    return name.replace("_", " ").strip() or column


def _time_axis(time_s: np.ndarray) -> tuple[np.ndarray, str]:
    """Time in minutes, or in hours from 3 h on (short tick labels either way)."""
    span = float(time_s[-1] - time_s[0]) if time_s.size else 0.0
    if span >= 3 * 3600:
        return time_s / 3600.0, "time (h)"
    return time_s / 60.0, "time (min)"


def _rise(values: np.ndarray) -> np.ndarray:
    """Values relative to their first finite value (zero-length and all-NaN stay as they are)."""
    finite = np.flatnonzero(np.isfinite(values))
    return values - values[finite[0]] if finite.size else values


@dataclass(frozen=True)
class BudgetColumns:
    """Which columns the plots draw.

    ``reading`` is the probe reading (m), plotted as its drift from the first value;
    ``predicted`` the predicted error (m); ``parts`` maps a legend label (thermal, loading,
    fluctuating, positioning, interference) to the column of that part (m); ``temperatures``
    maps a measuring point's name to its column (K or °C; a plain list of columns is named by
    :func:`human_name`), shown as rises from their first value. ``compensated`` (m) is drawn
    beside the drift when given; with ``true_wear`` (m) and ``cycles`` too, :func:`wear_figure`
    draws wear against cycles, with ``wear_limit_m`` as the limit line when given.
    """

    reading: str
    predicted: str
    parts: Mapping[str, str]
    temperatures: Mapping[str, str] | Sequence[str]
    compensated: str | None = None
    true_wear: str | None = None
    cycles: str | None = None
    wear_limit_m: float | None = None

    def temperature_columns(self) -> dict[str, str]:
        """Point name -> column of every temperature drawn."""
        if isinstance(self.temperatures, Mapping):
            return {_POINT_NAMES.get(k, str(k).replace("_", " ")): v for k, v in self.temperatures.items()}
        return {human_name(c): c for c in self.temperatures}

    def wear_columns(self) -> tuple[str, str, str] | None:
        """(true wear, compensated wear, cycles), when a wear plot can be drawn."""
        if self.true_wear and self.compensated and self.cycles:
            return self.true_wear, self.compensated, self.cycles
        return None

    def missing(self, table: SignalTable) -> list[str]:
        """The columns ``table`` lacks (of the error-budget plot)."""
        wanted = [self.reading, self.predicted, *self.parts.values(), *self.temperature_columns().values()]
        if self.compensated:
            wanted.append(self.compensated)
        return [name for name in wanted if name not in table]


def error_budget_png(
    table: SignalTable,
    path: str | os.PathLike[str],
    *,
    reading: str,
    predicted: str,
    parts: Mapping[str, str],
    temperatures: Mapping[str, str] | Sequence[str],
    title: str,
) -> Path:
    """Draw the error budget of ``table`` to the PNG ``path``; returns ``path``.

    The columns are those of :class:`BudgetColumns`; all lengths are shown in µm.
    Raises ``KeyError`` naming a column the table lacks.
    """
    columns = BudgetColumns(reading, predicted, parts, temperatures)
    return save_png(budget_figure(table, columns, title), Path(path))


def _checked(table: SignalTable, columns: BudgetColumns) -> None:
    missing = columns.missing(table)
    if missing:
        raise KeyError(f"columns not in the signal table: {missing}")


def _new_figure(size: tuple[float, float]) -> Figure:
    # matplotlib is imported when a plot is drawn: a process that never draws (a sweep's
    # worker) does not pay its second of import
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # fixed margins, the right one wide enough for the legends outside the panels: matplotlib's
    # constrained layout would find them too, but by drawing the whole figure once more (half
    # of the plot's time); tests/outputs/test_plots.py checks that nothing overlaps
    fig = Figure(figsize=size, dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _style() -> Any:
    import matplotlib.style

    # The default style, not the user's matplotlibrc: the same input gives the same bytes anywhere.
    return matplotlib.style.context("default")


def _legend_outside(ax: Axes) -> None:
    """The legend to the right of the panel, outside its curves."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", frameon=False)


def _stacked(ax: Axes, t: np.ndarray, parts: Mapping[str, np.ndarray]) -> None:
    """The parts as stacked areas: positive values stacked up from zero, negative ones down
    (a plain stack of mixed signs would hide a part under its neighbour)."""
    up = np.zeros_like(t)
    down = np.zeros_like(t)
    for (label, values), color in zip(parts.items(), itertools.cycle(_PART_COLORS)):
        v = np.nan_to_num(values)
        pos, neg = np.clip(v, 0.0, None), np.clip(v, None, 0.0)
        ax.fill_between(t, up, up + pos, color=color, alpha=0.75, linewidth=0, label=label)
        ax.fill_between(t, down, down + neg, color=color, alpha=0.75, linewidth=0)
        up, down = up + pos, down + neg


def budget_figure(table: SignalTable, columns: BudgetColumns, title: str) -> Figure:
    """The error-budget figure of ``table`` (three panels, see the module). Raises
    ``KeyError`` naming a column the table lacks."""
    _checked(table, columns)
    with _style():
        return _draw_budget(table, columns, title)


def _draw_budget(table: SignalTable, columns: BudgetColumns, title: str) -> Figure:
    every = max(1, len(table.time) // _MAX_POINTS)
    t, t_label = _time_axis(table.time[::every])

    def um(name: str) -> np.ndarray:
        return table[name][::every] * _UM_PER_M

    fig = _new_figure(FIGSIZE_IN)
    drift, budget, temps = fig.subplots(
        3,
        1,
        sharex=True,
        gridspec_kw={
            "height_ratios": [3, 3, 2],
            "left": 0.07,
            "right": 0.79,
            "top": 0.92,
            "bottom": 0.07,
            "hspace": 0.3,
        },
    )
    fig.suptitle(title)

    drift.plot(t, _rise(um(columns.reading)), color="black", linewidth=1.6, label="measured drift (probe)")
    drift.plot(t, um(columns.predicted), color="tab:red", linewidth=1.6, label="predicted error e_z")
    if columns.compensated:
        drift.plot(t, um(columns.compensated), color="tab:green", linewidth=1.2, label="compensated wear")
    drift.axhline(0.0, color="0.6", linewidth=0.6)
    drift.set_ylabel("displacement (µm)")
    drift.set_title("probe reading and the error model's prediction", fontsize="medium", y=1.0)

    _stacked(budget, t, {label: um(column) for label, column in columns.parts.items()})
    budget.plot(t, um(columns.predicted), color="tab:red", linewidth=1.0, linestyle="--", label="sum: e_z")
    budget.axhline(0.0, color="0.3", linewidth=0.6)
    budget.set_ylabel("error part (µm)")
    budget.set_title("error budget: the parts of e_z, stacked", fontsize="medium", y=1.0)

    for name, column in columns.temperature_columns().items():
        temps.plot(t, _rise(table[column][::every]), linewidth=1.0, label=name)
    temps.set_ylabel("temperature rise (K)")
    temps.set_title("temperature rises at the measuring points", fontsize="medium", y=1.0)
    temps.set_xlabel(t_label)

    for ax in (drift, budget, temps):
        _legend_outside(ax)
        ax.grid(True, linewidth=0.3)
    fig.align_ylabels([drift, budget, temps])
    return fig


def wear_figure(table: SignalTable, columns: BudgetColumns, title: str) -> Figure | None:
    """Wear against cycles: true, measured (the probe reading's change) and compensated, in
    µm, with the wear limit as a line; None when ``columns`` name no true wear, compensated
    wear and cycles (see :meth:`BudgetColumns.wear_columns`) or the table lacks one."""
    wear = columns.wear_columns()
    if wear is None or any(c not in table for c in (*wear, columns.reading)):
        return None
    true_wear, compensated, cycles = wear
    every = max(1, len(table.time) // _MAX_POINTS)
    with _style():
        fig = _new_figure(WEAR_FIGSIZE_IN)
        ax = fig.subplots(gridspec_kw={"left": 0.08, "right": 0.71, "top": 0.9, "bottom": 0.12})
        n = table[cycles][::every]
        ax.plot(
            n, _rise(table[true_wear][::every]) * _UM_PER_M, color="black", linewidth=1.8, label="true wear"
        )
        ax.plot(
            n,
            _rise(table[columns.reading][::every]) * _UM_PER_M,
            color="0.55",
            linewidth=1.0,
            label="measured (probe reading change)",
        )
        ax.plot(
            n, table[compensated][::every] * _UM_PER_M, color="tab:green", linewidth=1.4, label="compensated"
        )
        if columns.wear_limit_m is not None:
            limit = columns.wear_limit_m * _UM_PER_M
            ax.axhline(
                limit, color="tab:red", linestyle="--", linewidth=1.2, label=f"wear limit ({limit:g} µm)"
            )
        ax.set_xlabel("swing cycles completed")
        ax.set_ylabel("wear depth (µm)")
        ax.set_title(title, y=1.0)
        ax.grid(True, linewidth=0.3)
        _legend_outside(ax)
    return fig


def save_png(fig: Figure, path: Path) -> Path:
    """Write ``fig`` to the PNG ``path``, whole or not at all (:func:`twin.outputs.atomic.write_atomic`:
    a full disk or a killed plot leaves no cut PNG); returns ``path``."""
    # metadata Software=None drops matplotlib's version stamp: same input -> same bytes.
    return write_atomic(
        path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI, metadata={"Software": None})
    )


def warm_up() -> None:
    """Import matplotlib and draw a throw-away figure with text (loads the fonts): what the
    first plot would pay, paid ahead (:mod:`twin.outputs.plot_process` calls it on start)."""
    import io

    with _style():
        fig = _new_figure((1.0, 1.0))
        ax = fig.subplots()
        ax.set_title("warm-up")
        ax.plot([0.0, 1.0], [0.0, 1.0], label="x")
        ax.legend()
        fig.savefig(io.BytesIO(), format="png", dpi=DPI, metadata={"Software": None})


class _PlotSink(OutcomeSink):
    """A PNG drawn from the outcome's table when the run is over, into ``path``; by the run's
    :class:`~twin.outputs.plot_process.PlotProcess` when given one (``twin run`` starts it
    with the command; else it starts when the run opens its outputs), else in process.

    :meth:`prepare` sends the plot to that process as soon as the outcome is known, so it is
    drawn while the outputs before it close; :meth:`close` waits for it. Subclasses say what
    they draw (:meth:`_job`) and how (:meth:`_draw_here`).
    """

    #: a run interrupted after its co-simulation leaves out the plots not already sent to the
    #: plot process (they only draw what the CSV files hold, and drawing in the run's process
    #: means importing matplotlib, a third of a second)
    skippable = True
    #: the plot process's name for this plot (twin.outputs.plot_process.KINDS)
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

    def prepare(self, outcome: Outcome) -> bool:
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
        (:meth:`prepare`) is abandoned: the process is stopped at once and what it wrote of the
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
                self._draw_here(table, columns)
            except OSError:
                raise  # the file could not be written (a full disk): the run says which
            except Exception as exc:  # as the plot process reports it (plot_process.main)
                raise RunError(f"{self.path.name}: the plot failed: {type(exc).__name__}: {exc}") from exc

    @abstractmethod
    def _job(self, outcome: Outcome) -> tuple[SignalTable, BudgetColumns, list[str]] | None:
        """The table, the columns and the names of the columns the plot draws; None when the
        outcome has nothing for it. Raises ``KeyError`` naming a column the table lacks."""

    @abstractmethod
    def _draw_here(self, table: SignalTable, columns: BudgetColumns) -> None:
        """Draw the plot in this process."""

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
        from twin.outputs.plot_process import columns_json, thinned

        return self.process.send(
            self.kind, self.path, thinned(table, names, _MAX_POINTS), columns_json(columns), self.title
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
        _checked(table, columns)
        names = [columns.reading, columns.predicted, *columns.parts.values(), *present.values()]
        names += [columns.compensated] if columns.compensated else []
        return table, columns, list(dict.fromkeys(names))

    def _draw_here(self, table: SignalTable, columns: BudgetColumns) -> None:
        save_png(budget_figure(table, columns, self.title), self.path)


class WearPlotSink(_PlotSink):
    """``wear.png``: wear against swing cycles with the wear limit (only for a run whose table
    has the true wear, the compensated wear and the cycles)."""

    kind = "wear"

    def _job(self, outcome: Outcome) -> tuple[SignalTable, BudgetColumns, list[str]] | None:
        table = outcome.table
        wear = self.columns.wear_columns()
        if table is None or wear is None or any(c not in table for c in (*wear, self.columns.reading)):
            return None
        return table, self.columns, list(dict.fromkeys([*wear, self.columns.reading]))

    def _draw_here(self, table: SignalTable, columns: BudgetColumns) -> None:
        fig = wear_figure(table, columns, self.title)
        if fig is not None:
            save_png(fig, self.path)
