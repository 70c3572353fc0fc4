"""The plots of a run (PNG): the error budget, and wear against cycles for an endurance test.

``error_budget.png`` has three panels sharing the time axis: the probe reading's change (wear
and error together) with the predicted error (and the compensated wear), the parts of the
prediction the error model evaluates as stacked areas (positive parts stacked up from zero,
negative ones down; a factor switched off is not listed, the panel's title names it), and the
temperature rises. A replay of a measured experiment draws its measured drift (the paper's,
never fitted) beside the curves. Every axis names its quantity and unit, every curve says what
it includes, and the legends sit to the right of the panels, outside the curves. All lengths
are in µm.

Honest at any length: a long record is drawn from the rows :func:`twin.signals.decimate.plot_rows`
keeps, every bucket's extremes among them, so a spike between two drawn rows is never lost,
and each curve (an area: its two edges) is drawn through those of its own (:func:`_own_rows`);
an axis is scaled to where its curves mostly are (a single -12 µm spike no longer squashes
a +-2 µm signal to a line): samples beyond it are drawn as triangles on its edge, and the
legend says how many and how far they reach (:func:`_robust_limits`).

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
from twin.signals.decimate import plot_rows
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
    "drawn_rows",
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
#: the share of a panel's samples its scale may leave out at each end (as outliers marked on
#: its edge), and how far beyond that share the rest may reach before it does (in units of the
#: range of the samples kept): a drift's own ends are always inside
OUTLIER_SHARE = 0.01
OUTLIER_REACH = 0.5
#: the colour of a measured experiment's values (the paper's drift)
_MEASURED_COLOR = "tab:purple"


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
    :func:`human_name`), shown as rises from their first value; ``parts`` lists only the
    factors evaluated (``disabled`` names the others). ``compensated`` (m) is drawn
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
    #: the factors switched off (their labels), named in the budget panel's title
    disabled: Sequence[str] = ()
    #: the drift a replayed experiment measured at the probe over the run (m), and who measured
    #: it: drawn on the drift panel (the paper's -21 µm for its replay; never fitted)
    measured_drift_m: float | None = None
    measured_by: str = ""

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

    def budget_names(self) -> list[str]:
        """The columns the error-budget plot draws, each once."""
        names = [self.reading, self.predicted, *self.parts.values(), *self.temperature_columns().values()]
        return list(dict.fromkeys([*names, *([self.compensated] if self.compensated else [])]))

    def wear_names(self) -> list[str]:
        """The columns the wear plot draws (none when it draws nothing)."""
        wear = self.wear_columns()
        return list(dict.fromkeys([*wear, self.reading])) if wear else []

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


def _stacked(ax: Axes, t: np.ndarray, t_s: np.ndarray, parts: Mapping[str, np.ndarray]) -> None:
    """The parts as stacked areas: positive values stacked up from zero, negative ones down
    (a plain stack of mixed signs would hide a part under its neighbour). Each area is drawn
    through its own edges' extremes (:func:`_own_rows`, on the times ``t_s`` in seconds)."""
    up = np.zeros_like(t)
    down = np.zeros_like(t)
    for (label, values), color in zip(parts.items(), itertools.cycle(_PART_COLORS)):
        v = np.nan_to_num(values)
        top, bottom = up + np.clip(v, 0.0, None), down + np.clip(v, None, 0.0)
        for lower, upper, name in ((up, top, label), (down, bottom, None)):
            r = _own_rows(t_s, lower, upper)
            ax.fill_between(t[r], lower[r], upper[r], color=color, alpha=0.75, linewidth=0, label=name)
        up, down = top, bottom


def _own_rows(t_s: np.ndarray, *curves: np.ndarray) -> np.ndarray:
    """Of a plot's rows (times ``t_s`` in seconds), those one curve (an area: its two edges) is
    drawn through: every bucket's extremes of its own values, all of them up to
    :data:`~twin.signals.decimate.LIMIT` rows. The plot's rows hold every column's extremes;
    a line through its own keeps each spike of its own at a fraction of the vertices (a long
    run's panel of sixteen curves drew all of its 13,000 rows for each). Picked from the plot's
    rows, so a plot drawn from them (:func:`twin.outputs.plot_process.thinned`) draws the same."""
    return plot_rows(t_s, curves)


def _line(ax: Axes, t: np.ndarray, t_s: np.ndarray, values: np.ndarray, **style: Any) -> Any:
    """``values`` against ``t`` through their own extremes (:func:`_own_rows`); the line."""
    r = _own_rows(t_s, values)
    return ax.plot(t[r], values[r], **style)[0]


