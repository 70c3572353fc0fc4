"""The figures read off a record's ends (twin.errormodel.evaluate.END_FIGURES): the same bits
from the rows within end_reach_s of either end as from every row; what a Monte Carlo's sample
records and reports (twin.pipeline.run.run_samples)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from tests.test_compensate_streaming import TOML, record
from twin.errormodel.evaluate import END_FIGURES, end_figures, end_reach_s, evaluate
from twin.pipeline.compensation import compensation_config
from twin.signals.table import Signal, SignalTable

NO_LOADING = TOML.replace('"thermal", "loading", ', '"thermal", ')


def _flat(d: dict[str, Any], prefix: str = "") -> dict[str, float]:
    out: dict[str, float] = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        elif isinstance(v, int | float) and not isinstance(v, bool):
            out[f"{prefix}{k}"] = float(v)
    return out


def _figures(cols: dict[str, np.ndarray], rows: np.ndarray, cfg: Any) -> dict[str, float]:
    table = SignalTable(time=cols["time"][rows])
    for name, values in cols.items():
        if name != "time":
            table.add(Signal(name, "", "measured"), values[rows].copy())
    return _flat(evaluate(table, cfg, columns=False).summary)


def _config(tmp_path: Path, toml: str) -> Any:
    (tmp_path / "lab.toml").write_text(toml)
    cfg, _ = compensation_config(tmp_path / "lab.toml")
    return dataclasses.replace(cfg, credibility=False)


def test_the_end_figures_of_the_rows_near_the_ends_are_those_of_every_row(tmp_path: Path) -> None:
    cfg = _config(tmp_path, NO_LOADING)
    cols = record(3000, seed=11)  # a row a second, spikes and heavy-tailed noise in the probe
    reach = end_reach_s(cfg, 1.0)
    assert reach == cfg.window_s + (2 * cfg.spike_half_window + 1) * 1.0
    t = cols["time"]
    near = np.flatnonzero((t <= t[0] + reach) | (t >= t[-1] - reach))
    assert len(near) < len(t) // 8
    every, ends = _figures(cols, np.arange(len(t)), cfg), _figures(cols, near, cfg)
    kept = end_figures(every)
    assert {k.split(".")[0] for k in kept} == set(END_FIGURES)
    assert len(kept) > 20
    for key, value in kept.items():
        assert np.float64(ends[key]).tobytes() == np.float64(value).tobytes(), key
    # the others read every row: they differ (and the comparison above could fail)
    others = {k for k in every if k not in kept and every[k] != ends[k]}
    assert {"interference_spikes", "compensation.residual_rms_um.after"} <= others


def test_with_the_loading_factor_on_the_end_figures_read_every_row(tmp_path: Path) -> None:
    cfg = _config(tmp_path, TOML)  # the liner creeps under the load's whole history
    assert cfg.factor_on("loading")
    assert end_reach_s(cfg, 1.0) is None
    assert end_reach_s(dataclasses.replace(cfg, factors=("thermal", "interference")), 10.0) is not None
