"""The paper replay's prediction with its uncertainty: a Monte Carlo over what is not known.

A scenario's ``[uncertainty]`` table (``scenarios/li2017-thermal-experiment.toml`` has one)
makes ``twin run`` add, after the nominal run, a Monte Carlo of the same scenario on Dask
(:mod:`twin.sweep`'s client, executor and shipping) over every uncertain input:

- the tester as built (the spreads file, ``scenarios/validation/testers-as-built.toml``,
  facts.md section 6, around this scenario's values; spreads of FMU instances the scenario
  does not have are left out): the probe's zero drift (normal, mean 0, sigma 0.3 um/K: its
  sign is unknown), expansion coefficients, convection, joint conductances, heat capacities
  (where the thermal network's parameter file gives a parameter an ``interval = [lo, hi]``
  (uniform) or a ``std_error`` (lognormal with that relative sigma), that replaces the
  spread), the probe's mounting;
- the room curve: the paper gives only its rise, so each sample takes one of the shapes
  (:data:`~twin.validation.draws.ROOM_SHAPES`: first-order approach, linear ramp, S-curve; in
  turn, so each has a third of the samples) reaching the scenario's rise at its rise time,
  plus a slow random drift (zero at both ends, largest excursion uniform up to
  ``room_drift_K``);
- the sensors' noise (each sample its own seed).

The figures (summary.json of the run): ``drift_mm.interval_90`` (5 and 95 % quantiles of the
virtual probe's drift, the twin's prediction of what the paper's probe read), ``sigma``,
``samples``, and ``drift_mm.uncertainty`` with the same for the error model's predicted
drift, medians per room shape and whether the paper's measured drift lies inside; and
``paper.fem_components_mm``: the paper's FEM displacements beside the twin's thermal parts
(nominal, with their 90 % interval). Nothing here uses the paper's measured drift except the
one comparison reported.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.spec import NS_PER_S, Scenario
from twin.errors import ConfigError, ConfigErrors
from twin.seeds import Key, generator, scenario_seed

__all__ = ["Uncertainty", "add_to_summary", "parse_uncertainty", "run_uncertainty"]

_KEYS = {"samples", "seed", "spreads", "room", "room_shapes", "room_drift_K"}
#: the most Monte Carlo samples a run takes: the 90 % interval's ends are then known to about
#: 0.2 % of the spread (the 5 % quantile's standard error, sqrt(0.05 x 0.95 / n) / pdf), and
#: every sample's row is kept until uncertainty.csv is written; a mistyped count (1e9) would
#: otherwise fill the memory before the first sample ran
MAX_SAMPLES = 100_000


@dataclass(frozen=True)
class Uncertainty:
    """A checked ``[uncertainty]`` table."""

    source: Path
    samples: int
    seed: int
    spreads: Path
    room: str
    room_shapes: tuple[str, ...]
    room_drift_K: float


def _check(p: list[ConfigError], src: str, table: Mapping[str, Any]) -> None:
    from twin.validation.draws import ROOM_SHAPES

    p += [ConfigError("unknown key", source=src, key=f"uncertainty.{k}") for k in table if k not in _KEYS]
    for k, lo, hi in (("samples", 0, MAX_SAMPLES), ("seed", 0, 2**63 - 1)):
        v = table.get(k, lo)
        if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
            p.append(
                ConfigError(
                    f"expected an integer in [{lo}, {hi}], got {v!r}", source=src, key=f"uncertainty.{k}"
                )
            )
    drift = table.get("room_drift_K", 1.0)
    if isinstance(drift, bool) or not isinstance(drift, int | float) or not 0 <= drift < math.inf:
        p.append(
            ConfigError(f"expected a number >= 0, got {drift!r}", source=src, key="uncertainty.room_drift_K")
        )
    shapes = table.get("room_shapes", list(ROOM_SHAPES))
    if not isinstance(shapes, list) or not shapes or not set(shapes) <= set(ROOM_SHAPES):
        p.append(
            ConfigError(
                f"expected a list from {list(ROOM_SHAPES)}", source=src, key="uncertainty.room_shapes"
            )
        )


def parse_uncertainty(path: Path, data: Mapping[str, Any], samples: int | None = None) -> Uncertainty | None:
    """The scenario's ``[uncertainty]`` table, checked (None: the scenario has none and no
    ``samples`` were asked for, or zero samples)."""
    from twin.validation.draws import ROOM_SHAPES

    src = str(path)
    table = data.get("uncertainty")
    if table is None and not samples:
        return None
    if table is None:
        table = {}
    if not isinstance(table, dict):
        raise ConfigError("expected a table", source=src, key="uncertainty")
    p: list[ConfigError] = []
    _check(p, src, table)
    spreads = (
        path.resolve().parent / str(table.get("spreads", "validation/testers-as-built.toml"))
    ).resolve()
    if not spreads.is_file():
        p.append(ConfigError(f"no such file {spreads}", source=src, key="uncertainty.spreads"))
    if p:
        raise p[0] if len(p) == 1 else ConfigErrors(p)
    n = samples if samples is not None else int(table.get("samples", 0))
    if n <= 0:
        return None
    return Uncertainty(
        source=path,
        samples=n,
        seed=int(table.get("seed", 0)),
        spreads=spreads,
        room=str(table.get("room", "input.thermal.t_room")),
        room_shapes=tuple(table.get("room_shapes", ROOM_SHAPES)),
        room_drift_K=float(table.get("room_drift_K", 1.0)),
    )


# ----------------------------------------------------------------------------- inputs


def calibrated_spreads(data: Mapping[str, Any], base_dir: Path) -> dict[str, tuple[str, list[float]]]:
    """SALib rows (dist, bounds) of the parameters whose parameter files give an interval
    (``interval = [lo, hi]``: uniform) or a standard error (``std_error``: lognormal with the
    relative sigma), by ``fmu.<instance>.parameters.<name>``."""
    from twin.config.reader import read_toml

    out: dict[str, tuple[str, list[float]]] = {}
    for inst, spec in data.get("fmu", {}).items():
        for f in spec.get("parameter_files", []) if isinstance(spec, dict) else []:
            params = read_toml(base_dir / f, str(base_dir / f)).get("parameters", {})
            for name, entry in params.items():
                row = _interval_row(entry)
                if row is not None:
                    out[f"fmu.{inst}.parameters.{name}"] = row
    return out


def _interval_row(entry: Any) -> tuple[str, list[float]] | None:
    if not isinstance(entry, dict):
        return None
    interval, value, se = entry.get("interval"), entry.get("value"), entry.get("std_error")
    if isinstance(interval, list) and len(interval) == 2 and interval[0] < interval[1]:
        return "unif", [float(interval[0]), float(interval[1])]
    if isinstance(se, int | float) and isinstance(value, int | float) and value > 0 and se > 0:
        return "lognorm", [math.log(value), float(se) / float(value)]
    return None


def merge_spreads(problem: Mapping[str, Any], rows: Mapping[str, tuple[str, list[float]]]) -> dict[str, Any]:
    """SALib's problem with ``rows`` (key -> dist, bounds) in place of the same keys' rows,
    and added where the problem has none."""
    out = {k: list(problem[k]) for k in ("names", "bounds", "dists")}
    for key, (dist, bounds) in rows.items():
        if key in out["names"]:
            i = out["names"].index(key)
            out["bounds"][i], out["dists"][i] = bounds, dist
        else:
            out["names"].append(key)
            out["bounds"].append(bounds)
            out["dists"].append(dist)
    out["num_vars"] = len(out["names"])
    return out


def _testers(unc: Uncertainty, base: Path, data: Mapping[str, Any]) -> Any:
    """The spreads around this scenario, with the calibrated intervals in place of theirs."""
    from twin.validation.draws import Testers, load_testers

    spec = load_testers(unc.spreads, base, list(data.get("fmu", {})))
    problem = merge_spreads(spec.problem, calibrated_spreads(data, base.resolve().parent))
    return Testers(dataclasses.replace(spec, problem=problem), unc.seed)


def _room(unc: Uncertainty, data: dict[str, Any], scenario: Scenario, i: int) -> str:
    """Sample ``i``'s room: a rise (an ``exponential`` profile, the paper's) takes a shape in
    turn, reaching the scenario's rise at its rise time; any other room keeps its own curve;
    both with a slow drift."""
    from twin.config.profiles import profile_function
    from twin.validation.draws import (
        room_profile,
        sample_times,
        set_room,
        shape,
        smooth_drift,
        with_room_drift,
    )

    profile = room_profile(scenario, unc.room.split(".", 1)[1])
    drift = smooth_drift(generator(unc.seed, Key.SAMPLE, i), unc.room_drift_K)
    if profile.kind != "exponential":
        # not a rise of unknown shape (a day's sine, a lab's table): the scenario's own curve
        with_room_drift(data, scenario, unc.room, drift)
        return "own"
    f = profile_function(profile)
    end = scenario.duration_ns / NS_PER_S
    rise_at = float(profile.params.get("rise_at", end))
    start = float(f(np.array([0.0]))[0])
    rise = float(f(np.array([rise_at]))[0]) - start
    tau_ratio = float(profile.params.get("time_constant", rise_at / 4.0)) / rise_at
    name = unc.room_shapes[i % len(unc.room_shapes)]
    t = sample_times(scenario, [rise_at])
    values = start + rise * shape(name, t / rise_at, tau_ratio) + drift(t / end)
    set_room(data, unc.room, t, values, f"twin run uncertainty: room shape {name} plus a slow drift")
    return name


def sample_scenarios(
    unc: Uncertainty, base: Path, data: Mapping[str, Any], overrides: list[str]
) -> tuple[list[str], Callable[[int], tuple[Scenario, str]]]:
    """The varied keys, and sample ``i``'s scenario and room shape."""
    from twin.config.overrides import apply_overrides
    from twin.sweep.spec import build_scenario
    from twin.validation.draws import overrides_for

    data = copy.deepcopy(dict(data))
    apply_overrides(data, overrides, f"{base}: --set")
    testers = _testers(unc, base, data)
    nominal = build_scenario(data, base, [])

    def make(i: int) -> tuple[Scenario, str]:
        point = copy.deepcopy(data)
        name = _room(unc, point, nominal, i)
        sets = [*overrides_for(testers.draw(i), point), f"scenario.seed={scenario_seed(unc.seed, Key.RUN, Key.SAMPLE, i)}"]
        return build_scenario(point, base, sets), name

    return testers.names, make


