"""The uncertainty of a run's prediction: a Monte Carlo over what is not known of the tester.

A scenario's ``[uncertainty]`` table (the paper's experiment has one) makes its run add,
after the nominal run, a Monte Carlo of the same scenario (:func:`twin.pipeline.run.run`, on
Dask) over every uncertain input:

- the tester as built (the prior file, ``scenarios/base/priors.toml``, around this scenario's
  values; spreads of FMU instances the scenario does not have are left out), with a
  calibrated parameter's own standard error (``std_error`` in its parameter file: lognormal
  with that relative sigma) in place of its spread;
- the room curve (the prior file's ``[room]``): a rise of unknown shape (an ``exponential``
  profile, the paper's) takes its shapes in turn reaching the scenario's rise at its rise time;
  any other room keeps its own curve; both plus a slow random drift (zero at both ends, largest
  excursion uniform up to its ``drift_K``);
- the sensors' noise (each sample its own seed).

::

    [uncertainty]
    samples = 200                       # 0: none (twin run --uncertainty N overrides)
    seed = 2017
    spreads = "base/priors.toml"        # the prior file, relative to the scenario file
    room = "input.thermal.t_room"

A run of an updated tester (``twin run --tester FILE``, the default ``twin run``: the paper's
experiment with the tester ``twin update`` learnt from it) adds as many samples again, its
updated prediction: sample ``i`` is prior sample ``i`` (the same room, noise and held inputs:
the thermal network, the mounting, what the update left to its discrepancy) with the sampled
parameters set to the tester file's posterior draw ``i``. The prior predictive is drawn around
the scenario before the tester's values were set.

The figures (summary.json): ``drift_mm.prior``, the prior predictive of the virtual probe's
drift (median, 90 % interval, samples, and the share of its variance each input group
explains: :mod:`twin.uncertainty.shares`), and ``drift_mm.updated``, the updated prediction
(the same figures); ``drift_mm.interval_90`` and ``sigma`` beside the nominal figures (of the
run's own twin: the updated one where there is a tester), and ``drift_mm.uncertainty`` with the
same for the error model's predicted drift and the medians per room shape; ``uncertainty.csv``
holds every sample (``predictive``: prior or updated) with its figures and its drawn inputs.
A sample's figures are those read off the ends of its record
(:data:`twin.errormodel.evaluate.END_FIGURES`: the drifts, the rises, the wear at the end), and
in process its FMUs, stepped over the whole run, record only the rows those read
(:func:`twin.errormodel.evaluate.end_reach_s`: every row where the loading factor's creep
reads them all). What a measured
experiment makes of them is its report's (:mod:`twin.pipeline.report`).
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple, Protocol

import numpy as np

from twin.config.reader import Problems
from twin.config.spec import NS_PER_S, Scenario
from twin.errors import ConfigError
from twin.files import write_atomic
from twin.seeds import Key, generator, scenario_seed
from twin.uncertainty import rooms
from twin.uncertainty.shares import NOISE, ROOM, THERMAL_NETWORK, variance_shares
from twin.uncertainty.spreads import calibrated_rows, merge_rows
from twin.uncertainty.testers import Testers, apply, key_parts, load_prior, load_room, with_rests
from twin.uncertainty.updated import UpdatedTester

__all__ = [
    "MAX_SAMPLES",
    "Draw",
    "Progress",
    "Uncertainty",
    "add_to_summary",
    "own_rows",
    "parse_uncertainty",
    "predictive_rows",
    "sampler",
    "updated_sampler",
    "write_samples",
]

_KEYS = {"samples", "seed", "spreads", "room", "room_shapes", "room_drift_K"}
#: the most Monte Carlo samples a run takes: the 90 % interval's ends are then known to about
#: 0.2 % of the spread (the 5 % quantile's standard error, sqrt(0.05 x 0.95 / n) / pdf), and
#: every sample's row is kept until uncertainty.csv is written; a mistyped count (1e9) would
#: otherwise fill the memory before the first sample ran
MAX_SAMPLES = 100_000
#: the figures of a sample that uncertainty.csv keeps (then the thermal parts, then its drawn inputs)
SAMPLE_COLUMNS = (
    "sample", "predictive", "room_shape", "status", "error", "drift_mm.probe", "drift_mm.predicted",
)  # fmt: skip
#: the two predictives a sample belongs to: the twin before any record, the updated tester's
PRIOR, UPDATED = "prior", "updated"
#: a sample's room as inputs of the variance shares: the shape's index, the slow drift's mean
ROOM_INPUTS = ("room.shape", "room.drift_mean_K")
#: the sensors' noise: each sample its own seed, no number a share could be estimated on
NOISE_INPUT = "sensor noise seed"
#: the default prior file, relative to the scenario's folder
PRIOR_FILE = "base/priors.toml"


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
    spreads = (folder / str(table.get("spreads", PRIOR_FILE))).resolve()
    if not spreads.is_file():
        p.add("uncertainty.spreads", f"no such file {spreads}")
    p.check()
    n = samples if samples is not None else count
    if n <= 0:
        return None
    room = load_room(spreads)  # the prior's room curve, unless the table overrides it
    return Uncertainty(
        n,
        seed,
        spreads,
        str(table.get("room", "input.thermal.t_room")),
        tuple(shapes) if "room_shapes" in table else room.shapes,
        float(drift or 0.0) if "room_drift_K" in table else room.drift_K,
    )


# ----------------------------------------------------------------------------- the samples


class Draw(NamedTuple):
    """One sample: its scenario, its room's shape and what was drawn for it (by key)."""

    scenario: Scenario
    room_shape: str
    inputs: dict[str, float]


