"""``twin update``: the twin's uncertain parameters updated from a lab's record (issue 31).

A record file (``scenarios/records/li2017.toml``, the paper's) names the experiment it was
taken in, the prior file, the measured probe drift with its noise, the measured rises, the
prior groups the update samples and the discrepancy's scale. The update:

1. derives an emulator of the twin's probe drift from twin runs and verifies it against full
   runs at prior draws (:mod:`twin.calibration.emulator`; refused above 0.1 um);
2. sets the discrepancy's scale: the spread of the twin's drift over the prior inputs the
   update holds (thermal network, room, noise, ...), from twin runs;
3. samples the posterior with emcee (differential-evolution moves; every coordinate a
   standard normal under the prior: ``theta = mu + sigma u``, ``exp(m + s u)`` or
   ``low + (high - low) Phi(u)``), the discrepancy delta one more coordinate;
4. writes ``samples.parquet``, ``summary.json`` (each parameter's prior and posterior, the
   discrepancy, the prior and posterior predictive of the drift, R-hat and ESS from arviz,
   the emulator's check) and ``corner.png`` into the output folder.

Likelihood: ``measured ~ N(drift(theta) + delta, sigma_measured)``, ``delta ~ N(0, scale)``,
and for each calibration record (``[[calibration]]``: the probe heated alone on its bench,
:mod:`twin.calibration.bench`) ``identified ~ N(theta_k, standard error)`` of the parameters it
measures.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.calibration.bench import Bench, identified_links, lab_bench_records, links_summary, read_benches
from twin.calibration.emulator import Emulator, derive, twin_drift, verify
from twin.config.reader import Problems, read_toml
from twin.errors import ConfigError, RunError
from twin.files import write_atomic
from twin.seeds import Key, generator
from twin.uncertainty.spreads import Row

__all__ = ["Record", "load_record", "run_update"]

#: the role each prior group plays in the emulator's structure (twin.calibration.emulator)
ROLES = {
    "lengths": "carrier",
    "alphas": "alphas",
    "point-vs-mean": "point-vs-mean",
    "probe drift": "additive",
}
#: the emulator is used only within this of full twin runs (um)
EMULATOR_LIMIT_UM = 0.1
#: prior draws the emulator is checked at, and the draws of the prior predictive
VERIFY_DRAWS = 20
PRIOR_DRAWS = 4000
DELTA = "discrepancy_mm"
#: the least of each sampler setting (a command line's override is refused below it)
_LEAST = {"walkers": 8, "steps": 10, "burn": 0, "thin": 1}
_TOP = {"record", "drift", "rises", "update", "discrepancy", "sampler", "calibration"}


@dataclass(frozen=True)
class Record:
    """A checked record file."""

    path: Path
    name: str
    scenario: Path
    prior: Path
    drift_mm: float
    sigma_mm: float
    rises_K: Mapping[str, float]
    groups: tuple[str, ...]
    hold: tuple[str, ...]
    held_samples: int
    walkers: int
    steps: int
    burn: int
    thin: int
    seed: int
    calibration: tuple[Bench, ...] = ()


def load_record(path: Path, seed: int | None = None, sampler: Mapping[str, int] | None = None) -> Record:
    """The record file at ``path``, checked (every problem at once, one line each);
    ``seed`` and ``sampler`` (walkers, steps, burn) override its own."""
    for key, value in (sampler or {}).items():
        lo = _LEAST[key]
        if not isinstance(value, int) or value < lo:
            raise ConfigError(f"expected an integer >= {lo}, got {value!r}", source=f"--{key}")
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP, "")
    rec, drift, upd = p.table(raw, "record"), p.table(raw, "drift"), p.table(raw, "update")
    disc, samp = p.table(raw, "discrepancy"), dict(p.table(raw, "sampler")) | dict(sampler or {})
    for where, table, keys in (
        ("record.", rec, {"name", "scenario", "prior", "source"}),
        ("drift.", drift, {"measured_mm", "sigma_mm", "source"}),
        ("update.", upd, {"groups", "hold", "hold_source"}),
        ("discrepancy.", disc, {"scale", "samples", "source"}),
        ("sampler.", samp, set(_LEAST) | {"seed"}),
    ):
        p.unknown_keys(table, keys, where)
    folder = path.resolve().parent
    files = {}
    for key in ("scenario", "prior"):
        value = rec.get(key)
        files[key] = (folder / str(value)).resolve() if isinstance(value, str) else None
        if files[key] is None or not files[key].is_file():
            p.add(f"record.{key}", f"no such file {value!r}")
    measured = p.number(drift, "measured_mm", "drift.")
    sigma = p.number(drift, "sigma_mm", "drift.", lo=1e-9)
    groups = upd.get("groups")
    if not isinstance(groups, list) or not groups or not set(groups) <= set(ROLES):
        p.add("update.groups", f"expected a list from {sorted(ROLES)}")
    if disc.get("scale") != "held inputs":
        p.add(
            "discrepancy.scale", 'expected "held inputs" (the spread of the drift over what the update holds)'
        )
    held = p.integer(disc, "samples", "discrepancy.", default=40, lo=2, hi=10_000)
    walkers, steps, burn, thin = _sampler(p, samp)
    own_seed = p.integer(samp, "seed", "sampler.", default=0, lo=0, hi=2**63 - 1)
    table = p.table(raw, "rises")
    rises = {str(k): p.number(table, k, "rises.") for k in table if k not in ("resolution_K", "source")}
    hold = upd.get("hold", [])
    if not isinstance(hold, list) or not all(isinstance(h, str) for h in hold):
        p.add("update.hold", "expected a list of the prior file's keys")
    benches = read_benches(p, raw.get("calibration"), folder)
    if benches and isinstance(groups, list) and "probe drift" not in groups:
        p.add(
            "calibration",
            'a probe-heating record measures the "probe drift" group: update.groups must sample it',
        )
    p.check()
    return Record(
        path,
        str(rec.get("name", path.stem)),
        files["scenario"],
        files["prior"],
        float(measured),
        float(sigma),
        {k: float(v) for k, v in rises.items()},
        tuple(groups),
        tuple(hold),
        int(held),
        int(walkers),
        int(steps),
        int(burn),
        int(thin),
        int(own_seed if seed is None else seed),
        benches,
    )


def _sampler(p: Problems, samp: Mapping[str, Any]) -> tuple[Any, Any, Any, Any]:
    """The ``[sampler]`` table's walkers, steps, burn and thin (None where a problem is)."""
    walkers = p.integer(samp, "walkers", "sampler.", default=96, lo=8, hi=10_000)
    steps = p.integer(samp, "steps", "sampler.", default=4000, lo=10, hi=10_000_000)
    burn = p.integer(samp, "burn", "sampler.", default=1000, lo=0, hi=10_000_000)
    thin = p.integer(samp, "thin", "sampler.", default=10, lo=1, hi=100_000)
    if steps is not None and burn is not None and burn >= steps:
        p.add("sampler.burn", f"expected fewer than the {steps} steps")
    elif None not in (steps, burn, thin) and (steps - burn) // thin < 4:
        # R-hat and ESS need a few kept steps per walker (arviz gives NaN below)
        p.add(
            "sampler.steps",
            f"keeps {(steps - burn) // thin} steps per walker after burn and thinning: at least 4",
        )
    return walkers, steps, burn, thin


