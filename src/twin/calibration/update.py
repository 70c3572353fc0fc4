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
   the emulator's check), ``corner.png``, ``predictive.png`` (each record against its prior
   and posterior predictive) and ``tester.toml`` into the output folder: the
   updated tester file (:mod:`twin.uncertainty.updated`) that ``twin run``, ``twin
   compensate`` and ``twin identify`` take with ``--tester``; ``--write`` also puts it where
   the record's ``[tester] file`` says (the shipped ``scenarios/records/li2017-updated.toml``).

Likelihood: ``measured ~ N(drift(theta) + delta, sigma_measured)``, ``delta ~ N(0, scale)``,
and for each calibration record (``[[calibration]]``: the probe heated alone on its bench,
:mod:`twin.calibration.bench`) ``identified ~ N(theta_k, standard error)`` of the parameters it
measures.
"""

from __future__ import annotations

import json
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.calibration.bench import Bench, identified_links, lab_bench_records, links_summary, read_benches
from twin.calibration.design import next_experiment, report_line
from twin.calibration.emulator import Emulator, derive, twin_drift, verify
from twin.config.reader import Problems, read_toml, unsafe_name
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
_TOP = {"record", "drift", "rises", "update", "discrepancy", "sampler", "tester", "calibration"}
#: posterior draws an updated tester file keeps (evenly thinned): an updated prediction of
#: ``twin run`` takes one per Monte Carlo sample (the paper's: 200)
TESTER_DRAWS = 400


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
    #: where ``--write`` puts the updated tester file, and the coefficients file it names
    #: (identified on the updated tester by ``twin identify --tester``), both or neither
    tester_file: Path | None = None
    tester_coefficients: str | None = None
    calibration: tuple[Bench, ...] = ()


def load_record(path: Path, seed: int | None = None, sampler: Mapping[str, int] | None = None) -> Record:
    """The record file at ``path``, checked (every problem at once, one line each);
    ``seed`` and ``sampler`` (walkers, steps, burn) override its own."""
    for key, value in (sampler or {}).items():
        lo = _LEAST[key]
        if not isinstance(value, int) or value < lo:
            raise ConfigError(f"expected an integer >= {lo}, got {value!r}", source=f"--{key}")
    raw = read_toml(path, str(path))
    if "record" not in raw and set(raw) - _TOP:
        # another kind of file (an updated tester file, a scenario): one line, not one per table
        others = ", ".join(f"[{k}]" for k in sorted(set(raw) - _TOP))
        raise ConfigError(f"not a record file (no [record]; it has {others})", source=str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP, "")
    rec, drift, upd = p.table(raw, "record"), p.table(raw, "drift"), p.table(raw, "update")
    disc, samp = p.table(raw, "discrepancy"), dict(p.table(raw, "sampler")) | dict(sampler or {})
    tester_file, tester_coefficients = _tester(p, raw, path.resolve().parent)
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
    name = _where_it_writes(p, rec.get("name", path.stem), tester_file)
    measured = p.number(drift, "measured_mm", "drift.")
    sigma = p.number(drift, "sigma_mm", "drift.", lo=1e-9)
    groups, hold = _groups(p, upd)
    if disc.get("scale") != "held inputs":
        p.add(
            "discrepancy.scale", 'expected "held inputs" (the spread of the drift over what the update holds)'
        )
    held = p.integer(disc, "samples", "discrepancy.", default=40, lo=2, hi=10_000)
    walkers, steps, burn, thin = _sampler(p, samp)
    own_seed = p.integer(samp, "seed", "sampler.", default=0, lo=0, hi=2**63 - 1)
    table = p.table(raw, "rises")
    rises = {str(k): p.number(table, k, "rises.") for k in table if k not in ("resolution_K", "source")}
    benches = read_benches(p, raw.get("calibration"), folder)
    if benches and isinstance(groups, list) and "probe drift" not in groups:
        p.add(
            "calibration",
            'a probe-heating record measures the "probe drift" group: update.groups must sample it',
        )
    p.check()
    return Record(
        path,
        str(name),
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
        tester_file,
        tester_coefficients,
        benches,
    )


def _groups(p: Problems, upd: Mapping[str, Any]) -> tuple[Any, Any]:
    """The ``[update]`` table's sampled groups and held keys."""
    groups = upd.get("groups")
    if not isinstance(groups, list) or not groups or not set(groups) <= set(ROLES):
        p.add("update.groups", f"expected a list from {sorted(ROLES)}")
    hold = upd.get("hold", [])
    if not isinstance(hold, list) or not all(isinstance(h, str) for h in hold):
        p.add("update.hold", "expected a list of the prior file's keys")
    return groups, hold