class Maker(Protocol):
    """Sample ``i``'s draw; with a ``posterior``, the updated sample ``i``: prior sample ``i``
    with those values set (:func:`updated_sampler`)."""

    def __call__(self, i: int, posterior: Mapping[str, float] | None = None) -> Draw: ...


def sampler(unc: Uncertainty, scenario: Scenario) -> tuple[dict[str, str], Maker]:
    """The varied keys with their input groups (the room's and the noise's last), and sample
    ``i``'s draw."""
    prior = load_prior(unc.spreads, scenario)
    calibrated = calibrated_rows(scenario)
    testers = Testers(tuple(merge_rows(list(prior.rows), calibrated)), unc.seed)
    groups = {n: prior.groups.get(n, THERMAL_NETWORK) for n in testers.names}
    groups |= dict.fromkeys(ROOM_INPUTS, ROOM) | {NOISE_INPUT: NOISE}
    target = unc.room.split(".", 1)[1]
    # every sample's draw at once (each from its own stream: the same numbers one by one)
    draws = testers.draw_many(range(unc.samples))

    curves: dict[str, rooms.ShapedCurve] = {}

    def make(i: int, posterior: Mapping[str, float] | None = None) -> Draw:
        profile, name, mean = _room(unc, scenario, target, i, curves)
        drawn = dict(draws[i]) if i < len(draws) else testers.draw(i)
        values = with_rests(scenario, drawn, prior.rests)
        shape = float(unc.room_shapes.index(name)) if name in unc.room_shapes else 0.0
        inputs = drawn | dict(zip(ROOM_INPUTS, (shape, mean), strict=True))
        seed = scenario_seed(unc.seed, Key.RUN, Key.SAMPLE, i)
        if posterior is not None:
            at_once = _with_posterior(scenario, values, posterior)
            if at_once is not None:
                return Draw(at_once.with_input(profile).with_seed(seed), name, inputs | posterior)
        draw = Draw(apply(scenario, values).with_input(profile).with_seed(seed), name, inputs)
        if posterior is None:
            return draw
        return Draw(apply(draw.scenario, posterior), name, draw.inputs | posterior)

    return groups, make


def _with_posterior(
    scenario: Scenario, values: Mapping[str, Any], posterior: Mapping[str, float]
) -> Scenario | None:
    """``scenario`` with the prior's ``values`` and then the ``posterior``'s set in one pass, as
    setting them one after the other sets them (an updated sample is its prior sample with the
    posterior set: making the prior sample again first was half of its making), or None where
    one pass might not give what two give, and the caller takes two: a posterior value other
    than an instance's parameter (a profile's, the seed: set before the room's profile
    replaces it), or a value either pass refuses (two passes refuse the first in their order,
    the prior's values checked before the posterior replaces some of them)."""
    instances = {f.name for f in scenario.fmus}
    overridden: dict[str, dict[str, Any]] = {}
    for key in posterior:
        instance, parameter = key_parts(key)
        if instance not in instances or parameter is None:
            return None
        if key in values:
            overridden.setdefault(instance, {})[parameter] = values[key]
    try:
        for instance, replaced in overridden.items():
            scenario.with_parameters(instance, replaced)  # the prior's values the first pass checks
        return apply(scenario, {**values, **posterior})
    except ConfigError:
        return None


def updated_sampler(make: Maker, tester: UpdatedTester) -> Callable[[int], Draw]:
    """Updated sample ``i``: prior sample ``i`` with the tester's posterior draw ``i`` set."""

    def make_updated(i: int) -> Draw:
        return make(i, tester.draw(i))

    return make_updated


def predictive_rows(rows: Sequence[Mapping[str, Any]], which: str) -> list[Mapping[str, Any]]:
    """The samples of one predictive (:data:`PRIOR` or :data:`UPDATED`)."""
    return [r for r in rows if r.get("predictive", PRIOR) == which]


