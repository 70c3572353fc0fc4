"""The PNG figures of a sweep, drawn for its main output.

- ``sensitivity.png``: Sobol' bars (S1 and ST with their confidence) for a Saltelli design,
  Morris' mu* (with confidence) and sigma for a Morris design, otherwise a tornado of the
  inputs' rank correlations with the main output;
- ``scatter.png``: each input against the main output, one panel per input;
- ``histogram.png``: the distribution of the main output with its 5, 50 and 95 % quantiles.

Drawn on bare :class:`~matplotlib.figure.Figure` objects with the Agg canvas (no display, no
global backend switch) in matplotlib's default style, like the run's error-budget plot.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import matplotlib.style
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from twin.files import write_atomic

DPI = 100
#: at most this many inputs get a scatter panel (the most correlated ones)
MAX_PANELS = 12


def _figure(width: float, height: float) -> Figure:
    fig = Figure(figsize=(width, height), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig: Figure, path: Path) -> Path:
    """Whole or not at all, and a link planted at ``path`` replaced, not written through."""
    fig.tight_layout()
    return write_atomic(
        path, lambda tmp: fig.savefig(tmp, format="png", dpi=DPI, metadata={"Software": None})
    )


def _short(name: str) -> str:
    """The last two parts of a dotted key: enough to tell inputs apart on an axis."""
    return ".".join([p for p in name.split(".") if p != "parameters"][-2:])


def _bars(ax: Axes, labels: list[str], series: dict[str, tuple[list[float], list[float] | None]]) -> None:
    """Grouped horizontal bars, one group per label, optional error bars."""
    y = np.arange(len(labels))
    height = 0.8 / max(1, len(series))
    for k, (name, (values, errors)) in enumerate(series.items()):
        ax.barh(y + k * height, values, height, xerr=errors, label=name, capsize=3)
    ax.set_yticks(y + height * (len(series) - 1) / 2, [_short(s) for s in labels])
    ax.invert_yaxis()
    ax.axvline(0.0, color="0.5", linewidth=0.6)
    ax.grid(True, axis="x", linewidth=0.3)
    if len(series) > 1:
        ax.legend(frameon=False, fontsize="small")


#: the bars of each SALib design: (legend, index, its confidence or None)
_SERIES = {
    "saltelli": (("S1 (first order)", "S1", "S1_conf"), ("ST (total)", "ST", "ST_conf")),
    "morris": (("mu*", "mu_star", "mu_star_conf"), ("sigma", "sigma", None)),
}
_XLABEL = {
    "saltelli": "Sobol' index (95 % confidence)",
    "morris": "elementary effect",
    "tornado": "Spearman rank correlation with the output",
}


def sensitivity_png(
    path: Path, design: str, found: dict[str, Any], ranks: dict[str, float], main: str
) -> Path:
    """Sobol' bars, Morris' mu* and sigma, or (``design="tornado"``) a tornado of the rank
    correlations with ``main``."""
    if design in _SERIES:
        labels = list(found[_SERIES[design][0][1]])
        series = {
            legend: ([found[k][n] for n in labels], [found[c][n] for n in labels] if c else None)
            for legend, k, c in _SERIES[design]
        }
    else:
        labels = sorted(ranks, key=lambda n: -abs(ranks[n]))
        series = {"rank correlation": ([ranks[n] for n in labels], None)}
    with matplotlib.style.context("default"):
        fig = _figure(8.0, 1.2 + 0.45 * max(1, len(labels)) * len(series))
        ax = fig.add_subplot()
        _bars(ax, labels, series)
        if design == "tornado":
            ax.set_xlim(-1.0, 1.0)
        ax.set_xlabel(_XLABEL[design])
        ax.set_title(f"sensitivity of {main}", fontsize="medium")
        return _save(fig, path)


def scatter_png(
    path: Path, table: pd.DataFrame, names: list[str], main: str, ranks: dict[str, float]
) -> Path:
    """Each input (the most correlated first) against ``main``; failed points left out."""
    ok = table[table["status"] == "ok"]
    shown = sorted(names, key=lambda n: -abs(ranks.get(n, 0.0)))[:MAX_PANELS]
    cols = min(3, len(shown))
    rows = math.ceil(len(shown) / cols)
    with matplotlib.style.context("default"):
        fig = _figure(4.0 * cols, 3.2 * rows)
        for k, name in enumerate(shown):
            ax = fig.add_subplot(rows, cols, k + 1)
            x = pd.to_numeric(ok[name], errors="coerce")
            if x.isna().any():  # levels that are not numbers: one position per level
                levels = list(dict.fromkeys(ok[name]))
                x = ok[name].map({v: i for i, v in enumerate(levels)})
                ax.set_xticks(range(len(levels)), [str(v) for v in levels])
            ax.scatter(x, ok[main], s=8, alpha=0.6)
            ax.set_xlabel(_short(name))
            ax.set_ylabel(_short(main))
            ax.grid(True, linewidth=0.3)
        return _save(fig, path)


def histogram_png(path: Path, values: pd.Series, main: str) -> Path:
    """The distribution of ``main`` over the finished points, with its 5/50/95 % quantiles."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    with matplotlib.style.context("default"):
        fig = _figure(7.0, 4.5)
        ax = fig.add_subplot()
        ax.hist(v, bins=max(5, min(50, int(math.sqrt(v.size)) * 2)), color="tab:blue", alpha=0.8)
        for q, style in zip(np.quantile(v, (0.05, 0.5, 0.95)), ("--", "-", "--"), strict=True):
            ax.axvline(q, color="tab:red", linestyle=style, linewidth=1.0)
        ax.set_xlabel(main)
        ax.set_ylabel("points")
        ax.set_title(f"{v.size} points; 5, 50 and 95 % quantiles in red", fontsize="medium")
        ax.grid(True, linewidth=0.3)
        return _save(fig, path)


def draw_all(
    out: Path, design: str, table: pd.DataFrame, names: list[str], summary: dict[str, Any]
) -> list[Path]:
    """Every figure a sweep's results allow (none without a finished point)."""
    main = summary.get("main_output")
    if main is None or main not in table or not (table["status"] == "ok").any():
        return []
    ranks = summary.get("rank_correlation", {})
    found = summary.get("indices", {}).get(main, {})
    kind = design if design in ("saltelli", "morris") and "skipped" not in found else "tornado"
    drawn = [scatter_png(out / "scatter.png", table, names, main, ranks)]
    if ranks or kind != "tornado":
        drawn.append(sensitivity_png(out / "sensitivity.png", kind, found, ranks, main))
    drawn.append(histogram_png(out / "histogram.png", table[main], main))
    return drawn
