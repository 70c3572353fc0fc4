"""The uncertainty of a run's prediction: a Monte Carlo over what is not known of the tester.

A scenario's ``[uncertainty]`` table (the paper's experiment has one) makes its run add,
after the nominal run, a Monte Carlo of the same scenario (:func:`twin.pipeline.run.run`, on
Dask) over every uncertain input:

- the tester as built (the spreads file, ``scenarios/validation/testers-as-built.toml``,
  around this scenario's values; spreads of FMU instances the scenario does not have are
  left out), with a calibrated parameter's own standard error (``std_error`` in its
  parameter file: lognormal with that relative sigma) in place of its spread;
- the room curve: a rise of unknown shape (an ``exponential`` profile, the paper's) takes the
  shapes of :data:`~twin.uncertainty.rooms.ROOM_SHAPES` in turn (each a third of the samples)
  reaching the scenario's rise at its rise time; any other room keeps its own curve; both
  plus a slow random drift (zero at both ends, largest excursion uniform up to
  ``room_drift_K``);
- the sensors' noise (each sample its own seed).

::

    [uncertainty]
    samples = 64                                   # 0: none (twin run --uncertainty N overrides)
    seed = 2017
    spreads = "validation/testers-as-built.toml"   # relative to the scenario file
    room = "input.thermal.t_room"
    room_shapes = ["exponential", "ramp", "s-curve"]
    room_drift_K = 1.0

The figures (summary.json): ``drift_mm.interval_90`` (5 and 95 % quantiles of the virtual
probe's drift), ``sigma``, ``samples``, and ``drift_mm.uncertainty`` with the same for the
error model's predicted drift and the medians per room shape; ``uncertainty.csv`` holds every
sample. What a measured experiment makes of them is its report's
(:mod:`twin.pipeline.report`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.reader import Problems
from twin.config.spec import NS_PER_S, Scenario
from twin.errors import ConfigError
from twin.files import write_atomic
from twin.seeds import Key, generator, scenario_seed
from twin.uncertainty import rooms
from twin.uncertainty.spreads import calibrated_rows, merge_rows
from twin.uncertainty.testers import Testers, apply, load_testers

__all__ = [
    "MAX_SAMPLES",
    "Progress",
    "Uncertainty",
    "add_to_summary",
    "parse_uncertainty",
    "sampler",
    "write_samples",
]

_KEYS = {"samples", "seed", "spreads", "room", "room_shapes", "room_drift_K"}
#: the most Monte Carlo samples a run takes: the 90 % interval's ends are then known to about
#: 0.2 % of the spread (the 5 % quantile's standard error, sqrt(0.05 x 0.95 / n) / pdf), and
#: every sample's row is kept until uncertainty.csv is written; a mistyped count (1e9) would
#: otherwise fill the memory before the first sample ran
MAX_SAMPLES = 100_000
#: the figures of a sample that uncertainty.csv keeps (and the thermal parts)
SAMPLE_COLUMNS = ("sample", "room_shape", "status", "error", "drift_mm.probe", "drift_mm.predicted")


@dataclass(frozen=True)
class Uncertainty:
    """A checked ``[uncertainty]`` table."""

    samples: int
    seed: int
    spreads: Path
    room: str
    room_shapes: tuple[str, ...]
    room_drift_K: float


def parse_uncertainty(scenario: Scenario, samples: int | None = None) -> Uncertainty | None:
    """The scenario's ``[uncertainty]`` table, checked, with ``samples`` (``--uncertainty``) in
    place of its own count; None when it asks for no sample. Every problem at once."""
    if samples is not None and not 0 <= samples <= MAX_SAMPLES:
        raise ConfigError(
            f"expected a number of samples in [0, {MAX_SAMPLES}], got {samples}", source="--uncertainty"
        )
    table = dict(scenario.uncertainty)
    p = Problems(scenario.source_path)
    if not table and not samples:
        return None
    p.unknown_keys(table, _KEYS, "uncertainty.")
    count = p.integer(table, "samples", "uncertainty.", default=0, lo=0, hi=MAX_SAMPLES)
    seed = p.integer(table, "seed", "uncertainty.", default=0, lo=0, hi=2**63 - 1)
    drift = p.number({"room_drift_K": 1.0} | table, "room_drift_K", "uncertainty.", lo=0.0)
    shapes = table.get("room_shapes", list(rooms.ROOM_SHAPES))
    if not isinstance(shapes, list) or not shapes or not set(shapes) <= set(rooms.ROOM_SHAPES):
        p.add("uncertainty.room_shapes", f"expected a list from {list(rooms.ROOM_SHAPES)}")
    folder = Path(scenario.source_path).resolve().parent
    spreads = (folder / str(table.get("spreads", "validation/testers-as-built.toml"))).resolve()
    if not spreads.is_file():
        p.add("uncertainty.spreads", f"no such file {spreads}")
    p.check()
    n = samples if samples is not None else count
    if n <= 0:
        return None
    return Uncertainty(
        n, seed, spreads, str(table.get("room", "input.thermal.t_room")), tuple(shapes), float(drift or 0.0)
    )


# ----------------------------------------------------------------------------- the samples


def sampler(unc: Uncertainty, scenario: Scenario) -> tuple[list[str], Callable[[int], tuple[Scenario, str]]]:
    """The varied keys, and sample ``i``'s scenario with the name of its room's shape."""
    rows = merge_rows(load_testers(unc.spreads, scenario), calibrated_rows(scenario))
    testers = Testers(tuple(rows), unc.seed)
    target = unc.room.split(".", 1)[1]

    def make(i: int) -> tuple[Scenario, str]:
        profile, name = _room(unc, scenario, target, i)
        sample = apply(scenario, testers.draw(i)).with_input(profile)
        return sample.with_seed(scenario_seed(unc.seed, Key.RUN, Key.SAMPLE, i)), name

    return testers.names, make


def _room(unc: Uncertainty, scenario: Scenario, target: str, i: int) -> tuple[Any, str]:
    """Sample ``i``'s room: a rise takes a shape in turn; any other room keeps its own curve;
    both with a slow drift."""
    drift = rooms.smooth_drift(generator(unc.seed, Key.SAMPLE, i), unc.room_drift_K)
    if rooms.rise_of(scenario.profile(target), scenario.duration_ns / NS_PER_S) is None:
        return rooms.drifted(scenario, target, drift), "own"
    name = unc.room_shapes[i % len(unc.room_shapes)]
    source = f"twin run uncertainty: room shape {name} plus a slow drift"
    return rooms.shaped(scenario, target, name, drift, source), name


# ----------------------------------------------------------------------------- the figures


def stats(values: np.ndarray) -> dict[str, Any]:
    """Median, mean, sigma and the 90 % interval (5 and 95 % quantiles) of ``values``."""
    return {
        "median": float(np.median(values)),
        "mean": float(np.mean(values)),
        "sigma": float(np.std(values, ddof=1)) if len(values) > 1 else 0.0,
        "interval_90": [float(np.percentile(values, 5)), float(np.percentile(values, 95))],
    }


def column(rows: Sequence[Mapping[str, Any]], key: str) -> np.ndarray:
    """The figure ``key`` of every sample that ran."""
    return np.array([r[key] for r in rows if r["status"] == "ok" and key in r], dtype=float)


def add_to_summary(summary: dict[str, Any], mc: Mapping[str, Any]) -> dict[str, Any]:
    """The run's summary with the drift's uncertainty added."""
    rows = mc["rows"]
    probe = column(rows, "drift_mm.probe")
    drift = summary.setdefault("drift_mm", {})
    if len(probe) == 0:
        drift["uncertainty"] = {"samples": 0, "failed": len(rows)}
        return summary
    s = stats(probe)
    drift.update(interval_90=s["interval_90"], sigma=s["sigma"], samples=len(probe))
    shapes = sorted({r["room_shape"] for r in rows})
    by_shape = {k: column([r for r in rows if r["room_shape"] == k], "drift_mm.probe") for k in shapes}
    drift["uncertainty"] = {
        "quantity": "drift_mm.probe: the virtual probe's drift, the twin's prediction of the reading",
        "nominal": drift.get("probe"),
        **s,
        "samples": len(probe),
        "failed": sum(r["status"] != "ok" for r in rows),
        "predicted": stats(column(rows, "drift_mm.predicted")),
        "median_by_room_shape": {k: float(np.median(v)) for k, v in by_shape.items() if len(v)},
        "inputs": [*mc["inputs"], "room curve shape", "room drift", "sensor noise seed"],
        "wall_s": mc["wall_s"],
        "workers": mc["workers"],
    }
    return summary


def write_samples(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """The Monte Carlo's samples as a CSV (``uncertainty.csv`` of a run folder)."""
    import pandas as pd

    frame = pd.DataFrame.from_records(list(rows))
    parts = sorted(c for c in frame.columns if c.startswith("thermal_parts_mm."))
    frame = frame.reindex(columns=[*SAMPLE_COLUMNS, *parts])
    return write_atomic(path, lambda tmp: frame.to_csv(tmp, index=False))  # never through a link