def own_rows(rows: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    """The samples of the run's own twin: the updated tester's where it has them."""
    return predictive_rows(rows, UPDATED) or predictive_rows(rows, PRIOR)


def _room(
    unc: Uncertainty, scenario: Scenario, target: str, i: int, curves: dict[str, rooms.ShapedCurve]
) -> tuple[Any, str, float]:
    """Sample ``i``'s room: a rise takes a shape in turn; any other room keeps its own curve;
    both with a slow drift (and that drift's mean over the run, K). ``curves`` keeps each
    shape's curve before its drift (:func:`twin.uncertainty.rooms.shaped_curve`), made for the
    first sample that draws it: the samples' rooms differ by their drifts alone."""
    drift = rooms.smooth_drift(generator(unc.seed, Key.SAMPLE, i), unc.room_drift_K)
    mean = drift.grid_mean()
    if rooms.rise_of(scenario.profile(target), scenario.duration_ns / NS_PER_S) is None:
        return rooms.drifted(scenario, target, drift), "own", mean
    name = unc.room_shapes[i % len(unc.room_shapes)]
    source = f"twin run uncertainty: room shape {name} plus a slow drift"
    curve = curves.get(name)
    if curve is None:
        curve = curves[name] = rooms.shaped_curve(scenario, target, name)
    return curve.profile(drift, source), name, mean


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
    """The run's summary with the drift's uncertainty added: its prior predictive
    (``drift_mm.prior``), an updated tester's prediction (``drift_mm.updated``) and the
    figures of the run's own twin beside the nominal ones."""
    rows = own_rows(mc["rows"])
    probe = column(rows, "drift_mm.probe")
    drift = summary.setdefault("drift_mm", {})
    failed = sum(r["status"] != "ok" for r in mc["rows"])
    if len(probe):
        s = stats(probe)
        drift.update(interval_90=s["interval_90"], sigma=s["sigma"], samples=len(probe))
    groups = mc.get("groups", {})
    # each predictive that ran, even when the other's samples all failed (an updated tester's
    # draws the FMUs refuse leave the prior predictive as it was)
    prior = _predictive(predictive_rows(mc["rows"], PRIOR), groups)
    if prior is not None:
        drift["prior"] = {
            "quantity": "drift_mm.probe over the prior (scenarios/base/priors.toml): the prior predictive",
            **prior,
        }
    updated = _predictive(predictive_rows(mc["rows"], UPDATED), groups)
    if updated is not None:
        drift["updated"] = {
            "quantity": "drift_mm.probe over the updated tester's posterior draws (twin update): the updated prediction",
            "tester": mc.get("tester"),
            **updated,
        }
    if len(probe) == 0:
        drift["uncertainty"] = {"samples": 0, "failed": failed}
        return summary
    shapes = sorted({r["room_shape"] for r in rows})
    by_shape = {k: column([r for r in rows if r["room_shape"] == k], "drift_mm.probe") for k in shapes}
    drift["uncertainty"] = {
        "quantity": "drift_mm.probe: the virtual probe's drift, the twin's prediction of the reading",
        "of": UPDATED if updated is not None else PRIOR,
        "nominal": drift.get("probe"),
        **s,
        "samples": len(probe),
        "failed": failed,
        "predicted": stats(column(rows, "drift_mm.predicted")),
        "median_by_room_shape": {k: float(np.median(v)) for k, v in by_shape.items() if len(v)},
        "inputs": [*mc["inputs"], "room curve shape", "room drift", "sensor noise seed"],
        "wall_s": mc["wall_s"],
        "workers": mc["workers"],
    }
    return summary


def _predictive(rows: Sequence[Mapping[str, Any]], groups: Mapping[str, str]) -> dict[str, Any] | None:
    """One predictive's figures (None without a sample that ran)."""
    ok = [r for r in rows if r["status"] == "ok" and "drift_mm.probe" in r]
    if not ok:
        return None
    s = stats(column(ok, "drift_mm.probe"))
    return {
        "median": s["median"],
        "interval_90": s["interval_90"],
        "samples": len(ok),
        "variance_shares": variance_shares(ok, "drift_mm.probe", groups),
    }


def write_samples(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    """The Monte Carlo's samples as a CSV (``uncertainty.csv`` of a run folder): each sample's
    figures, then what was drawn for it.

    Written by the csv module as pandas' ``DataFrame.from_records(rows).to_csv(index=False)``
    wrote it (the same bytes: :func:`_csv_column`), without importing pandas, which a default
    run needed for nothing else."""
    rows = list(rows)
    seen: dict[str, None] = {}  # every key, in the order first met (pandas' columns)
    for row in rows:
        seen.update(dict.fromkeys(row))
    parts = sorted(c for c in seen if c.startswith("thermal_parts_mm."))
    # then every drawn input, in the order drawn: a sample can be rerun or analysed from its row
    inputs = [c for c in seen if c not in SAMPLE_COLUMNS and c not in parts]
    columns = [*SAMPLE_COLUMNS, *parts, *inputs]
    # row by row, then column by column: a key a row lacks is None there, a missing cell
    table = [list(map(row.get, columns)) for row in rows]
    cells = (
        [_csv_column(list(values)) for values in zip(*table, strict=True)] if table else [[] for _ in columns]
    )

    def write(tmp: Path) -> None:
        with tmp.open("w", encoding="utf-8", newline="") as f:
            out = csv.writer(f, lineterminator="\n")
            out.writerow(columns)
            out.writerows(zip(*cells, strict=True))

    return write_atomic(path, write)  # never through a link


def _csv_column(values: list[Any]) -> list[str]:
    """One column's cells as pandas writes them: a column of numbers, some missing or any a
    float, is pandas' float64 (numpy's shortest repr, ``3.0`` for an integer, missing empty); a
    column of integers (or of booleans) with none missing their text; anything else each
    value's text, missing (None, NaN) empty."""
    if values and set(map(type, values)) == {float}:
        # every cell a Python float (a sample's figures and what was drawn for it): their
        # shortest reprs made in one go by the list's repr, a NaN missing
        cells = repr(values)[1:-1].split(", ")
        return ["" if c == "nan" else c for c in cells] if "nan" in cells else cells
    missing = [v is None or (isinstance(v, float) and math.isnan(v)) for v in values]
    present = [v for v, m in zip(values, missing, strict=True) if not m]
    if present and all(isinstance(v, int | float | np.integer) and not isinstance(v, bool) for v in present):
        if not any(missing) and all(isinstance(v, int | np.integer) for v in present):
            return [str(int(v)) for v in values]
        # Python's shortest repr of a double is numpy's (both round-trip, same notation: tested
        # against numpy's text), at half its cost
        return ["" if m else repr(float(v)) for v, m in zip(values, missing, strict=True)]
    if present and not any(missing) and all(isinstance(v, bool | np.bool_) for v in present):
        return [str(bool(v)) for v in values]
    return ["" if m else str(v) for v, m in zip(values, missing, strict=True)]


def line(summary: Mapping[str, Any]) -> str | None:
    """The terminal's lines on the predictions (None without one): the nominal drift, the
    prior predictive and an updated tester's prediction side by side (median, 90 % interval,
    where a measured drift falls in each, which is calibration and which validation), and the
    input groups' shares of the prior's variance."""
    d = summary.get("drift_mm", {})
    failed = d.get("uncertainty", {}).get("failed", 0)
    if "interval_90" not in d and not failed:
        return None
    wall = d.get("uncertainty", {}).get("wall_s", math.nan)
    measured = d.get("paper_measured")
    updated = d.get("updated")
    who = "updated twin" if updated is not None else "nominal twin"
    counts = [e["samples"] for e in (d.get("prior"), updated) if e is not None]
    if "interval_90" not in d:  # no sample of the run's own twin ran: said, not left out
        out = f"uncertainty: no sample of the run's own twin ran ({failed} failed: uncertainty.csv says why)"
    else:
        out = f"drift (probe), {who} {d['probe']:+.4f} mm" + (
            f"; the paper measured {measured:+.4f} mm" if measured is not None else ""
        )
        # fewer posterior draws than samples: as many updated samples as draws
        each = (
            f"{d['samples']} samples per predictive"
            if len(set(counts)) < 2
            else f"{counts[0]} prior and {counts[1]} updated samples"
        )
        out += f" ({each}, {wall:.1f} s)"
    for label, entry, role in (
        ("prior predictive  ", d.get("prior"), "the twin before any record: validated by the measurement"),
        ("updated prediction", updated, "calibrated on the measurement: no validation of it"),
    ):
        if entry is None:
            continue
        lo, hi = entry["interval_90"]
        out += f"\n  {label} median {entry['median']:+.4f}, 90 % [{lo:+.4f}, {hi:+.4f}] mm"
        if "quantile_of_measured" in entry:
            out += f", measured at quantile {entry['quantile_of_measured']:.3f}"
        out += f" ({role})" if measured is not None else ""
    shares = d.get("prior", {}).get("variance_shares", {}).get("groups", {})
    if shares:
        parts = ", ".join(f"{g} {100 * v:.0f} %" for g, v in sorted(shares.items(), key=lambda kv: -kv[1]))
        out += f"\n  prior variance shares: {parts}"
    return out


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
