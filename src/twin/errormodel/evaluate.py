"""Evaluate the comprehensive error model on measured streams, end to end.

Input: a signal table with the virtual (or a lab's real) sensor readings: eight temperatures,
the displacement probe, and where present the load cell, torque sensor, angle encoder and
vibration pickup. Output, per time sample: the predicted error e_z and its five parts
(thermal, loading, fluctuating, positioning, interference), the thermal part body by body,
the change of the reading, and the compensated wear = reading change - predicted error;
with a true wear column (a twin run) the residual against it and the credibility indexes of
the on-line wear curve before and after compensation.

Every series is taken relative to its first sample (the probe is zeroed at the start of a
test), which keeps the compensation exact for whatever happens early in a run (running-in
wear, a load ramp). The drift numbers of the summary instead read start and end values off
least-squares lines through the first and last ``window`` seconds, evaluated at the first
and last time: that averages the sensors' noise out of a slow drift without the lag of a
plain mean. A factor whose sensor is absent from the table contributes zero.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from twin.errormodel.credibility import discrete_frechet, ra_fluctuation
from twin.errormodel.sources import (
    DEFAULT_ANGLE,
    DEFAULT_LOAD,
    DEFAULT_READING,
    DEFAULT_TEMPERATURES,
    DEFAULT_TORQUE,
    DEFAULT_VIBRATION,
    MechanicalCoefficients,
    ThermalGeometry,
    fluctuating_errors,
    hampel,
    loading_errors,
    positioning_errors,
    thermal_errors,
)
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

#: the Frechet distance is computed on at most this many points per curve (evenly decimated)
FRECHET_POINTS = 800


@dataclass(frozen=True)
class EvaluationConfig:
    """Which columns hold what, and what is known of the tester."""

    geometry: ThermalGeometry
    mechanics: MechanicalCoefficients | None = None
    temperatures: Mapping[str, str] = field(default_factory=lambda: dict(DEFAULT_TEMPERATURES))
    reading: str = DEFAULT_READING
    load: str = DEFAULT_LOAD
    torque: str = DEFAULT_TORQUE
    angle: str = DEFAULT_ANGLE
    vibration: str = DEFAULT_VIBRATION
    true_wear: str | None = "mechanics.wear_depth_true"
    window_s: float = 300.0
    spike_half_window: int = 10
    spike_sigmas: float = 5.0
    spike_min: float = 1e-6
    ra_window_s: float = 1800.0
    #: the factors the model evaluates; the paper's thermal experiment leaves out loading and
    #: fluctuating (no load, no motion: its Eq. 10), so their sensors' noise does not enter
    factors: tuple[str, ...] = PARTS


def evaluation_signals(*, with_true_wear: bool) -> list[Signal]:
    """Metadata of every column :func:`evaluate` adds, known before any data exists."""

    def sig(name: str, description: str, unit: str = "m") -> Signal:
        return Signal(f"errormodel.{name}", unit, "errormodel", description)

    out = [sig("e_z", "predicted detecting error e_z (comprehensive error model)")]
    out += [sig(f"e_{p}", f"{p} part of e_z") for p in PARTS]
    out += [sig(f"thermal.{b}", f"thermal e_z contribution of body '{b}'") for b in tester_model().bodies]
    out += [
        sig("reading_change", "probe reading minus its start value"),
        sig("wear_compensated", "compensated wear: reading change minus predicted error"),
        sig("spike", "1 where the robust filter found an interference spike", "1"),
    ]
    if with_true_wear:
        out.append(sig("residual", "compensated wear minus true wear"))
    return out


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


def _sum_parts(model: Any, errors: dict[str, dict[str, np.ndarray]], n: int) -> np.ndarray:
    if not errors:
        return np.zeros(n)
    return np.asarray(model.e_z(errors), dtype=float) * np.ones(n)


def evaluate(table: SignalTable, cfg: EvaluationConfig) -> Evaluation:
    """Run the error model over the table; adds ``errormodel.*`` columns to it."""
    t = table.time
    n = len(t)
    if n < 2:
        raise ConfigError("the error model needs at least two samples", source="errormodel")

    def rel(y: np.ndarray) -> np.ndarray:
        return y - y[0]

    def drift(y: np.ndarray) -> float:
        a, b = endpoints(t, y, cfg.window_s)
        return b - a

    # interference first: the robust filter separates the spikes from the reading
    reading = _column(table, cfg.reading, "probe reading")
    cleaned, spikes = hampel(reading, cfg.spike_half_window, cfg.spike_sigmas, cfg.spike_min)
    r0 = cleaned[0]
    change = cleaned - r0
    raw_change = reading - r0

    rises: dict[str, np.ndarray] = {}
    temperature_rise: dict[str, float] = {}
    for point, col in cfg.temperatures.items():
        y = _column(table, col, f"temperature at '{point}'")
        rises[point] = rel(y)
        temperature_rise[point] = drift(y)

    model = tester_model()
    by_body = model.e_z_by_body(thermal_errors(rises, cfg.geometry))
    thermal = np.sum(np.array(list(by_body.values())), axis=0)

    c = cfg.mechanics
    present = {k: getattr(cfg, k) in table for k in ("load", "torque", "angle", "vibration")}
    if "loading" not in cfg.factors:
        present["load"] = False
    if "fluctuating" not in cfg.factors:
        present["angle"] = present["vibration"] = False
    if "thermal" not in cfg.factors:
        by_body = {b: np.zeros(n) for b in by_body}
        thermal = np.zeros(n)
    loading = fluctuating = positioning = np.zeros(n)
    if c is not None:
        if present["load"]:
            loading = _sum_parts(model, loading_errors(rel(table[cfg.load]), c), n)
        angle = table[cfg.angle] if present["angle"] else None
        vibration = rel(table[cfg.vibration]) if present["vibration"] else None
        fl = fluctuating_errors(angle, float(angle[0]) if angle is not None else 0.0, vibration, c)
        fluctuating = rel(_sum_parts(model, fl, n))
        torque = rel(table[cfg.torque]) if present["torque"] else None
        if "positioning" in cfg.factors:
            positioning = rel(_sum_parts(model, positioning_errors(change, torque, c), n))
    interference = reading - cleaned if "interference" in cfg.factors else np.zeros(n)
    parts = {
        "thermal": thermal,
        "loading": loading,
        "fluctuating": fluctuating,
        "positioning": positioning,
        "interference": interference,
    }
    e_z = np.sum(np.array(list(parts.values())), axis=0)
    compensated = raw_change - e_z

    has_wear = bool(cfg.true_wear and cfg.true_wear in table)
    meta = {m.name: m for m in evaluation_signals(with_true_wear=has_wear)}

    def add(name: str, values: np.ndarray) -> None:
        table.add(meta[f"errormodel.{name}"], values)

    add("e_z", e_z)
    for name, values in parts.items():
        add(f"e_{name}", values)
    for body, values in by_body.items():
        add(f"thermal.{body}", values)
    add("reading_change", raw_change)
    add("wear_compensated", compensated)
    add("spike", spikes.astype(float))

    summary: dict[str, Any] = {
        "drift_mm": {"predicted": drift(e_z) * 1e3, "probe": drift(reading) * 1e3},
        "temperature_rise_C": temperature_rise,
        "error_parts_mm": {**{k: drift(v) * 1e3 for k, v in parts.items()}, "total": drift(e_z) * 1e3},
        "error_parts_rms_um": {k: float(np.sqrt(np.mean(v**2))) * 1e6 for k, v in parts.items()},
        "thermal_parts_mm": {
            g: sum(drift(by_body[b]) for b in bodies) * 1e3 for g, bodies in FEM_GROUPS.items()
        },
        "interference_spikes": int(spikes.sum()),
        "sensors_used": {k: v for k, v in present.items()},
    }
    if has_wear:
        wear = table[cfg.true_wear] - table[cfg.true_wear][0]
        before, after = raw_change - wear, compensated - wear
        add("residual", after)
        summary["wear_mm"] = {"true": float(wear[-1]) * 1e3, "compensated": float(compensated[-1]) * 1e3}
        summary["compensation"] = {
            "residual_rms_um": {"before": _rms(before) * 1e6, "after": _rms(after) * 1e6},
            "residual_max_um": {"before": _absmax(before) * 1e6, "after": _absmax(after) * 1e6},
        }
        summary["credibility"] = {
            "frechet_um": {
                "before": _frechet_um(t, raw_change, wear),
                "after": _frechet_um(t, compensated, wear),
            },
            "ra_um": {
                "before": ra_fluctuation(t, raw_change, cfg.ra_window_s) * 1e6,
                "after": ra_fluctuation(t, compensated, cfg.ra_window_s) * 1e6,
            },
        }
    return Evaluation(e_z, parts, by_body, raw_change, compensated, summary)


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(x**2)))


def _absmax(x: np.ndarray) -> float:
    return float(np.max(np.abs(x)))


def _frechet_um(t: np.ndarray, online: np.ndarray, true: np.ndarray) -> float:
    """Frechet distance between the curves (t in hours, z in um), decimated evenly."""
    step = max(1, int(np.ceil(len(t) / FRECHET_POINTS)))
    idx = np.unique(np.r_[np.arange(0, len(t), step), len(t) - 1])
    th = t[idx] / 3600.0
    p = np.column_stack([th, online[idx] * 1e6])
    q = np.column_stack([th, true[idx] * 1e6])
    return discrete_frechet(p, q)
