"""The PNG figures of a sweep, drawn for its main output.

- ``sensitivity.png``: Sobol' bars (S1 and ST with their confidence) for a Saltelli design,
  Morris' mu* (with confidence) and sigma for a Morris design, PAWN indices with the dummy
  input's noise floor for a sampled design, a tornado of the rank correlations for a grid;
- ``scatter.png``: each input against the main output, one panel per input, the most
  influential first (by the design's indices: the main driver is always among them);
- ``histogram.png``: the distribution of the main output with its 5, 50 and 95 % quantiles.

Axes name their quantity in words with its unit: a design key's unit is its FMU variable's
(an input profile's amplitude is in its input's unit, its period in s), an output's is the
unit its figure's name carries (``residual_rms_um`` is in um); counts are whole numbers.

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
from matplotlib.ticker import MaxNLocator

from twin.config.spec import PROFILE_DURATIONS, Scenario
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


#: unit suffixes of the figures' names (``drift_mm``, ``temperature_rise_C``) and how they read
_FIGURE_UNITS = {"um": "µm", "mm": "mm", "m": "m", "C": "°C", "K": "K", "s": "s", "N": "N", "pct": "%"}


def figure_label(name: str) -> str:
    """``compensation.residual_rms_um.after`` -> ``compensation residual rms after (µm)``."""
    unit, words = "", []
    for part in name.split("."):
        stem, _, tail = part.rpartition("_")
        if stem and tail in _FIGURE_UNITS and not unit:
            unit, part = _FIGURE_UNITS[tail], stem
        words.append(part.replace("_", " "))
    return " ".join(words) + (f" ({unit})" if unit else "")


def key_label(key: str, scenario: Scenario | None) -> str:
    """A design key in words with its unit: ``fmu.thermal.parameters.g_base_room`` ->
    ``thermal g_base_room (W/K)``, ``input.thermal.t_room.amplitude`` -> ``t_room amplitude (K)``."""
    parts = key.split(".")
    unit = ""
    if scenario is not None and parts[0] == "fmu" and len(parts) == 4:
        try:
            unit = scenario.fmu(parts[1]).unit(parts[3])
        except KeyError:
            unit = ""
        text = f"{parts[1]} {parts[3]}"
    elif scenario is not None and parts[0] == "input" and len(parts) == 4:
        try:
            unit = "s" if parts[3] in PROFILE_DURATIONS else scenario.fmu(parts[1]).unit(parts[2])
        except KeyError:
            unit = ""
        text = f"{parts[2]} {parts[3]}"
    else:
        text = _short(key)
    return text + (f" ({unit})" if unit and unit != "1" else "")


def labels(names: list[str], outputs: list[str], scenario: Scenario | None) -> dict[str, str]:
    """Every axis label of a sweep's figures: design keys and outputs."""
    return {n: key_label(n, scenario) for n in names} | {o: figure_label(o) for o in outputs}


def _bars(
    ax: Axes,
    labels: list[str],
    series: dict[str, tuple[list[float], list[float] | None]],
    names: dict[str, str],
) -> None:
    """Grouped horizontal bars, one group per label, optional error bars."""
    y = np.arange(len(labels))
    height = 0.8 / max(1, len(series))
    for k, (name, (values, errors)) in enumerate(series.items()):
        ax.barh(y + k * height, values, height, xerr=errors, label=name, capsize=3)
    ax.set_yticks(y + height * (len(series) - 1) / 2, [names.get(s, _short(s)) for s in labels])
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
    "pawn": "PAWN index (median KS distance over slices; dashed: a dummy input's)",
    "tornado": "Spearman rank correlation with the output",
}


def sensitivity_png(path: Path, design: str, found: dict[str, Any], main: str, names: dict[str, str]) -> Path:
    """Sobol' bars, Morris' mu* and sigma, PAWN (``design="pawn"``: ``found`` is the
    summary's ``pawn``) or a tornado of the rank correlations (``design="tornado"``: ``found``
    maps each input to its correlation with ``main``)."""
    if design in _SERIES:
        keys = list(found[_SERIES[design][0][1]])
        series = {
            legend: ([found[k][n] for n in keys], [found[c][n] for n in keys] if c else None)
            for legend, k, c in _SERIES[design]
        }
    elif design == "pawn":
        keys = sorted(found["pawn"], key=lambda n: -found["pawn"][n])
        series = {"PAWN": ([found["pawn"][n] for n in keys], None)}
    else:
        keys = sorted(found, key=lambda n: -abs(found[n]))
        series = {"rank correlation": ([found[n] for n in keys], None)}
    with matplotlib.style.context("default"):
        fig = _figure(9.0, 1.4 + 0.45 * max(1, len(keys)) * len(series))
        ax = fig.add_subplot()
        _bars(ax, keys, series, names)
        if design == "tornado":
            ax.set_xlim(-1.0, 1.0)
        if design == "pawn":
            ax.axvline(found["pawn_dummy"], color="tab:red", linestyle="--", linewidth=1.0)
        ax.set_xlabel(_XLABEL[design])
        ax.set_title(f"sensitivity of {names.get(main, main)}", fontsize="medium")
        return _save(fig, path)


