"""Coverage, the honest test of ``twin update``'s uncertainty (issue 31 point 4).

Virtual testers are drawn from the whole prior file (``scenarios/base/priors.toml``: every group,
the thermal network at its calibration's spread, the room's shape and slow drift, the sensor
noise), as the paper replay's Monte Carlo draws them (:func:`twin.pipeline.montecarlo.sampler`).
Each tester, in full twin runs of the FMUs with its drawn values:

- records the paper's experiment: its probe's drift, rounded as the paper's two readings were
  (each to 1 um), is its "measured" drift, with the paper record's sigma;
- records its probe heated alone on the bench (``calibration/probe-heating.toml``): its
  calibration record (:mod:`twin.calibration.bench`);
- runs two scenarios the update never sees (:data:`PREDICTED`): its true drifts.

Each tester is then updated with ``twin update``'s machinery (:mod:`twin.calibration.update`:
the paper's emulator, derived once at the nominal tester; the discrepancy's scale, once; per
tester only the sampler, lighter than the record's, its R-hat kept) and predicts the two
scenarios: each scenario's emulator at the posterior draws plus its discrepancy. The rates are
how often the 90 % intervals cover the truth: the predicted drifts (testers x scenarios) and
the drawn sampled parameters (testers x parameters, and per prior group).

A predicted scenario's emulator keeps the paper emulator's structure (its terms' index tuples:
which lengths multiply which coefficients) and refits the coefficients by least squares to full
runs of that scenario at prior draws of the sampled parameters (the held inputs nominal), then
is checked against further full runs (:func:`refit`, :func:`~twin.calibration.emulator.verify`).

A predicted scenario's discrepancy is the spread of its drift over the held inputs, taken from
the SAME held draws as the paper record's (one draw: one thermal network, one mounting, one
room drift, run in all three scenarios), so the three discrepancies are one joint Gaussian and
a predicted one is drawn conditioned on the paper record's posterior delta: a tester whose held
inputs pushed its paper drift one way pushes the predicted drifts the way they co-vary.

Truth runs, held runs and fitting runs are in process through pooled FMU instances (each run
takes 0.05-2 s: a Dask cluster's start-up would cost more than the ~300 runs).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from twin.calibration import update as U
from twin.calibration.bench import EXPERIMENT, identified_links
from twin.calibration.emulator import Emulator, derive, twin_drift, verify
from twin.config.load import load_scenario, scenarios_dir
from twin.errors import RunError
from twin.seeds import Key, generator, scenario_seed

__all__ = [
    "PREDICTED",
    "Machinery",
    "Predicted",
    "Settings",
    "rates",
    "refit",
    "run_coverage",
    "setup",
    "truth",
    "update_tester",
]

#: the paper's readings were given to 1 um (mm)
READING_MM = 1e-3
#: the interval whose coverage is measured
LEVEL = 0.90
#: posterior draws a prediction is made from
PREDICT_DRAWS = 4000


@dataclass(frozen=True)
class Predicted:
    """A scenario the update never sees: its file and overrides."""

    name: str
    path: Path
    overrides: tuple[str, ...] = ()
    reading: str = ""


#: day-night as committed; the MIL endurance's thermal drift read as the MIL run with load and
#: motion off (the hydraulic station still running), as twin heldout's thermal_only rows are: the
#: twin reports no true thermal part of a loaded run's drift (its error_parts are the error
#: model's estimate), and its loaded drift is the wear's
PREDICTED = (
    Predicted("day-night", scenarios_dir() / "day-night.toml", (), "24 h, room 20 +- 3 degC, 200 kN, motion"),
    Predicted(
        "mil-endurance-thermal",
        scenarios_dir() / "mil-endurance.toml",
        ("input.oscillation.drive_on.value=0", "fmu.hydraulic.parameters.load_mean=0"),
        "41.7 h, load and motion off, station on, room constant (+ its slow drift)",
    ),
)


@dataclass(frozen=True)
class Settings:
    """What a coverage run does: the testers, the held draws, the emulators' runs, the sampler."""

    testers: int = 30
    seed: int = 31
    held: int = 40
    fit_runs: int = 60
    check_runs: int = 10
    sampler: Mapping[str, int] = field(
        default_factory=lambda: {"walkers": 80, "steps": 20000, "burn": 5000, "thin": 10}
    )
    predicted: tuple[Predicted, ...] = PREDICTED
    record: Path = scenarios_dir() / "records" / "li2017.toml"


@dataclass
class Machinery:
    """What is derived once: the record, the scenarios, the emulators and the discrepancy."""

    record: U.Record
    prior: U.PriorMap
    groups: Mapping[str, str]
    scenarios: dict[str, Any]
    emulators: dict[str, Emulator]
    checks: dict[str, dict[str, float]]
    held: dict[str, Any] = field(default_factory=dict)