# ----------------------------------------------------------------------------- running


def run_uncertainty(
    unc: Uncertainty,
    base: Path,
    data: Mapping[str, Any],
    overrides: list[str],
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    stop: Callable[[], str | None] | None = None,
) -> dict[str, Any]:
    """Run the Monte Carlo on Dask; per sample its room shape and figures (flattened summary
    numbers, :func:`twin.sweep.point.flatten`), in sample order. ``stop`` returning a signal's
    name ends it after the samples done so far (``"interrupted"`` then names it)."""
    from twin.sweep import shipping
    from twin.sweep.execute import execute, failed, one_line, open_client, run_task

    names, make = sample_scenarios(unc, base, data, overrides)
    shapes: dict[int, str] = {}

    def payload(i: int) -> dict[str, Any]:
        try:
            scenario, shapes[i] = make(i)
        except ConfigError as exc:
            return failed(i, one_line(exc))
        return {"index": i, "scenario": scenario, "folders": False}

    start = time.perf_counter()
    records: dict[int, dict[str, Any]] = {}
    with open_client(scheduler, workers) as client:
        client.register_plugin(shipping.BinariesPlugin(shipping.collect()))
        threads = max(1, sum(client.nthreads().values()))
        for record in execute(client, range(unc.samples), payload, run_task):
            records[record["index"]] = record
            if stop is not None and stop():
                break  # the client closes the cluster on the way out
    rows = [
        {"sample": i, "room_shape": shapes.get(i, ""), "status": records[i]["status"],
         "error": records[i]["error"], **records[i]["figures"]}
        for i in sorted(records)
    ]  # fmt: skip
    return {
        "inputs": names,
        "rows": rows,
        "wall_s": time.perf_counter() - start,
        "workers": threads,
        "interrupted": stop() if stop is not None else None,
    }


