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

import itertools
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from twin.files import write_atomic
from twin.signals.table import SignalTable

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure


__all__ = [
    "DPI",
    "FIGSIZE_IN",
    "KINDS",
    "WEAR_FIGSIZE_IN",
    "BudgetColumns",
    "budget_figure",
    "draw",
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
MAX_POINTS = 2000


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
    table: SignalTable, path: str | os.PathLike[str], columns: BudgetColumns, title: str
) -> Path:
    """Draw the error budget of ``table`` (its ``columns``) to the PNG ``path``; returns
    ``path``. All lengths are shown in µm. Raises ``KeyError`` naming a column the table lacks.
    """
    return save_png(budget_figure(table, columns, title), Path(path))


def checked(table: SignalTable, columns: BudgetColumns) -> None:
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
    checked(table, columns)
    with _style():
        return _draw_budget(table, columns, title)


def _draw_budget(table: SignalTable, columns: BudgetColumns, title: str) -> Figure:
    every = max(1, len(table.time) // MAX_POINTS)
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
    every = max(1, len(table.time) // MAX_POINTS)
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
    """Write ``fig`` to the PNG ``path``, whole or not at all (:func:`twin.files.write_atomic`:
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


#: the plots a run draws, by kind: :func:`draw` makes them (in the run's process or its helper)
KINDS = ("budget", "wear")


def draw(kind: str, table: SignalTable, columns: BudgetColumns, title: str, path: Path) -> None:
    """Draw the plot ``kind`` (one of :data:`KINDS`) of ``table`` into the PNG ``path``; the
    wear plot of a table without wear is not drawn."""
    if kind == "budget":
        save_png(budget_figure(table, columns, title), path)
        return
    fig = wear_figure(table, columns, title)
    if fig is not None:
        save_png(fig, path)