# ----------------------------------------------------------------------------- set up once


def setup(settings: Settings, echo: Callable[[str], None] = print) -> Machinery:
    """The record, the paper's emulator (derived, checked), each predicted scenario's (refitted,
    checked) and the joint discrepancy of the held inputs."""
    from twin.uncertainty.testers import load_prior

    record = U.load_record(settings.record, sampler=dict(settings.sampler))
    record = dataclasses.replace(record, held_samples=settings.held)
    paper = load_scenario(record.scenario)
    prior, roles = U.sampled_rows(record, paper)
    groups = dict(load_prior(record.prior, paper).groups)
    nominal = {n: float(paper.nominal(n)) for n in prior.names}
    scenarios = {"paper": paper} | {
        p.name: load_scenario(p.path, list(p.overrides)) for p in settings.predicted
    }
    runs = {name: twin_drift(s) for name, s in scenarios.items()}
    emulators = {"paper": derive(runs["paper"], nominal, prior.scales(), roles)}
    rng = generator(settings.seed, Key.UPDATE, 10)
    for p in settings.predicted:
        emulators[p.name] = refit(
            emulators["paper"],
            runs[p.name],
            prior.theta(rng.standard_normal((settings.fit_runs, len(prior.rows)))),
        )
    checks = {}
    for name, emulator in emulators.items():
        draws = prior.theta(rng.standard_normal((settings.check_runs, len(prior.rows))))
        checks[name] = verify(emulator, runs[name], draws)
        echo(
            f"coverage: {name} emulator within {checks[name]['max_um']:.3f} um of {checks[name]['runs']} full runs"
        )
    m = Machinery(record, prior, groups, scenarios, emulators, checks)
    m.held = joint_held(m, nominal, runs)
    echo(
        "coverage: discrepancy over "
        f"{m.held['runs']} held draws, sigma "
        + ", ".join(
            f"{k} {s * 1e3:.2f} um"
            for k, s in zip(m.held["names"], np.sqrt(np.diag(m.held["cov"])), strict=True)
        )
    )
    return m


def refit(paper: Emulator, run: Callable[[Mapping[str, float]], float], draws: np.ndarray) -> Emulator:
    """The paper emulator's terms, their coefficients refitted to ``run``'s drifts at ``draws``
    (rows of parameters) by least squares, the base its nominal run."""
    if len(draws) < len(paper.terms):
        raise RunError(f"refitting {len(paper.terms)} terms takes at least as many runs, got {len(draws)}")
    base = run({})
    values = np.array([run(dict(zip(paper.names, map(float, row), strict=True))) for row in draws])
    x = draws / paper.step
    x0 = paper.nominal / paper.step
    features = np.column_stack(
        [np.prod(x[:, idx], axis=1) - np.prod(x0[list(idx)]) for _, idx in paper.terms]
    )
    coef, *_ = np.linalg.lstsq(features, values - base, rcond=None)
    terms = tuple((float(c), idx) for c, (_, idx) in zip(coef, paper.terms, strict=True))
    return dataclasses.replace(paper, base=float(base), terms=terms)


def joint_held(
    m: Machinery, nominal: Mapping[str, float], runs: Mapping[str, Callable[..., float]]
) -> dict[str, Any]:
    """The drifts of every scenario over the same held draws (the sampled parameters nominal):
    their covariance is the discrepancies' joint Gaussian. The paper's draws are the update's
    own (:func:`twin.calibration.update.held_spread`: the record's seed and count)."""
    from twin.pipeline.montecarlo import Uncertainty, sampler
    from twin.uncertainty.testers import load_room

    room = load_room(m.record.prior)
    unc = Uncertainty(
        m.record.held_samples,
        m.record.seed,
        m.record.prior,
        "input.thermal.t_room",
        room.shapes,
        room.drift_K,
    )
    names = list(m.scenarios)
    makes = {name: sampler(unc, s)[1] for name, s in m.scenarios.items()}
    drifts = np.array([[runs[n](nominal, makes[n](j).scenario) for n in names] for j in range(unc.samples)])
    return {
        "names": names,
        "cov": np.cov(drifts, rowvar=False, ddof=1),
        "mean": drifts.mean(axis=0),
        "runs": len(drifts),
    }


# ----------------------------------------------------------------------------- each tester


