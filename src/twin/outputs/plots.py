"""The error-budget plot of a run (PNG).

Two stacked panels sharing the time axis: on top the drift of the probe reading, the
predicted error and its parts (µm); below the temperature rises (K). Drawn on a bare
:class:`~matplotlib.figure.Figure` with the Agg canvas, not through ``pyplot``: no display is
needed, no global backend is switched under the caller, and no figure is left open.
Fixed size, dpi and fonts and no ``Software`` metadata make the bytes reproducible.
"""

from __future__ import annotations

import itertools
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib.style
import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from twin.signals.table import SignalTable

__all__ = ["DPI", "FIGSIZE_IN", "error_budget_png"]

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

    ``reading`` is the probe reading (m), plotted as its drift from the first value;
    ``predicted`` the predicted error (m); ``parts`` maps a legend label (thermal, loading,
    fluctuating, positioning, interference) to the column of that part (m). All lengths are
    shown in µm. ``temperatures`` (K or °C) are shown as rises from their first value.
    Raises ``KeyError`` naming a column the table lacks.
    """
    wanted = [reading, predicted, *parts.values(), *temperatures]
    missing = [name for name in wanted if name not in table]
    if missing:
        raise KeyError(f"columns not in the signal table: {missing}")
    # The default style, not the user's matplotlibrc: the same input gives the same bytes anywhere.
    with matplotlib.style.context("default"):
        return _draw(table, Path(path), reading, predicted, parts, temperatures, title)


def _draw(
    table: SignalTable,
    path: Path,
    reading: str,
    predicted: str,
    parts: Mapping[str, str],
    temperatures: Sequence[str],
    title: str,
) -> Path:
    # at most ~2000 points per line: the figure is 1000 px wide, and drawing every sample of a
    # long run costs seconds without changing a pixel of the trends
    every = max(1, len(table.time) // 2000)
    t, t_label = _time_axis(table.time[::every])

    def col(name: str) -> np.ndarray:
        return table[name][::every]

    fig = Figure(figsize=FIGSIZE_IN, dpi=DPI)
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1, sharex=True, gridspec_kw={"height_ratios": [3, 2]})

    top.plot(t, _rise(col(reading)) * _UM_PER_M, color="black", linewidth=1.6, label="measured drift")
    top.plot(t, col(predicted) * _UM_PER_M, color="tab:red", linewidth=1.6, label="predicted error")
    for (label, column), color in zip(parts.items(), itertools.cycle(_PART_COLORS)):
        top.plot(t, col(column) * _UM_PER_M, color=color, linewidth=1.0, linestyle="--", label=label)
    top.axhline(0.0, color="0.6", linewidth=0.6)
    top.set_ylabel("error (µm)")
    top.set_title(title)
    top.legend(loc="upper left", fontsize="small", ncols=2, frameon=False)
    top.grid(True, linewidth=0.3)

    for column in temperatures:
        bottom.plot(t, _rise(col(column)), linewidth=1.0, label=column)
    bottom.set_ylabel("temperature rise (K)")
    bottom.set_xlabel(t_label)
    if temperatures:
        bottom.legend(loc="upper left", fontsize="small", ncols=2, frameon=False)
    bottom.grid(True, linewidth=0.3)

    fig.align_ylabels([top, bottom])
    fig.tight_layout()
    # metadata Software=None drops matplotlib's version stamp: same input -> same bytes.
    fig.savefig(path, format="png", dpi=DPI, metadata={"Software": None})
    return path
