"""Honest pictures (issue 33): a long record's plot keeps every spike (extremes per bucket, not an
even stride), an axis is scaled to its signal with the samples beyond marked on its edge, the
curves say what they include, a switched-off factor is not in the legend, and a replay of the
paper draws the paper's measured drift."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from twin.cli import main
from twin.errormodel.sources import DEFAULT_TEMPERATURES
from twin.outputs import plots
from twin.signals.decimate import BUCKETS, LIMIT, extreme_rows, plot_rows

READING = "probe reading change\n(wear + errors)"
#: the two spikes injected into the lab's probe reading (m): far beyond its +-2 µm signal
SPIKES = (-12e-6, +9e-6)


def _lab_csv(path: Path, rows: int) -> np.ndarray:
    """A lab's file at 1 s: eight temperatures rising 1 K, a probe drifting -2 µm with a 1 µm
    wobble, and the two spikes at a third and two thirds of the record; returns the spikes'
    times (s)."""
    t = np.arange(rows, dtype=float)
    rise = 1.0 - np.exp(-t / max(rows / 4, 1.0))
    probe = 4.8e-3 - 2e-6 * rise + 1e-6 * np.sin(t / max(rows / 40, 1.0))
    at = np.array([rows // 3, 2 * rows // 3])
    probe[at] += SPIKES
    temps = 293.15 + rise
    names = [f"T{i}" for i in range(8)]
    data = np.column_stack([t, *([temps] * 8), probe])
    header = "time," + ",".join(names) + ",probe"
    np.savetxt(path, data, delimiter=",", header=header, comments="", fmt="%.10g")
    return t[at]


def _config(path: Path) -> Path:
    points = list(DEFAULT_TEMPERATURES)
    path.write_text(
        '[errormodel]\nreading = "probe"\nfactors = ["thermal"]\ntemperatures = { '
        + ", ".join(f'{p} = "T{i}"' for i, p in enumerate(points))
        + " }\n"
    )
    return path


@pytest.mark.parametrize("rows", [600, LIMIT - 1, LIMIT + 1, 37_003, 250_000])
def test_a_lab_files_two_spikes_are_in_error_budget_png_at_any_row_count(
    rows: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    figures = []
    real = plots.budget_figure

    def keep(*args, **kwargs):  # the real figure, kept to read its artists back
        figures.append(real(*args, **kwargs))
        return figures[-1]

    monkeypatch.setattr(plots, "budget_figure", keep)
    spike_s = _lab_csv(tmp_path / "lab.csv", rows)
    out = tmp_path / "out"
    args = ["compensate", str(tmp_path / "lab.csv"), "--config", str(_config(tmp_path / "lab.toml"))]
    assert main([*args, "--out", str(out)]) == 0
    assert (out / "error_budget.png").stat().st_size > 0
    (fig,) = figures
    drift = fig.axes[0]
    lines = {line.get_label(): line for line in drift.get_lines()}
    reading = lines[READING]
    x, y = np.asarray(reading.get_xdata()), np.asarray(reading.get_ydata())
    assert len(x) <= 20 * 1000  # thinned (a few rows a bucket), not every row of a long file
    scale = 3600.0 if rows >= 3 * 3600 else 60.0
    bottom, top = drift.get_ylim()
    markers = [
        ln for ln in drift.get_lines() if ln.get_linestyle() == "None" and ln.get_marker() in ("v", "^")
    ]
    for t_s, spike in zip(spike_s, SPIKES, strict=True):
        at = np.flatnonzero(np.isclose(x, t_s / scale, rtol=0, atol=1e-9))
        assert at.size == 1, f"the spike at {t_s} s is not among the drawn samples"
        assert y[at[0]] == pytest.approx(spike * 1e6, abs=3.0)  # the spike's value, on a +-2 µm drift
        if not bottom <= y[at[0]] <= top:  # beyond the scale: marked on its edge at its time
            edge = bottom if spike < 0 else top
            assert any(
                np.any(np.isclose(m.get_xdata(), t_s / scale, atol=1e-9) & np.isclose(m.get_ydata(), edge))
                for m in markers
            ), "a spike beyond the scale is not marked"
    # the spikes do not set the scale: the +-2 µm signal keeps most of the panel
    assert top - bottom < 10.0, (bottom, top)
    legend = [t.get_text() for t in drift.get_legend().get_texts()]
    # each spike twice: on the reading and on the compensated wear (the interference factor is
    # off here, so the prediction does not take the spikes out of it)
    assert any("4 sample(s) beyond the scale" in text for text in legend), legend
    # a factor switched off is not listed; the budget's title names it
    budget = fig.axes[1]
    assert [c.get_label() for c in budget.collections if not c.get_label().startswith("_")] == [
        "thermal ΔE_T"
    ]
    assert "loading" in budget.get_title() and "switched off" in budget.get_title()


def test_the_rows_kept_hold_every_buckets_extremes_and_picking_again_changes_nothing() -> None:
    rng = np.random.default_rng(5)
    n = 123_457
    time = np.cumsum(rng.uniform(0.5, 1.5, n))
    a = rng.normal(size=n)
    b = np.cumsum(rng.normal(size=n))
    a[[17, 90_000]] = [40.0, -40.0]
    b[5000:5010] = np.nan
    rows = plot_rows(time, [a, b])
    assert rows.size < n // 10
    assert {17, 90_000} <= set(rows.tolist()) and np.isnan(b[rows]).any()  # the spikes and the gap
    assert rows[0] == 0 and rows[-1] == n - 1
    again = plot_rows(time[rows], [a[rows], b[rows]])
    np.testing.assert_array_equal(again, np.arange(rows.size))
    # per bucket of rows: the min and max of each column are among the rows kept
    bucket = np.arange(n) // 1000
    kept = extreme_rows(bucket, [a])
    for k in range(0, n // 1000, 17):
        sl = slice(k * 1000, (k + 1) * 1000)
        assert {int(np.argmin(a[sl])) + k * 1000, int(np.argmax(a[sl])) + k * 1000} <= set(kept.tolist())


def test_each_curve_of_a_long_record_is_drawn_through_its_own_extremes() -> None:
    # eight noisy columns: the union of their bucket extremes is most of the plot's rows,
    # while each curve needs only its own (about four a bucket)
    from .sample import make_table

    table = make_table(rows=40_000)
    columns = _sample_columns()
    fig = plots.budget_figure(table, columns, "sample")
    drawn = plots.drawn_rows(table, columns.budget_names())
    assert drawn.size > 2 * LIMIT
    t_s = table.time[drawn]
    hours = t_s / 3600.0
    bucket = np.clip(((t_s - t_s[0]) / (t_s[-1] - t_s[0]) * BUCKETS).astype(np.int64), 0, BUCKETS - 1)
    starts = np.flatnonzero(np.r_[True, bucket[1:] != bucket[:-1]])  # as plot_rows buckets them

    def extremes(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per bucket of the plot's rows: the smallest and largest y drawn there."""
        at = np.searchsorted(x, hours[starts])
        return np.minimum.reduceat(y, at), np.maximum.reduceat(y, at)

    drift, budget, _ = fig.axes
    e_z = table[columns.predicted][drawn] * 1e6
    for ax, label in ((drift, "predicted error e_z"), (budget, "sum: e_z")):
        (line,) = [ln for ln in ax.get_lines() if ln.get_label() == label]
        x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        assert len(x) <= LIMIT < drawn.size  # its own rows, not the union of every curve's
        assert np.isin(x, hours).all()  # rows the plot draws, with their values
        mine, theirs = extremes(x, y), extremes(hours, e_z)
        np.testing.assert_array_equal(mine[0], theirs[0])  # in every bucket its lowest value
        np.testing.assert_array_equal(mine[1], theirs[1])  # and its highest
    for area in budget.collections:
        (path,) = area.get_paths()
        assert len(path.vertices) < drawn.size  # each area through its own edges' extremes