def truth(m: Machinery, settings: Settings, i: int) -> dict[str, Any]:
    """Tester ``i``: its drawn values, its measured paper drift, its bench links and its true
    drifts of the predicted scenarios (full runs)."""
    from twin.pipeline.montecarlo import ROOM_INPUTS, Uncertainty, sampler
    from twin.uncertainty.testers import load_room

    room = load_room(m.record.prior)
    unc = Uncertainty(
        settings.testers, settings.seed, m.record.prior, "input.thermal.t_room", room.shapes, room.drift_K
    )
    # each scenario draws the tester from the same uniform numbers around its own file's values:
    # the sampled parameters come out equal (checked); a held one centred elsewhere in a file
    # (the paper's experiment sets the sensor's tilt 0, the tester's files 0.01 rad) keeps its file's
    drifts, values = {}, {}
    for name, scenario in m.scenarios.items():
        draw = sampler(unc, scenario)[1](i)
        drawn = {k: v for k, v in draw.inputs.items() if k not in ROOM_INPUTS}
        if values and any(drawn[n] != values[n] for n in m.prior.names):
            raise RunError(f"tester {i} draws other sampled values in {name} than in the paper's experiment")
        values = values or drawn
        drifts[name] = twin_drift(draw.scenario)({})
    # the paper's two readings, each to 1 um: the start's fraction of a micron is unknown
    start = generator(settings.seed, Key.RUN, i, 1).uniform(0.0, READING_MM)
    measured = (np.round((start + drifts["paper"]) / READING_MM) - np.round(start / READING_MM)) * READING_MM
    return {
        "index": i,
        "values": values,
        "measured_mm": float(measured),
        "paper_drift_mm": drifts.pop("paper"),
        "true_mm": drifts,
        "links": bench_links(values, scenario_seed(settings.seed, Key.RUN, i, 2)),
    }


def bench_links(values: Mapping[str, float], seed: int) -> dict[str, tuple[float, float]]:
    """The tester's probe heated alone on the bench (its drawn values), identified."""
    from twin.errormodel.identify import EXPERIMENTS
    from twin.pipeline.lab import lab_record
    from twin.uncertainty.testers import apply

    experiment = next(e for e in EXPERIMENTS if e.name == EXPERIMENT)
    bench = apply(load_scenario(scenarios_dir() / "calibration" / experiment.scenario), values)
    return identified_links([lab_record(experiment, bench.with_seed(seed))])


def update_tester(m: Machinery, settings: Settings, t: Mapping[str, Any]) -> dict[str, Any]:
    """Tester ``t`` updated from its records, its parameters' and predictions' 90 % intervals."""
    import arviz as az

    record = dataclasses.replace(
        m.record, drift_mm=t["measured_mm"], seed=scenario_seed(settings.seed, Key.UPDATE, t["index"])
    )
    scale = float(np.sqrt(m.held["cov"][0, 0]))
    chains, wall = U.sample(record, m.prior, m.emulators["paper"], scale, t["links"])
    rhat = az.rhat(az.convert_to_dataset({f"p{k}": chains[:, :, k] for k in range(chains.shape[-1])}))
    flat = chains.reshape(-1, chains.shape[-1])
    pick = generator(record.seed, Key.UPDATE, 3).choice(
        len(flat), size=min(PREDICT_DRAWS, len(flat)), replace=False
    )
    u = flat[pick]
    theta = m.prior.theta(u[:, :-1])
    lo, hi = 50 * (1 - LEVEL), 100 - 50 * (1 - LEVEL)
    params = {}
    for k, name in enumerate(m.prior.names):
        a, b = np.percentile(theta[:, k], [lo, hi])
        params[name] = {
            "interval": [float(a), float(b)],
            "true": t["values"][name],
            "covered": bool(a <= t["values"][name] <= b),
        }
    predictions = {}
    deltas = predicted_deltas(m, scale * u[:, -1], generator(record.seed, Key.UPDATE, 4))
    for name, delta in deltas.items():
        full = _emulated(m, name, theta) + delta
        a, b = np.percentile(full, [lo, hi])
        true = t["true_mm"][name]
        predictions[name] = {
            "median": float(np.median(full)),
            "interval": [float(a), float(b)],
            "true": true,
            "covered": bool(a <= true <= b),
        }
    return {
        "index": t["index"],
        "measured_mm": t["measured_mm"],
        "r_hat_max": float(max(float(rhat[v]) for v in rhat.data_vars)),
        "sampler_s": wall,
        "parameters": params,
        "predictions": predictions,
    }


def _emulated(m: Machinery, name: str, theta: np.ndarray) -> np.ndarray:
    emulator = m.emulators[name]
    order = [emulator.names.index(n) for n in m.prior.names]
    full = np.empty((theta.shape[0], len(emulator.names)))
    full[:, order] = theta
    return emulator.drift(full)