def scatter_png(path: Path, table: pd.DataFrame, keys: list[str], main: str, names: dict[str, str]) -> Path:
    """Each input against ``main``, in the order of ``keys`` (the most influential first),
    at most :data:`MAX_PANELS`; failed points left out."""
    ok = table[table["status"] == "ok"]
    shown = keys[:MAX_PANELS]
    cols = min(3, len(shown))
    rows = math.ceil(len(shown) / cols)
    with matplotlib.style.context("default"):
        fig = _figure(4.2 * cols, 3.3 * rows)
        for k, name in enumerate(shown):
            ax = fig.add_subplot(rows, cols, k + 1)
            x = pd.to_numeric(ok[name], errors="coerce")
            if x.isna().any():  # levels that are not numbers: one position per level
                levels = list(dict.fromkeys(ok[name]))
                x = ok[name].map({v: i for i, v in enumerate(levels)})
                ax.set_xticks(range(len(levels)), [str(v) for v in levels])
            ax.scatter(x, ok[main], s=8, alpha=0.6)
            ax.set_xlabel(names.get(name, _short(name)), fontsize="small")
            ax.set_ylabel(names.get(main, main), fontsize="small")
            ax.grid(True, linewidth=0.3)
        return _save(fig, path)


def histogram_png(path: Path, values: pd.Series, label: str) -> Path:
    """The distribution of an output over the finished points, with its 5/50/95 % quantiles."""
    return _save(histogram_figure(values, label), path)


def histogram_figure(values: pd.Series, label: str) -> Figure:
    """The figure of :func:`histogram_png` (``label``: the output's axis label)."""
    v = values.to_numpy(dtype=float)
    v = v[np.isfinite(v)]
    with matplotlib.style.context("default"):
        fig = _figure(7.0, 4.5)
        ax = fig.add_subplot()
        ax.hist(v, bins=max(5, min(50, int(math.sqrt(v.size)) * 2)), color="tab:blue", alpha=0.8)
        for q, style in zip(np.quantile(v, (0.05, 0.5, 0.95)), ("--", "-", "--"), strict=True):
            ax.axvline(q, color="tab:red", linestyle=style, linewidth=1.0)
        ax.set_xlabel(label)
        ax.set_ylabel("points")
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))  # a count of points is whole
        ax.set_title(f"{v.size} points; 5, 50 and 95 % quantiles in red", fontsize="medium")
        ax.grid(True, linewidth=0.3)
        fig.tight_layout()
        return fig


def ranking(design: str, summary: dict[str, Any], names: list[str]) -> tuple[str, dict[str, Any], list[str]]:
    """Which sensitivity figure the summary allows (its kind and its numbers) and the inputs
    from the most influential down: by ST, mu*, PAWN, else the rank correlation's size."""
    main = summary.get("main_output")
    found = summary.get("indices", {}).get(main, {})
    ranks = summary.get("rank_correlation", {})
    pawn = summary.get("pawn", {})
    if design in _SERIES and "skipped" not in found and found:
        by = found["ST" if design == "saltelli" else "mu_star"]
        score = {n: abs(by.get(n, 0.0)) for n in names}
        kind = design
    elif pawn:
        score, kind, found = dict(pawn["pawn"]), "pawn", pawn
    else:
        score, kind, found = {n: abs(v) for n, v in ranks.items()}, "tornado", ranks
    order = sorted(names, key=lambda n: -score.get(n, -1.0))
    return kind, found, order


def draw_all(
    out: Path,
    design: str,
    table: pd.DataFrame,
    keys: list[str],
    summary: dict[str, Any],
    names: dict[str, str],
) -> list[Path]:
    """Every figure a sweep's results allow (none without a finished point); ``names`` are
    the axis labels of keys and outputs (:func:`labels`)."""
    main = summary.get("main_output")
    if main is None or main not in table or not (table["status"] == "ok").any():
        return []
    kind, found, order = ranking(design, summary, keys)
    drawn = [scatter_png(out / "scatter.png", table, order, main, names)]
    if found:
        drawn.append(sensitivity_png(out / "sensitivity.png", kind, found, main, names))
    drawn.append(histogram_png(out / "histogram.png", table[main], names.get(main, main)))
    return drawn