# ----------------------------------------------------------------------------- the prior


@dataclass(frozen=True)
class PriorMap:
    """The sampled parameters' prior rows, each mapped from a standard normal coordinate."""

    rows: tuple[Row, ...]

    @property
    def names(self) -> list[str]:
        return [r[0] for r in self.rows]

    def theta(self, u: np.ndarray) -> np.ndarray:
        """Parameters from standard normal coordinates (rows of ``u``)."""
        from scipy.special import ndtr

        out = np.empty_like(u)
        for k, (_, dist, b) in enumerate(self.rows):
            x = u[:, k]
            if dist == "norm":
                out[:, k] = b[0] + b[1] * x
            elif dist == "lognorm":
                out[:, k] = np.exp(b[0] + b[1] * x)
            elif dist == "unif":
                out[:, k] = b[0] + (b[1] - b[0]) * ndtr(x)
            else:
                raise ConfigError(
                    f"the update takes normal, lognormal or uniform spreads, not {dist}", key=self.rows[k][0]
                )
        return out

    def scales(self) -> dict[str, float]:
        """Each parameter's prior sigma."""
        return {r[0]: float(np.std(self.theta(_grid(len(self.rows)))[:, k])) for k, r in enumerate(self.rows)}


def _grid(dims: int) -> np.ndarray:
    """Standard normal quantiles, the same in every column (a prior's sigma without noise)."""
    from scipy.special import ndtri

    q = ndtri((np.arange(2000) + 0.5) / 2000)
    return np.repeat(q[:, None], dims, axis=1)


