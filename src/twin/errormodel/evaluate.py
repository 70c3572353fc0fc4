"""Evaluate the comprehensive error model on measured streams, end to end.

Input: a signal table with the temperature sensors' readings and the displacement probe's
reading (a twin run or a lab's CSV). Output, per time sample: the predicted error e_z, its
five parts (thermal, loading, fluctuating, positioning, interference), the thermal part body
by body, the change of the reading, and the compensated wear = reading change - predicted
error; with a true wear column (a twin run) also the residual against it.

Start and end values of drifts are read off a least-squares line through the first and the
last ``window`` seconds of samples, evaluated at the first and last time: that averages the
sensors' noise out without the lag a plain mean over a window would add.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin.errormodel.sources import DEFAULT_READING, DEFAULT_TEMPERATURES, ThermalGeometry, thermal_errors
from twin.errormodel.tester import tester_model
from twin.errors import ConfigError
from twin.signals.table import Signal, SignalTable

PARTS = ("thermal", "loading", "fluctuating", "positioning", "interference")

#: how the tester's bodies group into the paper's four FEM part results (facts.md 2)
FEM_GROUPS: dict[str, tuple[str, ...]] = {
    "bearing_block": ("bearing_block",),
    "t_plate": ("testing_spindle", "spherical_plain_bearing", "t_plate"),
    "detecting_frame": ("detecting_frame",),
    "long_pole": ("contacting_clamp", "long_pole"),
    "displacement_sensor": ("displacement_sensor",),
}


@dataclass(frozen=True)
class EvaluationConfig:
    """Which columns hold what, and the tester's geometry."""

    geometry: ThermalGeometry
    temperatures: Mapping[str, str] = field(default_factory=lambda: dict(DEFAULT_TEMPERATURES))
    reading: str = DEFAULT_READING
    true_wear: str | None = "mechanics.wear_depth_true"
    window_s: float = 300.0


def endpoints(t: np.ndarray, y: np.ndarray, window_s: float) -> tuple[float, float]:
    """Start and end value of ``y`` from lines through the first and last ``window_s``."""

    def fit(mask: np.ndarray, at: float) -> float:
        if mask.sum() < 2:
            return float(y[mask][0]) if mask.any() else float("nan")
        _slope, icpt = np.polyfit(t[mask] - at, y[mask], 1)
        return float(icpt)

    return fit(t <= t[0] + window_s, float(t[0])), fit(t >= t[-1] - window_s, float(t[-1]))


@dataclass
class Evaluation:
    """The per-sample results (also added to the table) and the end-minus-start numbers."""

    e_z: np.ndarray
    parts: dict[str, np.ndarray]
    thermal_by_body: dict[str, np.ndarray]
    reading_change: np.ndarray
    compensated: np.ndarray
    summary: dict[str, Any]


def _column(table: SignalTable, name: str, what: str) -> np.ndarray:
    if name not in table:
        raise ConfigError(f"no column '{name}' for the {what}", source="errormodel")
    return table[name]


def evaluate(table: SignalTable, cfg: EvaluationConfig) -> Evaluation:
    """Run the error model over the table; adds ``errormodel.*`` columns to it."""
    t = table.time
    if len(t) < 2:
        raise ConfigError("the error model needs at least two samples", source="errormodel")
    rises: dict[str, np.ndarray] = {}
    temperature_rise: dict[str, float] = {}
    for point, col in cfg.temperatures.items():
        y = _column(table, col, f"temperature at '{point}'")
        start, end = endpoints(t, y, cfg.window_s)
        rises[point] = y - start
        temperature_rise[point] = end - start
    reading = _column(table, cfg.reading, "probe reading")
    r0, r1 = endpoints(t, reading, cfg.window_s)

    model = tester_model()
    by_body = model.e_z_by_body(thermal_errors(rises, cfg.geometry))
    thermal = np.sum(np.array(list(by_body.values())), axis=0)
    zeros = np.zeros_like(t)
    # the other four factors enter with the loading/oscillation models; without their causes
    # (no load, no motion, aligned sensor, no interference) they are zero
    parts = {
        "thermal": thermal,
        "loading": zeros,
        "fluctuating": zeros,
        "positioning": zeros,
        "interference": zeros,
    }
    e_z = np.sum(np.array(list(parts.values())), axis=0)
    change = reading - r0
    compensated = change - e_z

    def add(name: str, values: np.ndarray, description: str) -> None:
        table.add(Signal(f"errormodel.{name}", "m", "errormodel", description), values)

    add("e_z", e_z, "predicted detecting error e_z (comprehensive error model)")
    for name, values in parts.items():
        add(f"e_{name}", values, f"{name} part of e_z")
    for body, values in by_body.items():
        add(f"thermal.{body}", values, f"thermal e_z contribution of body '{body}'")
    add("reading_change", change, "probe reading minus its start value")
    add("wear_compensated", compensated, "compensated wear: reading change minus predicted error")

    def drift(y: np.ndarray) -> float:
        a, b = endpoints(t, y, cfg.window_s)
        return b - a

    summary: dict[str, Any] = {
        "drift_mm": {"predicted": drift(e_z) * 1e3, "probe": (r1 - r0) * 1e3},
        "temperature_rise_C": temperature_rise,
        "error_parts_mm": {**{k: drift(v) * 1e3 for k, v in parts.items()}, "total": drift(e_z) * 1e3},
        "thermal_parts_mm": {
            group: sum(drift(by_body[b]) for b in bodies) * 1e3 for group, bodies in FEM_GROUPS.items()
        },
    }
    if cfg.true_wear and cfg.true_wear in table:
        wear = table[cfg.true_wear] - table[cfg.true_wear][0]
        residual = compensated - wear
        add("residual", residual, "compensated wear minus true wear")
        summary["wear_mm"] = {"true": float(wear[-1]) * 1e3, "compensated": float(compensated[-1]) * 1e3}
    return Evaluation(e_z, parts, by_body, change, compensated, summary)
