"""The plots: real PNGs of the fixed size, identical bytes for identical input, and figures a person
can read (checked on matplotlib's objects: labels with units, legends outside, the stacked budget,
the wear plot's MIL limit line)."""

from __future__ import annotations

import itertools
import re
import struct
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.collections import PolyCollection
from matplotlib.figure import Figure

from twin.outputs.plots import DPI, FIGSIZE_IN, BudgetColumns, budget_figure, error_budget_png, wear_figure
from twin.signals.table import Signal, SignalTable

from .sample import PARTS, make_table

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _draw(table: SignalTable, path: Path) -> Path:
    columns = BudgetColumns(
        "probe.reading", "errormodel.e_total", PARTS, ["thermal.t_base", "thermal.t_spindle"]
    )
    return error_budget_png(table, path, columns, "Paper experiment: error budget")


def test_png_signature_and_size(table: SignalTable, tmp_path: Path) -> None:
    path = _draw(table, tmp_path / "budget.png")
    assert path == tmp_path / "budget.png"
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    assert (width, height) == (round(FIGSIZE_IN[0] * DPI), round(FIGSIZE_IN[1] * DPI))
    pixels = matplotlib.image.imread(path)
    assert pixels.shape[:2] == (height, width)
    # Something was drawn: a good share of the pixels are not white.
    assert np.mean(pixels[..., :3].min(axis=-1) < 0.9) > 0.02


def test_same_input_same_bytes_and_no_software_stamp(tmp_path: Path) -> None:
    a = _draw(make_table(), tmp_path / "a.png").read_bytes()
    b = _draw(make_table(), tmp_path / "b.png").read_bytes()
    assert a == b
    assert b"matplotlib" not in a.lower()
    assert a != _draw(make_table(seed=8), tmp_path / "c.png").read_bytes()


def test_short_and_long_runs_draw(tmp_path: Path) -> None:
    # 4 h switches the axis to hours; 1 row must not fail either.
    long = make_table(rows=1441, seed=3)  # 10 s steps -> 4 h
    assert _draw(long, tmp_path / "long.png").read_bytes()[:8] == PNG_SIGNATURE
    one = make_table(rows=1)
    assert _draw(one, tmp_path / "one.png").read_bytes()[:8] == PNG_SIGNATURE


def test_missing_column_is_named(table: SignalTable, tmp_path: Path) -> None:
    with pytest.raises(KeyError, match=r"thermal\.nope"):
        error_budget_png(
            table,
            tmp_path / "x.png",
            BudgetColumns("probe.reading", "errormodel.e_total", PARTS, ["thermal.nope"]),
            "x",
        )
    assert not (tmp_path / "x.png").exists()


# ----------------------------------------------------------------------------- what a person reads


def _columns(**extra: object) -> BudgetColumns:
    return BudgetColumns(
        "probe.reading",
        "errormodel.e_total",
        PARTS,
        {"base": "thermal.t_base", "t_plate": "thermal.t_spindle"},
        **extra,  # type: ignore[arg-type]
    )


def _has_unit(label: str) -> bool:
    return bool(re.search(r"\((µm|K|h|min)\)$", label))


def _legend_outside(fig: Figure, ax: Axes) -> bool:
    """The legend's box lies right of the panel's (drawn, so the boxes are real pixels)."""
    fig.canvas.draw()
    legend = ax.get_legend()
    return legend is not None and legend.get_window_extent().x0 >= ax.get_window_extent().x1


def test_every_panel_names_its_quantity_and_unit_and_the_legends_sit_outside(table: SignalTable) -> None:
    fig = budget_figure(table, _columns(), "sample")
    drift, budget, temps = fig.axes
    for ax in (drift, budget, temps):
        assert _has_unit(ax.get_ylabel()), ax.get_ylabel()
        assert _legend_outside(fig, ax)
    assert _has_unit(temps.get_xlabel()) and temps.get_xlabel().startswith("time")
    assert "µm" in drift.get_ylabel() and "µm" in budget.get_ylabel() and "K" in temps.get_ylabel()
    # human names, not column names
    labels = [t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()]
    assert not any("." in label for label in labels), labels
    assert {"base", "T-plate"} <= set(temps.get_legend_handles_labels()[1])