def _tester(p: Problems, raw: Mapping[str, Any], folder: Path) -> tuple[Path | None, str | None]:
    """The ``[tester]`` table: where ``--write`` puts the updated tester file, and the
    coefficients file that file names (both relative to the record file)."""
    tester = p.table(raw, "tester") if "tester" in raw else {}
    p.unknown_keys(tester, {"file", "coefficients", "source"}, "tester.")
    for key in ("file", "coefficients"):
        if key in tester and not (isinstance(tester[key], str) and tester[key].endswith(".toml")):
            p.add(f"tester.{key}", "expected a .toml file name (relative to this file)")
            return None, None
    name = tester.get("file")
    if isinstance(name, str) and Path(name).name != name:
        # --write writes there: a record from elsewhere must not name a file outside its folder
        p.add("tester.file", "expected a file name in the record's own folder, no path")
        return None, None
    return (folder / name if name else None), tester.get("coefficients")


def _where_it_writes(p: Problems, name: Any, tester_file: Path | None) -> Any:
    """The record's name, which names the default output folder (runs/update-<name>): no path
    in it, or the update would write wherever the record says; and its ``[tester] file``, which
    ``--write`` replaces: never the record itself, its scenario, its prior or anyone's file."""
    if (why := unsafe_name(name)) is not None:
        p.add("record.name", why)
    if tester_file is not None and _not_a_tester(tester_file):
        p.add(
            "tester.file",
            f"{tester_file.name} exists and is not an updated tester file: --write would replace it",
        )
    return name


def _not_a_tester(path: Path) -> bool:
    """Whether ``path`` is a file other than an updated tester file (which ``--write`` may
    replace): anything else there is someone's data."""
    if path.is_symlink() or not path.exists():
        return False  # a link there is replaced, never followed (twin.files)
    if not path.is_file():
        return True
    try:
        raw = read_toml(path, str(path))
    except ConfigError:
        return True
    return "tester" not in raw or not set(raw) <= {"tester", "values", "posterior"}


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
    record: Record,
    out: Path,
    echo: Callable[[str], None] = print,
    emulator: Emulator | None = None,
    *,
    write: bool = False,
) -> dict[str, Any]:
    """Update the twin from ``record`` into ``out`` (see the module); the summary. An
    ``emulator`` derived before (of the same record) is checked again, not derived again;
    ``write`` also writes the updated tester file where the record's ``[tester] file`` says."""
    from twin.config.load import load_scenario

    start = time.perf_counter()
    if write and record.tester_file is None:
        # refused before the update runs (the paper's takes minutes), not after it
        raise ConfigError(
            "names no [tester] file for --write to write", source=str(record.path), key="tester.file"
        )
    scenario = load_scenario(record.scenario)
    prior, roles = sampled_rows(record, scenario)
    dims = len(prior.rows) + 1
    if record.walkers < 2 * dims:
        # emcee's ensemble moves need the walkers to span the space (its start is refused below)
        raise ConfigError(
            f"expected at least {2 * dims} walkers (twice the {dims} sampled coordinates), got {record.walkers}",
            source=f"{record.path}: sampler.walkers (or --walkers)",
        )
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
    summary["next_experiment"] = next_experiment(record, prior, emulator, chains, roles)
    summary["wall_s"] = {"sampler": wall, "total": time.perf_counter() - start}
    summary["rises_K"] |= twin_rises(scenario, record.rises_K)
    values = write_outputs(out, summary, prior, emulator, chains)
    write_atomic(
        out / "predictive.png", lambda tmp: predictive_plot(tmp, record, (prior, emulator), chains, summary)
    )
    write_tester(out / "tester.toml", record, summary, (prior.names, values), coefficients=False)
    if write and record.tester_file is not None:
        write_tester(record.tester_file, record, summary, (prior.names, values), coefficients=True)
        echo(f"update: the updated tester written to {record.tester_file}")
    return summary


