"""Sample data: a small signal table shaped like a run (temperatures, probe reading, error budget)."""

from __future__ import annotations

import numpy as np

from twin.signals.table import Signal, SignalTable

PARTS = {
    "thermal": "errormodel.e_thermal",
    "loading": "errormodel.e_loading",
    "fluctuating": "errormodel.e_fluctuating",
    "positioning": "errormodel.e_positioning",
    "interference": "errormodel.e_interference",
}
BUDGET = ["errormodel.e_total", *PARTS.values()]


def make_table(rows: int = 721, seed: int = 7) -> SignalTable:
    """Two hours at 10 s; values with full float64 precision (random digits, tiny and huge)."""
    rng = np.random.default_rng(seed)
    time = np.arange(rows) * 10.0
    rise = 1.0 - np.exp(-time / 1800.0)
    table = SignalTable(time=time)
    table.add(
        Signal("thermal.t_base", "K", "thermal", "base plate"),
        293.15 + 4.0 * rise + rng.normal(0, 0.01, rows),
    )
    table.add(Signal("thermal.t_spindle", "K", "thermal"), 293.15 + 9.0 * rise + rng.normal(0, 0.01, rows))
    parts = {}
    for i, column in enumerate(PARTS.values()):
        parts[column] = (i + 1) * 1e-6 * rise + rng.normal(0, 1e-8, rows)
        table.add(Signal(column, "m", "errormodel"), parts[column])
    total = sum(parts.values())
    table.add(Signal("errormodel.e_total", "m", "errormodel", "predicted error"), total)
    table.add(
        Signal("probe.reading", "m", "probe", "capacitive probe"), 1.25e-3 + total + rng.normal(0, 2e-8, rows)
    )
    table.add(Signal("probe.range", "m", "probe"), np.full(rows, 1e300) * rng.random(rows))
    return table