def test_the_panels_do_not_overlap(table: SignalTable) -> None:
    fig = budget_figure(table, _columns(), "sample")
    fig.canvas.draw()
    boxes = [ax.get_tightbbox() for ax in fig.axes]  # each panel with its labels
    for upper, lower in itertools.pairwise(boxes):
        assert upper.y0 >= lower.y1 - 1, (upper, lower)  # a pixel of rounding


def test_the_budget_stacks_the_five_parts_and_their_sum_is_the_prediction(table: SignalTable) -> None:
    fig = budget_figure(table, _columns(), "sample")
    budget = fig.axes[1]
    areas = [
        c for c in budget.collections if isinstance(c, PolyCollection) and not c.get_label().startswith("_")
    ]
    assert [a.get_label() for a in areas] == list(PARTS)
    # the top of the stack (all parts positive in the sample) is the sum of the parts in µm
    top = areas[-1].get_paths()[0].vertices[:, 1].max()
    expected = sum(table[c] for c in PARTS.values()).max() * 1e6
    assert top == pytest.approx(expected, rel=1e-9)


def _wear_table() -> SignalTable:
    table = make_table()
    n = len(table)
    wear = np.linspace(0.0, 120e-6, n)
    table.add(Signal("mechanics.wear_depth_true", "m", "mechanics"), wear)
    table.add(Signal("errormodel.wear_compensated", "m", "errormodel"), wear + 1e-6)
    table.add(Signal("oscillation.cycles", "1", "oscillation"), np.floor(np.arange(n) * 10.0 / 6.0))
    return table


def test_the_wear_plot_draws_true_measured_compensated_and_the_mil_limit() -> None:
    columns = _columns(
        compensated="errormodel.wear_compensated",
        true_wear="mechanics.wear_depth_true",
        cycles="oscillation.cycles",
        wear_limit_m=0.152e-3,
    )
    fig = wear_figure(_wear_table(), columns, "endurance")
    assert fig is not None
    (ax,) = fig.axes
    assert ax.get_ylabel() == "wear depth (µm)" and "cycles" in ax.get_xlabel()
    lines = {line.get_label(): line for line in ax.get_lines()}
    assert {
        "true wear",
        "probe reading change\n(wear + errors)",
        "compensated wear\n(reading change − e_z)",
    } <= set(lines)
    (limit,) = [line for label, line in lines.items() if label.startswith("wear limit")]
    assert list(limit.get_ydata()) == [pytest.approx(152.0)] * 2  # a horizontal line at 0.152 mm
    assert lines["true wear"].get_ydata()[-1] == pytest.approx(120.0)
    assert _legend_outside(fig, ax)


def test_no_wear_plot_without_true_wear_or_cycles() -> None:
    assert wear_figure(_wear_table(), _columns(), "x") is None
    no_cycles = _columns(compensated="errormodel.wear_compensated", true_wear="mechanics.wear_depth_true")
    assert wear_figure(_wear_table(), no_cycles, "x") is None


def test_the_endurance_scenario_declares_the_mil_limit_and_its_run_gets_the_wear_plot() -> None:
    from twin.pipeline import prepare
    from twin.pipeline.stages import budget_columns

    endurance = prepare("mil-endurance")
    columns = budget_columns(endurance.evaluation, endurance)
    assert columns.wear_limit_m == pytest.approx(0.152e-3)  # facts 4
    assert columns.wear_columns() == (
        "mechanics.wear_depth_true",
        "errormodel.wear_compensated",
        "oscillation.cycles",
    )
    sine = prepare("sine-load")
    assert budget_columns(sine.evaluation, sine).wear_limit_m is None