def line(summary: Mapping[str, Any]) -> str | None:
    """The terminal's line on the interval (None without one)."""
    d = summary.get("drift_mm", {})
    if "interval_90" not in d:
        return None
    lo, hi = d["interval_90"]
    wall = d.get("uncertainty", {}).get("wall_s", math.nan)
    return (
        f"drift (probe) {d['probe']:+.4f} mm, sigma {d['sigma']:.4f}, 90 % interval [{lo:+.4f}, {hi:+.4f}] mm "
        f"({d['samples']} samples, {wall:.1f} s)"
    )


class Progress:
    """A line per tenth of the samples done (per sample when there are fewer than ten): the
    count and the time since the Monte Carlo began (its cluster's start included), as plain
    lines (no carriage return) that a log file or a batch system's output keeps as they are."""

    def __init__(self, total: int, echo: Callable[[str], None], start: float | None = None) -> None:
        self.total, self.echo = max(total, 1), echo
        self.start = time.perf_counter() if start is None else start
        self.told = 0  # the last tenth (or sample) told

    def done(self, count: int) -> None:
        """``count`` samples are done."""
        mark = count if self.total < 10 else count * 10 // self.total
        if mark <= self.told:
            return
        self.told = mark
        elapsed = time.perf_counter() - self.start
        self.echo(
            f"uncertainty: {count}/{self.total} samples ({100 * count // self.total} %), {elapsed:.1f} s"
        )