def sampled_rows(record: Record, scenario: Any) -> tuple[PriorMap, dict[str, str]]:
    """The prior rows the update samples and each one's emulator role."""
    from twin.uncertainty.testers import load_prior

    prior = load_prior(record.prior, scenario)
    rows = [r for r in prior.rows if prior.groups.get(r[0]) in record.groups and r[0] not in record.hold]
    return PriorMap(tuple(rows)), {r[0]: ROLES[prior.groups[r[0]]] for r in rows}


# ----------------------------------------------------------------------------- the update


def run_update(
    record: Record, out: Path, echo: Callable[[str], None] = print, emulator: Emulator | None = None
) -> dict[str, Any]:
    """Update the twin from ``record`` into ``out`` (see the module); the summary. An
    ``emulator`` derived before (of the same record) is checked again, not derived again."""
    from twin.config.load import load_scenario

    start = time.perf_counter()
    scenario = load_scenario(record.scenario)
    prior, roles = sampled_rows(record, scenario)
    run = twin_drift(scenario)
    nominal = {n: float(scenario.nominal(n)) for n in prior.names}
    if emulator is None:
        emulator = derive(run, nominal, prior.scales(), roles)
    rng = generator(record.seed, Key.UPDATE, 0)
    check = verify(emulator, run, prior.theta(rng.standard_normal((VERIFY_DRAWS, len(prior.rows)))))
    echo(
        f"update: emulator from {len(emulator.terms)} terms, within {check['max_um']:.3f} um "
        f"of {check['runs']} full twin runs (RMS {check['rms_um']:.3f} um)"
    )
    if check["max_um"] > EMULATOR_LIMIT_UM:
        raise RunError(
            f"the emulator misses the twin by {check['max_um']:.3f} um (limit {EMULATOR_LIMIT_UM} um)"
        )
    held = held_spread(record, scenario, nominal, run)
    echo(
        f"update: discrepancy scale {held['sigma_mm'] * 1e3:.2f} um (the drift's spread over {held['runs']} held draws)"
    )
    links = identified_links(lab_bench_records(record.calibration))
    chains, wall = sample(record, prior, emulator, held["sigma_mm"], links)
    echo(f"update: {record.walkers} walkers x {record.steps} steps in {wall:.1f} s")
    summary = summarise(record, prior, emulator, chains, held)
    if links:
        summary["calibration"] = links_summary(links, record.calibration)
    summary["emulator"] = check | {"terms": emulator.describe()}
    summary["wall_s"] = {"sampler": wall, "total": time.perf_counter() - start}
    summary["rises_K"] |= twin_rises(scenario, record.rises_K)
    write_outputs(out, summary, prior, emulator, chains)
    return summary


def twin_rises(scenario: Any, measured: Mapping[str, float]) -> dict[str, Any]:
    """The nominal twin's rises beside the record's (K): what the held thermal network gives."""
    from twin.pipeline.prepare import prepare_scenario
    from twin.pipeline.stages import run_point

    figures = run_point(prepare_scenario(scenario)).figures()
    twin = {
        k: float(figures[f"temperature_rise_C.{k}"]) for k in measured if f"temperature_rise_C.{k}" in figures
    }
    diffs = [abs(twin[k] - measured[k]) for k in twin]
    return {"twin": twin, "largest_difference_K": max(diffs) if diffs else None}