def _stats(values: np.ndarray) -> dict[str, Any]:
    return {
        "median": float(np.median(values)),
        "mean": float(np.mean(values)),
        "sigma": float(np.std(values, ddof=1)) if len(values) > 1 else 0.0,
        "interval_90": [float(np.percentile(values, 5)), float(np.percentile(values, 95))],
    }


def _column(rows: list[dict[str, Any]], key: str) -> np.ndarray:
    return np.array([r[key] for r in rows if r["status"] == "ok" and key in r], dtype=float)


def fem_components(summary: Mapping[str, Any], rows: list[dict[str, Any]] | None) -> dict[str, Any]:
    """The paper's FEM displacements (mm) beside the twin's thermal parts (its nominal run's,
    and their 90 % interval over the Monte Carlo). Sign: the paper's, Z down positive; the
    twin's, its contribution to the probe's reading."""
    from twin.paper import FEM_PARTS_M

    derived = {"bearing_block"}  # the paper's arithmetic, not a number it prints (facts 2)
    twin = summary.get("thermal_parts_mm", {})
    truth = summary.get("thermal_parts_mm_truth", {})
    out: dict[str, Any] = {}
    for part, metres in FEM_PARTS_M.items():
        entry: dict[str, Any] = {"paper": metres * 1e3, "derived": part in derived, "twin": twin.get(part)}
        if part in truth:
            # the tester's own displacement (FixtureMechanics), beside the error model's part
            entry["twin_truth"] = truth[part]
        values = _column(rows or [], f"thermal_parts_mm.{part}")
        if len(values):
            entry["twin_interval_90"] = _stats(values)["interval_90"]
        out[part] = entry
    return out