def predicted_deltas(
    m: Machinery, paper_delta: np.ndarray, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Each predicted scenario's discrepancy at the posterior's paper deltas: the held draws'
    joint Gaussian conditioned on the paper's (mean Sigma_pq / Sigma_pp delta, variance the
    rest)."""
    cov = m.held["cov"]
    out = {}
    for j, name in enumerate(m.held["names"][1:], start=1):
        gain = cov[0, j] / cov[0, 0]
        rest = max(cov[j, j] - cov[0, j] ** 2 / cov[0, 0], 0.0)
        out[name] = gain * paper_delta + np.sqrt(rest) * rng.standard_normal(len(paper_delta))
    return out


# ----------------------------------------------------------------------------- the rates


def rates(rows: Sequence[Mapping[str, Any]], groups: Mapping[str, str]) -> dict[str, Any]:
    """The coverage rates from the testers' rows: counts and their ratio."""
    pred = [p["covered"] for r in rows for p in r["predictions"].values()]
    par = [(n, p["covered"]) for r in rows for n, p in r["parameters"].items()]
    by_group: dict[str, list[bool]] = {}
    for n, c in par:
        by_group.setdefault(groups.get(n, "other"), []).append(c)
    by_scenario: dict[str, list[bool]] = {}
    for r in rows:
        for name, p in r["predictions"].items():
            by_scenario.setdefault(name, []).append(p["covered"])

    def rate(flags: Sequence[bool]) -> dict[str, Any]:
        return {
            "covered": int(sum(flags)),
            "of": len(flags),
            "rate": float(sum(flags) / len(flags)) if flags else float("nan"),
        }

    return {
        "predictive": rate(pred),
        "predictive_by_scenario": {k: rate(v) for k, v in by_scenario.items()},
        "parameters": rate([c for _, c in par]),
        "parameters_by_group": {k: rate(v) for k, v in by_group.items()},
    }


def run_coverage(
    settings: Settings, echo: Callable[[str], None] = print, machinery: Machinery | None = None
) -> dict[str, Any]:
    """Draw, record, update and predict every tester (see the module); the summary. The
    ``machinery`` set up before (:func:`setup`, of the same settings) is used, not set up again."""
    start = time.perf_counter()
    m = setup(settings, echo) if machinery is None else machinery
    setup_s = time.perf_counter() - start
    rows = []
    truth_s = 0.0
    for i in range(settings.testers):
        began = time.perf_counter()
        t = truth(m, settings, i)
        truth_s += time.perf_counter() - began
        rows.append(update_tester(m, settings, t) | {"true_paper_drift_mm": t["paper_drift_mm"]})
        r = rows[-1]
        echo(
            f"coverage: tester {i}: measured {t['measured_mm'] * 1e3:+.0f} um, R-hat max {r['r_hat_max']:.4f}, "
            + ", ".join(f"{k} {'in' if p['covered'] else 'OUT'}" for k, p in r["predictions"].items())
            + f", parameters {sum(p['covered'] for p in r['parameters'].values())}/{len(r['parameters'])}"
        )
    return {
        "settings": {
            "testers": settings.testers,
            "seed": settings.seed,
            "held_draws": settings.held,
            "fit_runs": settings.fit_runs,
            "check_runs": settings.check_runs,
            "sampler": dict(settings.sampler),
            "record": str(settings.record.relative_to(scenarios_dir().parent))
            if settings.record.is_relative_to(scenarios_dir().parent)
            else str(settings.record),
            "predicted": [
                {"name": p.name, "file": p.path.name, "set": list(p.overrides), "what": p.reading}
                for p in settings.predicted
            ],
            "level": LEVEL,
        },
        "rates": rates(rows, m.groups),
        "r_hat_max": float(max(r["r_hat_max"] for r in rows)),
        "emulators": m.checks,
        "discrepancy": {
            "names": m.held["names"],
            "sigma_mm": [float(s) for s in np.sqrt(np.diag(m.held["cov"]))],
            "correlation": (
                m.held["cov"] / np.outer(np.sqrt(np.diag(m.held["cov"])), np.sqrt(np.diag(m.held["cov"])))
            ).tolist(),
            "runs": m.held["runs"],
            # the held draws' mean drift against the nominal tester's (the emulators' base): the
            # update's delta is zero-mean, so this is what it leaves out
            "mean_minus_nominal_mm": [
                float(mean - m.emulators[n].base)
                for n, mean in zip(m.held["names"], m.held["mean"], strict=True)
            ],
        },
        "wall_s": {
            "setup": setup_s,
            "truth": truth_s,
            "sampler": float(sum(r["sampler_s"] for r in rows)),
            "total": time.perf_counter() - start,
        },
        "testers": rows,
    }