def held_spread(
    record: Record, scenario: Any, nominal: Mapping[str, float], run: Callable[..., float]
) -> dict[str, Any]:
    """The discrepancy's scale: the twin's drift over prior draws of every input the update
    holds (the Monte Carlo of ``twin run``, twin.pipeline.montecarlo, with the sampled
    parameters set back to their nominal values)."""
    from twin.pipeline.montecarlo import Uncertainty, sampler
    from twin.uncertainty.testers import load_room

    room = load_room(record.prior)
    unc = Uncertainty(
        record.held_samples, record.seed, record.prior, "input.thermal.t_room", room.shapes, room.drift_K
    )
    _, make = sampler(unc, scenario)
    drifts = np.array([run(nominal, make(i).scenario) for i in range(record.held_samples)])
    return {
        "sigma_mm": float(np.std(drifts, ddof=1)),
        "median_mm": float(np.median(drifts)),
        "runs": len(drifts),
    }


def log_posterior(
    record: Record,
    prior: PriorMap,
    emulator: Emulator,
    scale: float,
    links: Mapping[str, tuple[float, float]] | None = None,
) -> Callable[[np.ndarray], np.ndarray]:
    """The log posterior of standard normal coordinates (rows: walkers), the last one delta's;
    ``links``: a sampled parameter -> (its value identified by a calibration record, standard
    error), each one more Gaussian term (:mod:`twin.calibration.bench`)."""
    order = [emulator.names.index(n) for n in prior.names]
    missing = sorted(set(links or {}) - set(prior.names))
    if missing:
        raise ConfigError(
            f"a calibration record measures {', '.join(missing)}, which the update does not sample",
            source=str(record.path),
            key="update.groups",
        )
    linked = [(prior.names.index(k), v, s) for k, (v, s) in (links or {}).items()]

    def logp(u: np.ndarray) -> np.ndarray:
        theta = np.empty((u.shape[0], len(emulator.names)))
        sampled = prior.theta(u[:, :-1])
        theta[:, order] = sampled
        model = emulator.drift(theta) + scale * u[:, -1]
        out = -0.5 * np.sum(u**2, axis=1) - 0.5 * ((model - record.drift_mm) / record.sigma_mm) ** 2
        for k, value, se in linked:
            out -= 0.5 * ((sampled[:, k] - value) / se) ** 2
        return out

    return logp