def check_out(out: Path) -> None:
    """Refuse (before anything runs) an output folder that is a link, or that holds another
    command's outputs (a run's run.json, a summary.json that is not an update's): the update's
    summary.json would replace theirs without a word."""
    from twin.outputs.guard import refuse_links
    from twin.outputs.run_folder import RUN_FILE

    if out.is_symlink():
        refuse_links(out.parent, [out.name])
    if not out.is_dir():
        return
    refuse_links(out, ["samples.parquet", "summary.json", "corner.png", "predictive.png", "tester.toml"])
    found = [RUN_FILE] if (out / RUN_FILE).exists() else []
    try:
        own = "measured_drift_mm" in json.loads((out / "summary.json").read_text(encoding="utf-8"))
    except FileNotFoundError:
        own = True
    except (OSError, UnicodeDecodeError, ValueError, TypeError):
        own = False  # unreadable: not known to be an update's, so not replaced
    if not own:
        found.append("summary.json")
    if found:
        raise ConfigError(
            f"{out} holds another command's outputs ({', '.join(found)}): name another --out",
            source="--out",
        )


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
    with warnings.catch_warnings():
        # a short chain (a test's, a trial's) has more walkers than kept steps: arviz warns of
        # a transposed array, which this is not (walkers are its chains)
        warnings.filterwarnings("ignore", "More chains", UserWarning)
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
        "prior": str(record.prior),
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
) -> np.ndarray:
    """samples.parquet, summary.json and corner.png into ``out``; the posterior's samples
    (physical units, the sampled parameters then delta) in walker order."""
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
    # single precision keeps 7 digits, more than any parameter is known to, at half the file
    stored = frame.astype({c: "float32" for c in frame.columns if c not in ("walker", "step")})
    write_atomic(out / "samples.parquet", lambda tmp: stored.to_parquet(tmp, index=False))
    text = json.dumps(summary, indent=2, sort_keys=False) + "\n"
    write_atomic(out / "summary.json", lambda tmp: Path(tmp).write_text(text))
    leading = sorted(
        summary["parameters"], key=lambda n: -abs(summary["parameters"][n]["shift_prior_sigma"])
    )[:5]
    columns = [*[n for n in leading if n != DELTA], DELTA, "drift_mm"]
    write_atomic(out / "corner.png", lambda tmp: corner_plot(frame[columns], tmp))
    return values


def _spread_draws(walkers: int, total: int) -> np.ndarray:
    """Which of the posterior's samples (walker by walker, ``total`` of them) a tester file
    keeps: draw ``j`` from walker ``j mod walkers``, at one of ``count`` steps spread evenly over
    the chain, taken in a shuffled order (a multiplier prime to ``count``), so that any first
    ``n`` draws (a run's ``n`` samples) come from every walker and the whole chain."""
    steps = total // walkers
    count = min(TESTER_DRAWS, total)
    j = np.arange(count)
    # 7919 is prime and larger than any count kept (TESTER_DRAWS): j -> 7919 j mod count permutes
    return (j % walkers) * steps + ((j * 7919) % count) * steps // count


def write_tester(
    path: Path,
    record: Record,
    summary: Mapping[str, Any],
    posterior: tuple[Sequence[str], np.ndarray],
    *,
    coefficients: bool,
) -> Path:
    """The updated tester file (:mod:`twin.uncertainty.updated`) at ``path``: the posterior
    means as its values, :data:`TESTER_DRAWS` evenly thinned draws, the stamps of what it was
    made from, and (``coefficients``) the record's ``[tester] coefficients``."""
    import os

    from twin.fmu.build import source_hash
    from twin.fmu.sources import model_names
    from twin.uncertainty.updated import file_sha256, write_updated

    names, values = posterior
    params = summary["parameters"]
    means = {n: params[n]["posterior"]["mean"] for n in names}
    rows = values[_spread_draws(record.walkers, len(values)), : len(names)]
    g, d = summary["diagnostics"], summary["drift_mm"]["updated"]
    folder = path.resolve().parent
    head: dict[str, Any] = {
        "name": f"{record.name}-updated",
        # relative beside the record (the shipped tester), absolute from a run folder elsewhere
        "record": rel
        if not (rel := os.path.relpath(record.path.resolve(), folder)).startswith("../..")
        else str(record.path.resolve()),
        "record_sha256": file_sha256(record.path),
        # the experiment's scenario file: its rates or parameters changed, the update is stale
        "scenario_sha256": file_sha256(record.scenario),
        "prior_sha256": file_sha256(record.prior),
        "fmu_sources": {m: source_hash(m) for m in model_names()},
        "source": (
            f"twin update {record.path.name}: emcee, {record.walkers} walkers x {record.steps} steps "
            f"(burn {record.burn}, thin {record.thin}), seed {record.seed}"
        ),
        "diagnostics": {
            "r_hat_max": g["r_hat_max"],
            "ess_min": g["ess_min"],
            "beyond_3_prior_sigma": list(summary["beyond_3_prior_sigma"]),
            "discrepancy_prior_sigma_mm": summary["discrepancy"]["prior_sigma_mm"],
            "discrepancy_posterior_mean_mm": summary["discrepancy"]["posterior"]["mean"],
            "updated_drift_median_mm": d["median"],
            "updated_drift_interval_90_mm": d["interval_90"],
        },
    }
    if coefficients and record.tester_coefficients is not None:
        named = (record.path.resolve().parent / record.tester_coefficients).resolve()
        head["coefficients"] = os.path.relpath(named, folder)
    comment = (
        f"The tester of the record {record.name}, updated by `twin update` (made by a program: rerun\n"
        "`twin update --write` to renew it, do not edit by hand). [values] are the posterior means,\n"
        "[posterior] evenly thinned posterior draws; see twin.uncertainty.updated."
    )
    return write_updated(path, head, means, (names, rows), comment)