def drawn_rows(table: SignalTable, names: Sequence[str]) -> np.ndarray:
    """The rows of ``table`` a plot of its columns ``names`` draws (every bucket's extremes:
    :func:`twin.signals.decimate.plot_rows`)."""
    return plot_rows(table.time, [table[n] for n in names])


def _robust_limits(
    ax: Axes,
    t: np.ndarray,
    curves: Sequence[tuple[np.ndarray, str]],
    also: Sequence[float] = (),
    unit: str = "µm",
) -> None:
    """Scale ``ax`` to where its ``curves`` (values, colour) mostly are, and mark the samples
    beyond that scale as triangles on its edge, with one legend entry saying how many and how
    far they reach. A sample is beyond only when it lies more than :data:`OUTLIER_REACH`
    ranges beyond the :data:`OUTLIER_SHARE` quantiles: every other sample stays inside, and a
    panel without such samples keeps matplotlib's own limits. ``also`` are values the scale
    must show (a measured value, zero)."""
    values = np.concatenate([v[np.isfinite(v)] for v, _ in curves]) if curves else np.zeros(0)
    if values.size < 20:
        return
    lo, hi = (float(q) for q in np.quantile(values, [OUTLIER_SHARE, 1.0 - OUTLIER_SHARE]))
    reach = OUTLIER_REACH * max(hi - lo, 1e-9 * max(abs(lo), abs(hi), 1e-30))
    inside = values[(values >= lo - reach) & (values <= hi + reach)]
    bottom, top = min([float(inside.min()), *also]), max([float(inside.max()), *also])
    vmin, vmax = float(values.min()), float(values.max())
    if bottom <= vmin and vmax <= top:
        return  # nothing far out (or what is, a measured value shows anyway)
    margin = 0.08 * max(top - bottom, reach)
    bottom, top = bottom - margin, top + margin
    ax.set_ylim(bottom, top)
    outside = 0
    for v, color in curves:
        for beyond, edge, marker in ((v < bottom, bottom, "v"), (v > top, top, "^")):
            if beyond.any():
                outside += int(beyond.sum())
                ax.plot(t[beyond], np.full(int(beyond.sum()), edge), linestyle="none", marker=marker,
                        color=color, markersize=7, clip_on=False, zorder=5)  # fmt: skip
    reaching = [f"down to {vmin:.3g}"] if vmin < bottom else []
    reaching += [f"up to {vmax:.3g}"] if vmax > top else []
    ax.plot([], [], linestyle="none", marker="v" if vmin < bottom else "^", color="0.3",
            label=f"{outside} sample(s) beyond the scale,\non its edge ({' and '.join(reaching)} {unit})")  # fmt: skip


def budget_figure(table: SignalTable, columns: BudgetColumns, title: str) -> Figure:
    """The error-budget figure of ``table`` (three panels, see the module). Raises
    ``KeyError`` naming a column the table lacks."""
    checked(table, columns)
    with _style():
        return _draw_budget(table, columns, title)


def _draw_budget(table: SignalTable, columns: BudgetColumns, title: str) -> Figure:
    rows = drawn_rows(table, columns.budget_names())
    t_s = table.time[rows]
    t, t_label = _time_axis(t_s)

    def um(name: str) -> np.ndarray:
        return table[name][rows] * _UM_PER_M

    fig = _new_figure(FIGSIZE_IN)
    drift, budget, temps = fig.subplots(
        3,
        1,
        sharex=True,
        gridspec_kw={
            "height_ratios": [3, 3, 2],
            "left": 0.07,
            "right": 0.77,
            "top": 0.92,
            "bottom": 0.07,
            "hspace": 0.3,
        },
    )
    fig.suptitle(title)
    _draw_drift(drift, t, t_s, um, columns)

    parts = {label: um(column) for label, column in columns.parts.items()}
    _stacked(budget, t, t_s, parts)
    e_z = um(columns.predicted)
    _line(budget, t, t_s, e_z, color="tab:red", linewidth=1.0, linestyle="--", label="sum: e_z")
    budget.axhline(0.0, color="0.3", linewidth=0.6)
    budget.set_ylabel("error part (µm)")
    off = f" ({', '.join(columns.disabled)} switched off)" if columns.disabled else ""
    budget.set_title(f"error budget: the parts of e_z, stacked{off}", fontsize="medium", y=1.0)
    stack = [np.nan_to_num(v) for v in parts.values()]
    ups = np.cumsum([np.clip(v, 0.0, None) for v in stack], axis=0) if stack else []
    downs = np.cumsum([np.clip(v, None, 0.0) for v in stack], axis=0) if stack else []
    _robust_limits(budget, t, [(e_z, "tab:red"), *((v, "0.3") for v in (*ups, *downs))], also=(0.0,))

    rises = []
    for name, column in columns.temperature_columns().items():
        rise = _rise(table[column][rows])
        line = _line(temps, t, t_s, rise, linewidth=1.0, label=name)
        rises.append((rise, line.get_color()))
    _robust_limits(temps, t, rises, unit="K")
    temps.set_ylabel("temperature rise (K)")
    temps.set_title("temperature rises at the measuring points", fontsize="medium", y=1.0)
    temps.set_xlabel(t_label)

    for ax in (drift, budget, temps):
        _legend_outside(ax)
        ax.grid(True, linewidth=0.3)
    fig.align_ylabels([drift, budget, temps])
    return fig


