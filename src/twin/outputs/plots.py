"""The error-budget plot of a run (PNG).

Two stacked panels sharing the time axis: on top the drift of the probe reading, the
predicted error and its parts (µm); below the temperature rises (K). Drawn on a bare
:class:`~matplotlib.figure.Figure` with the Agg canvas, not through ``pyplot``: no display is
needed, no global backend is switched under the caller, and no figure is left open.
Fixed size, dpi and fonts and no ``Software`` metadata make the bytes reproducible.
"""

from __future__ import annotations

import dataclasses
import itertools
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from twin.outputs.sink import OutcomeSink
from twin.signals.table import SignalTable

if TYPE_CHECKING:
    from twin.outputs.sink import Outcome

__all__ = ["DPI", "FIGSIZE_IN", "BudgetColumns", "ErrorBudgetSink", "error_budget_png"]

FIGSIZE_IN = (10.0, 7.0)
DPI = 100  # 1000 x 700 pixels
_UM_PER_M = 1e6
# The parts' colours leave out black and red, which mark the measured drift and the prediction.
_PART_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:purple", "tab:brown", "tab:cyan", "tab:olive")


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
    """Which columns the error-budget plot draws.

    ``reading`` is the probe reading (m), plotted as its drift from the first value;
    ``predicted`` the predicted error (m); ``parts`` maps a legend label (thermal, loading,
    fluctuating, positioning, interference) to the column of that part (m); ``temperatures``
    (K or °C) are shown as rises from their first value.
    """

    reading: str
    predicted: str
    parts: Mapping[str, str]
    temperatures: Sequence[str]

    def missing(self, table: SignalTable) -> list[str]:
        """The columns ``table`` lacks."""
        wanted = [self.reading, self.predicted, *self.parts.values(), *self.temperatures]
        return [name for name in wanted if name not in table]


def error_budget_png(
    table: SignalTable,
    path: str | os.PathLike[str],
    *,
    reading: str,
    predicted: str,
    parts: Mapping[str, str],
    temperatures: Sequence[str],
    title: str,
) -> Path:
    """Draw the error budget of ``table`` to the PNG ``path``; returns ``path``.

    The columns are those of :class:`BudgetColumns`; all lengths are shown in µm.
    Raises ``KeyError`` naming a column the table lacks.
    """
    return _plot(table, Path(path), BudgetColumns(reading, predicted, parts, temperatures), title)


def _plot(table: SignalTable, path: Path, columns: BudgetColumns, title: str) -> Path:
    missing = columns.missing(table)
    if missing:
        raise KeyError(f"columns not in the signal table: {missing}")
    # matplotlib is imported when a plot is drawn: a process that never draws (a sweep's
    # worker) does not pay its second of import
    import matplotlib.style

    # The default style, not the user's matplotlibrc: the same input gives the same bytes anywhere.
    with matplotlib.style.context("default"):
        return _draw(table, path, columns, title)


def _draw(table: SignalTable, path: Path, columns: BudgetColumns, title: str) -> Path:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # at most ~2000 points per line: the figure is 1000 px wide, and drawing every sample of a
    # long run costs seconds without changing a pixel of the trends
    every = max(1, len(table.time) // 2000)
    t, t_label = _time_axis(table.time[::every])

    def col(name: str) -> np.ndarray:
        return table[name][::every]

    fig = Figure(figsize=FIGSIZE_IN, dpi=DPI)
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})

    top.plot(t, _rise(col(columns.reading)) * _UM_PER_M, color="black", linewidth=1.6, label="measured drift")
    top.plot(t, col(columns.predicted) * _UM_PER_M, color="tab:red", linewidth=1.6, label="predicted error")
    for (label, column), color in zip(columns.parts.items(), itertools.cycle(_PART_COLORS)):
        top.plot(t, col(column) * _UM_PER_M, color=color, linewidth=1.0, linestyle="--", label=label)
    top.axhline(0.0, color="0.6", linewidth=0.6)
    top.set_ylabel("error (µm)")
    top.set_title(title)
    top.legend(loc="upper left", fontsize="small", ncols=2, frameon=False)
    top.grid(True, linewidth=0.3)

    for column in columns.temperatures:
        bottom.plot(t, _rise(col(column)), linewidth=1.0, label=column)
    bottom.set_ylabel("temperature rise (K)")
    bottom.set_xlabel(t_label)
    if columns.temperatures:
        bottom.legend(loc="upper left", fontsize="small", ncols=2, frameon=False)
    bottom.grid(True, linewidth=0.3)

    fig.align_ylabels([top, bottom])
    fig.tight_layout()
    # metadata Software=None drops matplotlib's version stamp: same input -> same bytes.
    fig.savefig(path, format="png", dpi=DPI, metadata={"Software": None})
    return path


class ErrorBudgetSink(OutcomeSink):
    """``error_budget.png`` as a sink: drawn from the outcome's table when the run is over.

    Only when the error model ran (the plot shows its prediction); temperatures the table
    lacks are left out rather than failing the plot.
    """

    #: a run interrupted after its co-simulation leaves the plot out (it only draws what
    #: errormodel.csv holds, and importing matplotlib alone takes half a second)
    skippable = True

    def __init__(self, path: Path, columns: BudgetColumns, title: str) -> None:
        self.path = path
        self.columns = columns
        self.title = title

    def write_outcome(self, outcome: Outcome) -> None:
        table = outcome.table
        if table is None:
            return
        present = [name for name in self.columns.temperatures if name in table]
        _plot(table, self.path, dataclasses.replace(self.columns, temperatures=present), self.title)