def predictive_plot(
    path: Path,
    record: Record,
    model: tuple[PriorMap, Emulator],
    chains: np.ndarray,
    summary: Mapping[str, Any],
) -> None:
    """The posterior predictive of each record beside its prior predictive: the drift (the
    twin plus the discrepancy, the measured value with its sigma) and each calibration term
    (the linked parameter, the identified value with its standard error)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    prior, emulator = model
    scale = summary["discrepancy"]["prior_sigma_mm"]
    order = [emulator.names.index(n) for n in prior.names]
    draws = generator(record.seed, Key.UPDATE, 2).standard_normal((PRIOR_DRAWS, len(prior.rows) + 1))

    def physical(u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        theta = np.empty((u.shape[0], len(emulator.names)))
        theta[:, order] = prior.theta(u[:, :-1])
        return theta, emulator.drift(theta) + scale * u[:, -1]

    flat = chains.reshape(-1, chains.shape[-1])
    (pri_theta, pri_drift), (post_theta, post_drift) = physical(draws), physical(flat)
    twin_only = (post_drift - scale * flat[:, -1]) * 1e3  # the updated twin, without the discrepancy
    terms = summary.get("calibration", {}).get("terms", {})
    fig, axes = plt.subplots(1, 1 + len(terms), figsize=(5.0 * (1 + len(terms)), 3.4), squeeze=False)
    panels = [("drift, um", pri_drift * 1e3, post_drift * 1e3, record.drift_mm * 1e3, record.sigma_mm * 1e3)]
    for name, term in terms.items():
        k = emulator.names.index(name)  # the prior file's key the bench measures
        label = f"{name.split('.')[-1]} (bench)"
        panels.append((label, pri_theta[:, k], post_theta[:, k], term["identified"], term["standard_error"]))
    for ax, (label, before, after, measured, sigma) in zip(axes[0], panels, strict=True):
        # fine bins: the posterior is a sliver of the prior's range
        bins = np.linspace(*np.percentile(np.concatenate([before, after]), [0.5, 99.5]), 150)
        ax.hist(before, bins=bins, density=True, color="0.75", label="prior predictive")
        ax.hist(
            after,
            bins=bins,
            density=True,
            histtype="step",
            color="tab:blue",
            lw=1.5,
            label="posterior predictive",
        )
        if ax is axes[0][0]:
            ax.hist(
                twin_only,
                bins=bins,
                density=True,
                histtype="step",
                color="tab:blue",
                ls="--",
                label="updated twin",
            )
        ax.axvspan(measured - sigma, measured + sigma, color="tab:red", alpha=0.25)
        ax.axvline(measured, color="tab:red", lw=1.2, label="measured (+- sigma)")
        ax.set_xlabel(label, fontsize=8)
        ax.tick_params(labelsize=7)
    axes[0][0].legend(fontsize=7)
    fig.suptitle(
        f"twin update {record.name}: each record against its prior and posterior predictive", fontsize=9
    )
    fig.tight_layout()
    fig.savefig(path, format="png", dpi=110)
    plt.close(fig)


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
    lines.append(report_line(summary["next_experiment"]))
    return lines