def add_to_summary(summary: dict[str, Any], mc: Mapping[str, Any] | None) -> dict[str, Any]:
    """The run's summary with the drift's uncertainty and the FEM comparison added."""
    from twin.paper import DRIFT_M

    summary.setdefault("paper", {})["fem_components_mm"] = fem_components(summary, mc["rows"] if mc else None)
    summary["paper"]["sign_convention"] = (
        "paper: displacement, Z down positive; twin: the part's contribution to the probe's reading"
    )
    if mc is None:
        return summary
    rows = mc["rows"]
    probe = _column(rows, "drift_mm.probe")
    if len(probe) == 0:
        summary["drift_mm"]["uncertainty"] = {"samples": 0, "failed": len(rows)}
        return summary
    s = _stats(probe)
    drift = summary["drift_mm"]
    drift.update(interval_90=s["interval_90"], sigma=s["sigma"], samples=len(probe))
    paper = DRIFT_M * 1e3
    shapes = sorted({r["room_shape"] for r in rows})
    drift["uncertainty"] = {
        "quantity": "drift_mm.probe: the virtual probe's drift, the twin's prediction of the paper's reading",
        "nominal": drift.get("probe"),
        **s,
        "samples": len(probe),
        "failed": sum(r["status"] != "ok" for r in rows),
        **(
            {
                "paper_measured_inside_interval_90": bool(
                    s["interval_90"][0] <= paper <= s["interval_90"][1]
                ),
                # where the measured value falls in the distribution: near 0.05 or 0.95 the
                # inside/outside verdict is within the quantiles' sampling error
                "paper_measured_quantile": float(np.mean(probe <= paper)),
            }
            if "paper_measured" in drift
            else {}
        ),
        "predicted": _stats(_column(rows, "drift_mm.predicted")),
        "median_by_room_shape": {
            k: float(np.median(_column([r for r in rows if r["room_shape"] == k], "drift_mm.probe")))
            for k in shapes
            if len(_column([r for r in rows if r["room_shape"] == k], "drift_mm.probe"))
        },
        "inputs": [*mc["inputs"], "room curve shape", "room drift", "sensor noise seed"],
        "wall_s": mc["wall_s"],
        "workers": mc["workers"],
    }
    return summary


def write_samples(out: Path, mc: Mapping[str, Any]) -> Path:
    """The Monte Carlo's samples as ``uncertainty.csv`` in the run folder."""
    import pandas as pd

    path = out / "uncertainty.csv"
    keep = ["sample", "room_shape", "status", "error", "drift_mm.probe", "drift_mm.predicted"]
    frame = pd.DataFrame.from_records(mc["rows"])
    frame = frame.reindex(
        columns=[*keep, *sorted(c for c in frame.columns if c.startswith("thermal_parts_mm."))]
    )
    frame.to_csv(path, index=False)
    return path


# ----------------------------------------------------------------------------- twin run


@dataclass(frozen=True)
class RunUncertainty:
    """What ``twin run`` adds to a run of a scenario with an ``[uncertainty]`` table."""

    path: Path
    data: Mapping[str, Any]
    overrides: tuple[str, ...]
    uncertainty: Uncertainty | None


def for_run(path: Path, overrides: list[str], samples: int | None) -> RunUncertainty | None:
    """Checked before the run: None when the scenario has no ``[uncertainty]`` table and
    ``--uncertainty`` asks for nothing."""
    from twin.config.load import read_scenario_data

    data = read_scenario_data(path)
    if "uncertainty" not in data and not samples:
        return None
    return RunUncertainty(path, data, tuple(overrides), parse_uncertainty(path, data, samples))


def finish_run(
    ru: RunUncertainty, out: Path, echo: Callable[[str], None], stop: Callable[[], str | None] | None = None
) -> str | None:
    """Run the Monte Carlo (if any samples), add its figures and the FEM comparison to the
    run folder's summary.json, write uncertainty.csv. Returns the name of a signal that
    stopped the Monte Carlo (the run's own outputs then stay as they were), else None."""
    import json

    from twin.outputs.summary import write_summary

    mc = None
    if ru.uncertainty is not None:
        unc = ru.uncertainty
        echo(f"uncertainty: {unc.samples} samples of {ru.path.name} on Dask")
        mc = run_uncertainty(unc, ru.path, ru.data, list(ru.overrides), stop=stop)
        if mc["interrupted"]:
            return str(mc["interrupted"])
        write_samples(out, mc)
    path = out / "summary.json"
    summary = add_to_summary(json.loads(path.read_text(encoding="utf-8")), mc)
    write_summary(path, summary)
    d = summary["drift_mm"]
    if "interval_90" in d:
        lo, hi = d["interval_90"]
        echo(
            f"drift (probe) {d['probe']:+.4f} mm, sigma {d['sigma']:.4f}, 90 % interval [{lo:+.4f}, {hi:+.4f}] mm "
            f"({d['samples']} samples, {mc['wall_s']:.1f} s)"
            + (f"; paper {d['paper_measured']:+.4f} mm" if "paper_measured" in d else "")
        )
    return None