def _draw_drift(ax: Axes, t: np.ndarray, t_s: np.ndarray, um: Any, columns: BudgetColumns) -> None:
    """The probe reading's change (all it includes: the wear and every error), the predicted
    error, the compensated wear, and a replayed experiment's measured drift."""
    curves = [
        (_rise(um(columns.reading)), "black", 1.6, "probe reading change\n(wear + errors)"),
        (um(columns.predicted), "tab:red", 1.6, "predicted error e_z"),
    ]
    if columns.compensated:
        curves.append((um(columns.compensated), "tab:green", 1.2, "compensated wear\n(reading change − e_z)"))
    for values, color, width, label in curves:
        _line(ax, t, t_s, values, color=color, linewidth=width, label=label)
    also = [0.0]
    if columns.measured_drift_m is not None and t.size:
        measured = columns.measured_drift_m * _UM_PER_M
        by = f" ({columns.measured_by})" if columns.measured_by else ""
        ax.axhline(measured, color=_MEASURED_COLOR, linestyle=":", linewidth=1.2)
        ax.plot([t[-1]], [measured], color=_MEASURED_COLOR, marker="*", markersize=12, linestyle="none",
                label=f"measured drift{by}:\n{measured:+.1f} µm at the end", zorder=6)  # fmt: skip
        also.append(measured)
    ax.axhline(0.0, color="0.6", linewidth=0.6)
    ax.set_ylabel("displacement (µm)")
    ax.set_title("probe reading and the error model's prediction", fontsize="medium", y=1.0)
    _robust_limits(ax, t, [(v, c) for v, c, _, _ in curves], also=also)


def wear_figure(table: SignalTable, columns: BudgetColumns, title: str) -> Figure | None:
    """Wear against cycles: true, measured (the probe reading's change) and compensated, in
    µm, with the wear limit as a line; None when ``columns`` name no true wear, compensated
    wear and cycles (see :meth:`BudgetColumns.wear_columns`) or the table lacks one."""
    wear = columns.wear_columns()
    if wear is None or any(c not in table for c in (*wear, columns.reading)):
        return None
    true_wear, compensated, cycles = wear
    rows = drawn_rows(table, columns.wear_names())
    with _style():
        fig = _new_figure(WEAR_FIGSIZE_IN)
        ax = fig.subplots(gridspec_kw={"left": 0.08, "right": 0.71, "top": 0.9, "bottom": 0.12})
        n = table[cycles][rows]
        t_s = table.time[rows]
        curves = []
        for values, color, width, label in (
            (_rise(table[true_wear][rows]) * _UM_PER_M, "black", 1.8, "true wear"),
            (
                _rise(table[columns.reading][rows]) * _UM_PER_M,
                "0.55",
                1.0,
                "probe reading change\n(wear + errors)",
            ),
            (
                table[compensated][rows] * _UM_PER_M,
                "tab:green",
                1.4,
                "compensated wear\n(reading change − e_z)",
            ),
        ):
            _line(ax, n, t_s, values, color=color, linewidth=width, label=label)
            curves.append((values, color))
        if columns.wear_limit_m is not None:
            limit = columns.wear_limit_m * _UM_PER_M
            ax.axhline(
                limit, color="tab:red", linestyle="--", linewidth=1.2, label=f"wear limit ({limit:g} µm)"
            )
        _robust_limits(ax, np.asarray(n, dtype=float), curves)
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