def sample(
    record: Record,
    prior: PriorMap,
    emulator: Emulator,
    scale: float,
    links: Mapping[str, tuple[float, float]] | None = None,
) -> tuple[np.ndarray, float]:
    """The posterior's chains in standard normal coordinates, (walkers, steps after burn,
    parameters + delta), and the sampler's wall time (s); ``links`` as :func:`log_posterior`."""
    import emcee

    dims = len(prior.rows) + 1
    start = generator(record.seed, Key.UPDATE, 1).standard_normal((record.walkers, dims))
    # differential evolution for the slab the one drift leaves, stretch moves for the rest;
    # no DESnookerMove: with it the parameters the record says nothing of came out 13 % narrower
    # than their prior (the sd of their coordinates 0.87 over 96 walkers x 8000 steps)
    moves = [(emcee.moves.DEMove(), 0.8), (emcee.moves.StretchMove(), 0.2)]
    sampler = emcee.EnsembleSampler(
        record.walkers,
        dims,
        log_posterior(record, prior, emulator, scale, links),
        moves=moves,
        vectorize=True,
    )
    sampler.random_state = np.random.RandomState(record.seed % 2**32).get_state()
    began = time.perf_counter()
    # only every thin-th step is stored: the whole chain of the paper's record (96 walkers x
    # 120000 steps x 37) would take 3.4 GB
    sampler.run_mcmc(start, record.steps // record.thin, thin_by=record.thin, progress=False)
    wall = time.perf_counter() - began
    return np.swapaxes(sampler.get_chain(discard=record.burn // record.thin), 0, 1), wall


# ----------------------------------------------------------------------------- the figures


def _stats(x: np.ndarray) -> dict[str, Any]:
    lo, med, hi = np.percentile(x, [5, 50, 95])
    return {
        "mean": float(np.mean(x)),
        "sd": float(np.std(x, ddof=1)),
        "median": float(med),
        "interval_90": [float(lo), float(hi)],
    }


def summarise(
    record: Record, prior: PriorMap, emulator: Emulator, chains: np.ndarray, held: Mapping[str, Any]
) -> dict[str, Any]:
    """summary.json's figures (see the module)."""
    import arviz as az

    names = [*prior.names, DELTA]
    scale = held["sigma_mm"]
    flat_u = chains.reshape(-1, chains.shape[-1])
    post = _physical(prior, flat_u, scale)
    draws = generator(record.seed, Key.UPDATE, 2).standard_normal((PRIOR_DRAWS, len(names)))
    pri = _physical(prior, draws, scale)
    data = az.convert_to_dataset({n.split(".")[-1]: chains[:, :, k] for k, n in enumerate(names)})
    rhat, ess = az.rhat(data), az.ess(data)
    params = {}
    for k, n in enumerate(names):
        short = n.split(".")[-1]
        a, b = _stats(pri[:, k]), _stats(post[:, k])
        shift = (b["mean"] - a["mean"]) / a["sd"] if a["sd"] > 0 else 0.0
        params[n] = {
            "prior": a,
            "posterior": b,
            "shift_prior_sigma": shift,
            "r_hat": float(rhat[short]),
            "ess": float(ess[short]),
        }
    drift = _predictive(record, prior, emulator, (draws, flat_u), scale)
    return {
        "record": str(record.path),
        "name": record.name,
        "measured_drift_mm": record.drift_mm,
        "measured_sigma_mm": record.sigma_mm,
        "drift_mm": drift,
        "discrepancy": {
            "prior_sigma_mm": scale,
            "held_runs": held["runs"],
            "posterior": params[DELTA]["posterior"],
        },
        "parameters": params,
        "diagnostics": {
            "r_hat_max": float(max(v["r_hat"] for v in params.values())),
            "ess_min": float(min(v["ess"] for v in params.values())),
            "walkers": record.walkers,
            "thin": record.thin,
            "steps": record.steps,
            "burn": record.burn,
            "seed": record.seed,
        },
        "beyond_3_prior_sigma": [n for n, v in params.items() if abs(v["shift_prior_sigma"]) > 3],
        "rises_K": {
            "measured": dict(record.rises_K),
            "note": "with the thermal network held at its calibration the rises do not depend on the sampled parameters: reported, not used twice",
        },
    }


def _physical(prior: PriorMap, u: np.ndarray, scale: float) -> np.ndarray:
    """Parameters (and delta, mm) from standard normal coordinates."""
    return np.column_stack([prior.theta(u[:, :-1]), scale * u[:, -1]])


def _predictive(
    record: Record, prior: PriorMap, emulator: Emulator, u: tuple[np.ndarray, np.ndarray], scale: float
) -> dict[str, Any]:
    """The drift's prior and posterior predictive: the twin's (the emulator) and the twin's
    plus the discrepancy, with where the measured drift falls in each."""
    order = [emulator.names.index(n) for n in prior.names]
    out: dict[str, Any] = {}
    for label, coords in zip(("prior", "updated"), u, strict=True):
        theta = np.empty((coords.shape[0], len(emulator.names)))
        theta[:, order] = prior.theta(coords[:, :-1])
        twin = emulator.drift(theta)
        with_delta = twin + scale * coords[:, -1]
        out[label] = _stats(twin) | {
            "quantile_of_measured": float(np.mean(twin < record.drift_mm)),
            "with_discrepancy": _stats(with_delta)
            | {"quantile_of_measured": float(np.mean(with_delta < record.drift_mm))},
            "samples": len(twin),
        }
    out["nominal"] = emulator.base
    return out


def write_outputs(
    out: Path, summary: Mapping[str, Any], prior: PriorMap, emulator: Emulator, chains: np.ndarray
) -> None:
    """samples.parquet, summary.json and corner.png into ``out``."""
    import pandas as pd

    out.mkdir(parents=True, exist_ok=True)
    scale = summary["discrepancy"]["prior_sigma_mm"]
    flat = chains.reshape(-1, chains.shape[-1])
    values = _physical(prior, flat, scale)
    frame = pd.DataFrame(values, columns=[*prior.names, DELTA])
    frame.insert(0, "walker", np.repeat(np.arange(chains.shape[0]), chains.shape[1]))
    frame.insert(1, "step", np.tile(np.arange(chains.shape[1]), chains.shape[0]))
    order = [emulator.names.index(n) for n in prior.names]
    theta = np.empty((flat.shape[0], len(emulator.names)))
    theta[:, order] = values[:, :-1]
    frame["drift_mm"] = emulator.drift(theta)
    write_atomic(out / "samples.parquet", lambda tmp: frame.to_parquet(tmp, index=False))
    text = json.dumps(summary, indent=2, sort_keys=False) + "\n"
    write_atomic(out / "summary.json", lambda tmp: Path(tmp).write_text(text))
    leading = sorted(
        summary["parameters"], key=lambda n: -abs(summary["parameters"][n]["shift_prior_sigma"])
    )[:5]
    columns = [*[n for n in leading if n != DELTA], DELTA, "drift_mm"]
    write_atomic(out / "corner.png", lambda tmp: corner_plot(frame[columns], tmp))


def corner_plot(frame: Any, path: Path) -> None:
    """A corner plot of ``frame``'s columns (histograms on the diagonal, 2-D histograms below)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = list(frame.columns)
    n = len(cols)
    fig, axes = plt.subplots(n, n, figsize=(2.0 * n, 2.0 * n), squeeze=False)
    for i, a in enumerate(cols):
        for j, b in enumerate(cols):
            ax = axes[i][j]
            if j > i:
                ax.axis("off")
            elif i == j:
                ax.hist(frame[a], bins=40, color="0.3")
            else:
                ax.hist2d(frame[b], frame[a], bins=40, cmap="Greys")
            ax.tick_params(labelsize=5)
            if i == n - 1:
                ax.set_xlabel(b.split(".")[-1], fontsize=6)
            if j == 0 and i > 0:
                ax.set_ylabel(a.split(".")[-1], fontsize=6)
    fig.suptitle("twin update: the posterior (the five most shifted, the discrepancy, the drift)", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)


def report_lines(summary: Mapping[str, Any]) -> list[str]:
    """The terminal's lines: the predictive drifts beside the measured, the diagnostics."""
    d, m = summary["drift_mm"], summary["measured_drift_mm"]
    lines = []
    for label, what in (
        ("prior", "prior predictive (the twin before the record)"),
        ("updated", "posterior predictive (calibrated on this record)"),
    ):
        s = d[label]
        lo, hi = s["interval_90"]
        lines.append(
            f"drift {what}: median {s['median']:+.4f}, 90 % [{lo:+.4f}, {hi:+.4f}] mm; measured {m:+.4f} at quantile {s['quantile_of_measured']:.3f}"
        )
    disc = summary["discrepancy"]
    lines.append(
        f"discrepancy: prior sigma {disc['prior_sigma_mm'] * 1e3:.2f} um, posterior {disc['posterior']['mean'] * 1e3:+.2f} +- {disc['posterior']['sd'] * 1e3:.2f} um"
    )
    far = summary["beyond_3_prior_sigma"]
    lines.append("beyond 3 prior sigma: " + (", ".join(n.split(".")[-1] for n in far) if far else "none"))
    g = summary["diagnostics"]
    lines.append(
        f"R-hat max {g['r_hat_max']:.4f}, ESS min {g['ess_min']:.0f}; sampler {summary['wall_s']['sampler']:.1f} s, total {summary['wall_s']['total']:.1f} s"
    )
    return lines