def test_a_short_record_is_drawn_whole_and_a_record_without_outliers_keeps_its_own_scale() -> None:
    from .sample import make_table

    table = make_table()
    fig = plots.budget_figure(table, _sample_columns(), "sample")
    drift = fig.axes[0]
    reading = next(ln for ln in drift.get_lines() if ln.get_label() == READING)
    assert len(reading.get_xdata()) == len(table.time)
    assert not any(ln.get_marker() in ("v", "^") for ln in drift.get_lines())
    y = np.asarray(reading.get_ydata())
    bottom, top = drift.get_ylim()
    assert bottom <= np.nanmin(y) and np.nanmax(y) <= top


def _sample_columns(**extra: object) -> plots.BudgetColumns:
    from .sample import PARTS

    return plots.BudgetColumns("probe.reading", "errormodel.e_total", PARTS, ["thermal.t_base"], **extra)  # type: ignore[arg-type]


def test_the_paper_replay_draws_the_papers_measured_drift_never_fitted() -> None:
    from twin.paper import DRIFT_M
    from twin.pipeline import RunOptions, prepare
    from twin.pipeline.stages import budget_columns
    from twin.validation import reports

    replay = prepare("li2017-thermal-experiment", options=RunOptions(reports=reports))
    columns = budget_columns(replay.evaluation, replay)
    assert columns.measured_drift_m == DRIFT_M and "Li et al" in columns.measured_by
    from .sample import make_table

    fig = plots.budget_figure(
        make_table(), _sample_columns(measured_drift_m=DRIFT_M, measured_by="Li et al. 2017"), "x"
    )
    drift = fig.axes[0]
    (star,) = [ln for ln in drift.get_lines() if ln.get_marker() == "*"]
    assert star.get_ydata()[0] == pytest.approx(-21.0) and "measured drift" in star.get_label()
    bottom, top = drift.get_ylim()
    assert bottom <= -21.0 <= top
    # a scenario that replays nothing draws no measured value
    plain = prepare("constant-load", options=RunOptions(reports=reports))
    assert budget_columns(plain.evaluation, plain).measured_drift_m is None
