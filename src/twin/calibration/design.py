"""The next experiment: the one that best separates the update's leading explanations of the
record, with its predicted outcome (issue 31, point 3).

A drift record pins the sum of what moves the probe, not each part: after the update the
explanations of the record trade off against each other (a probe that drifts more, a base inset
that grows less, ...). This module says which ones, and which experiment a lab can run tells
them apart:

1. **Explanations.** Each term of the update's emulator (:mod:`twin.calibration.emulator`) is a
   contribution to the drift; the terms of one part (its expansion coefficient) are one
   explanation, "<part> growth", the probe's zero and span drift another, "probe drift". The
   leading explanations are those with the largest posterior spread of their contribution, up
   to 90 % of the summed variance (2 to 4 of them): their posterior means, spreads and
   correlations (negative where the record trades them off).
2. **Candidates.** The shipped calibration experiments whose reading depends on them
   (:data:`CANDIDATES`: scenarios/calibration/*.toml, each read as a lab reads it: the probe's
   mean over two windows of the scenario's own profile). Each candidate's outcome is linear
   in the sampled parameters around their posterior mean, from full twin runs (a step of one
   posterior sd in each parameter); its noise is the record's reading noise and the
   outcome's spread over the inputs the update holds (the thermal network, the room's slow
   drift, the sensors' noise: twin runs, as the update's discrepancy scale is the drift's).
3. **Criterion.** The expected information the outcome gives about the leading explanations'
   contributions: the mutual information of a linear-Gaussian model, ``0.5 log(var(y) /
   var(y | c))`` (nats), from posterior draws of the outcome ``y`` (the linear model plus the
   noise) and the contributions ``c`` (the emulator). An experiment that reads the same sum the
   record read learns little: the record already pinned it. Beside it the information about
   every sampled parameter, ``0.5 log(1 + var(J theta) / noise^2)``.
4. **What the result tells.** The named experiment's outcome under the posterior (median and
   90 % interval of those draws) and under each leading explanation alone: the tester that
   carries all of the leading explanations' posterior shift from their prior in that one
   explanation, the others at their prior means, the rest at the posterior mean (the least
   move from the posterior mean in prior sigmas, through the emulator), run in full.

Nothing here is chosen knowing the measured drift beyond what the posterior carries.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin.calibration.emulator import Emulator
from twin.config.spec import Scenario
from twin.errors import RunError
from twin.seeds import Key, generator

__all__ = [
    "CANDIDATES",
    "Candidate",
    "Explanation",
    "contributions",
    "explanations",
    "information",
    "next_experiment",
    "outcome_run",
    "rank",
]

#: posterior draws the criterion and the prediction use (their 90 % interval's ends to ~0.05 sd)
DRAWS = 4000
#: the leading explanations carry this much of the summed posterior variance of all of them
COVER = 0.9
LEAST, MOST = 2, 4


@dataclass(frozen=True)
class Candidate:
    """An experiment a lab can run: a shipped calibration scenario and what is read of it,
    the probe's mean over ``after_h`` minus its mean over ``before_h`` (hours)."""

    key: str
    name: str
    reads: str
    before_h: tuple[float, float]
    after_h: tuple[float, float]
    source: str


#: the calibration experiments whose probe reading moves with the sampled parameters; the
#: mechanical ones (gauge blocks, load steps, runout, light oscillation, load hold) run with the
#: room held for minutes or under a held room, so nothing the update samples moves their reading
CANDIDATES = (
    Candidate(
        "probe-heating",
        "probe-heating bench",
        "the probe at 5 mm, its body +10 K minus cold",
        (0.40, 0.50),
        (3.55, 3.65),
        "scenarios/calibration/probe-heating.toml: tip at 5 mm 0.336-0.667 h and 3.336-3.667 h, body at 20 degC until 0.5 h and +10 K from 2.5 h",
    ),
    Candidate(
        "pole-heating",
        "pole heating",
        "the probe at the heater's end minus before it",
        (0.40, 0.50),
        (4.40, 4.50),
        "scenarios/calibration/pole-heating.toml: heater tape on at 0.51 h, off at 4.5 h",
    ),
    Candidate(
        "thermal-soak",
        "thermal soak",
        "the probe at the warm hold's end minus before the room's ramp",
        (0.90, 1.00),
        (9.90, 10.00),
        "scenarios/calibration/thermal-soak.toml: room 20 degC until 1 h, 25 degC 4-10 h",
    ),
    Candidate(
        "hot-cooldown",
        "hot cool-down",
        "the probe over the cool-down (drive stopped, nothing wears)",
        (1.05, 1.15),
        (4.90, 5.00),
        "scenarios/calibration/hot-cooldown.toml: the drive stops at 1 h, the log ends at 5 h",
    ),
)


@dataclass(frozen=True)
class Explanation:
    """One explanation of the drift: a set of the emulator's terms (indexes)."""

    label: str
    terms: tuple[int, ...]


def explanations(emulator: Emulator, roles: Mapping[str, str]) -> list[Explanation]:
    """The emulator's terms grouped by part (the expansion coefficient among their factors),
    the probe's own drift terms as one; a length acting alone is its own."""
    groups: dict[str, list[int]] = {}
    for t, (_, idx) in enumerate(emulator.terms):
        members = [emulator.names[i] for i in idx]
        alphas = [m for m in members if roles.get(m) == "alphas"]
        if alphas:
            label = alphas[0].split(".")[-1].removeprefix("alpha_").replace("_", " ") + " growth"
        elif all(roles.get(m) == "additive" for m in members):
            label = "probe drift"
        else:
            label = members[0].split(".")[-1].replace("_", " ")
        groups.setdefault(label, []).append(t)
    return [Explanation(k, tuple(v)) for k, v in groups.items()]


def contributions(emulator: Emulator, theta: np.ndarray, found: Sequence[Explanation]) -> np.ndarray:
    """Each explanation's contribution to the drift (mm, relative to the nominal tester) at
    each row of ``theta`` (parameters in the emulator's order): rows x explanations."""
    x = np.atleast_2d(theta) / emulator.step
    x0 = emulator.nominal / emulator.step
    out = np.zeros((x.shape[0], len(found)))
    for k, e in enumerate(found):
        for t in e.terms:
            c, idx = emulator.terms[t]
            out[:, k] += c * (np.prod(x[:, idx], axis=1) - np.prod(x0[list(idx)]))
    return out


def information(y: np.ndarray, c: np.ndarray) -> float:
    """The mutual information (nats) of a scalar outcome ``y`` and the contributions ``c``
    (rows: draws) of a Gaussian with their sample covariance: ``0.5 log(var(y) / var(y | c))``."""
    cov = np.cov(np.column_stack([y, c]), rowvar=False)
    syy, syc, scc = cov[0, 0], cov[0, 1:], cov[1:, 1:]
    rest = syy - syc @ np.linalg.pinv(scc) @ syc
    return float(0.5 * np.log(syy / max(rest, syy * 1e-12)))


def outcome_run(scenario: Scenario, candidate: Candidate) -> Callable[[Mapping[str, float]], float]:
    """The candidate's outcome (mm) for a tester of some values (of ``scenario``, or of a
    draw of it, ``other``): a full run of its FMUs in process, the instances pooled, the
    probe's reading kept alone."""
    from twin.errormodel.config import evaluation_config
    from twin.fmu.pool import SlotPool
    from twin.pipeline.prepare import prepare_scenario
    from twin.pipeline.stages import simulate
    from twin.uncertainty.testers import apply

    daq = next(f.name for f in scenario.fmus if f.model == "SensorsDAQ")
    column = f"{daq}.probe_meas"
    evaluation = dataclasses.replace(evaluation_config(scenario), credibility=False)
    pool = SlotPool()

    def run(values: Mapping[str, float], other: Scenario | None = None) -> float:
        prepared = prepare_scenario(apply(scenario if other is None else other, values), evaluation)
        sim = simulate(prepared, keep={column}, pool=pool)
        if sim.result.status != "completed":
            raise RunError(f"a run of the {candidate.name} failed: {sim.result.error}")
        hours = sim.table.time / 3600.0
        probe = sim.table[column]

        def mean(window: tuple[float, float]) -> float:
            inside = (hours >= window[0]) & (hours <= window[1])
            return float(np.mean(probe[inside]))

        return (mean(candidate.after_h) - mean(candidate.before_h)) * 1e3

    return run


# ----------------------------------------------------------------------------- the posterior


@dataclass(frozen=True)
class Posterior:
    """The update's posterior as the design reads it: draws of the standard normal
    coordinates ``u`` and of the parameters ``theta`` (the emulator's order), the leading
    explanations and their contributions at those draws."""

    u: np.ndarray
    theta: np.ndarray
    leading: tuple[Explanation, ...]
    contrib: np.ndarray
    prior_contrib: np.ndarray


def read_posterior(
    prior: Any, emulator: Emulator, chains: np.ndarray, roles: Mapping[str, str], seed: int
) -> Posterior:
    """:class:`Posterior` from the update's chains (walkers, steps, coordinates + delta)."""
    flat = chains.reshape(-1, chains.shape[-1])[:, :-1]
    keep = np.linspace(0, flat.shape[0] - 1, min(DRAWS, flat.shape[0])).astype(int)
    u = flat[keep]
    theta = _theta(prior, emulator, u)
    found = explanations(emulator, roles)
    post = contributions(emulator, theta, found)
    pri_u = generator(seed, Key.UPDATE, 3).standard_normal((DRAWS, u.shape[1]))
    pri = contributions(emulator, _theta(prior, emulator, pri_u), found)
    var = np.var(post, axis=0)
    order = np.argsort(-var, kind="stable")
    share = np.cumsum(var[order]) / var.sum()
    n = int(np.clip(np.searchsorted(share, COVER) + 1, LEAST, MOST))
    lead = order[:n]
    return Posterior(u, theta, tuple(found[i] for i in lead), post[:, lead], pri[:, lead])


def _theta(prior: Any, emulator: Emulator, u: np.ndarray) -> np.ndarray:
    """Parameters in the emulator's order from the prior's standard normal coordinates."""
    order = [emulator.names.index(n) for n in prior.names]
    theta = np.empty((u.shape[0], len(emulator.names)))
    theta[:, order] = prior.theta(u)
    return theta


def alone(prior: Any, emulator: Emulator, post: Posterior, k: int) -> np.ndarray:
    """The parameters (emulator's order) of the tester where leading explanation ``k`` alone
    carries the leading explanations' summed posterior shift from their prior means, the other
    leading ones at their prior means: the least move from the posterior mean in standard
    normal coordinates (Gauss-Newton through the emulator)."""
    target = post.prior_contrib.mean(axis=0)
    target[k] += float(np.sum(post.contrib.mean(axis=0) - post.prior_contrib.mean(axis=0)))

    def c_of(u: np.ndarray) -> np.ndarray:
        return contributions(emulator, _theta(prior, emulator, u), post.leading)

    u = post.u.mean(axis=0)
    for _ in range(8):
        r = target - c_of(u[None, :])[0]
        if np.max(np.abs(r)) < 1e-7:
            break
        h = 1e-4
        moved = u[None, :] + h * np.eye(u.size)
        a = ((c_of(moved) - c_of(u[None, :])) / h).T
        u = u + np.linalg.pinv(a) @ r  # the least move that meets the target (minimum norm)
    return _theta(prior, emulator, u[None, :])[0]


# ----------------------------------------------------------------------------- the design


def next_experiment(
    record: Any, prior: Any, emulator: Emulator, chains: np.ndarray, roles: Mapping[str, str]
) -> dict[str, Any]:
    """summary.json's ``next_experiment``: the leading explanations, every candidate scored,
    and the best one's predicted outcome (see the module)."""
    from twin.config.load import load_scenario, scenarios_dir

    post = read_posterior(prior, emulator, chains, roles, record.seed)
    mean_theta = post.theta.mean(axis=0)
    hypotheses = {e.label: alone(prior, emulator, post, k) for k, e in enumerate(post.leading)}
    rng = generator(record.seed, Key.UPDATE, 4)
    entries, draws = {}, {}
    for cand in CANDIDATES:
        scenario = load_scenario(scenarios_dir() / "calibration" / f"{cand.key}.toml")
        run = outcome_run(scenario, cand)
        held = held_spread(record, scenario, run, _values(emulator.names, mean_theta))
        sigma = float(np.hypot(record.sigma_mm, held))
        entry, draws[cand.name] = score(cand, run, (emulator.names, mean_theta), post, (sigma, rng))
        entry["if_alone_mm"] = {k: run(_values(emulator.names, v)) for k, v in hypotheses.items()}
        entry["held_spread_mm"] = held
        entries[cand.name] = entry
    ranked = [entries[name] | {"information_nats": info} for name, info in rank(draws, post.contrib)]
    best = ranked[0]
    leading = _leading(post)
    best["separates"] = separated(best["if_alone_mm"], {e["label"]: e["correlation"] for e in leading})
    return {
        "criterion": "mutual information of the outcome and the leading explanations' contributions (linear-Gaussian, nats)",
        "leading_explanations": leading,
        "name": best["name"],
        "best": best,
        "ranking": [{k: r[k] for k in ("name", "information_nats", "information_all_nats")} for r in ranked],
        "candidates": ranked,
    }


def held_spread(
    record: Any, scenario: Scenario, run: Callable[..., float], values: Mapping[str, float]
) -> float:
    """The outcome's spread (mm) over what the update holds, as the update's discrepancy
    scale is the drift's (:func:`twin.calibration.update.held_spread`): ``held_samples``
    draws of the prior file's other inputs (the thermal network, the room's slow drift, the
    sensors' noise), the sampled parameters at ``values``. 0 for a bench without the tester's
    thermal network (the probe-heating bench holds its room and fixture)."""
    from twin.pipeline.montecarlo import Uncertainty, sampler
    from twin.uncertainty.testers import load_room

    if not any(f.model == "ThermalNetwork" for f in scenario.fmus):
        return 0.0
    room = load_room(record.prior)
    unc = Uncertainty(
        record.held_samples, record.seed, record.prior, "input.thermal.t_room", room.shapes, room.drift_K
    )
    _, make = sampler(unc, scenario)
    outcomes = [run(values, make(i).scenario) for i in range(record.held_samples)]
    return float(np.std(outcomes, ddof=1))


def rank(draws: Mapping[str, np.ndarray], contrib: np.ndarray) -> list[tuple[str, float]]:
    """The candidates by the information their outcome's draws (noise included) give about
    the contributions ``contrib`` drawn with them, most first."""
    scored = [(name, information(y, contrib)) for name, y in draws.items()]
    return sorted(scored, key=lambda kv: -kv[1])


def _values(names: Sequence[str], theta: np.ndarray) -> dict[str, float]:
    return {n: float(v) for n, v in zip(names, theta, strict=True)}


def score(
    cand: Candidate,
    run: Callable[[Mapping[str, float]], float],
    at: tuple[Sequence[str], np.ndarray],
    post: Posterior,
    noise: tuple[float, np.random.Generator],
) -> tuple[dict[str, Any], np.ndarray]:
    """One candidate: its outcome's linear model around the posterior mean (full runs) and
    its predictive draws (one per posterior draw, the noise added)."""
    names, centre = at
    sigma, rng = noise
    base = run(_values(names, centre))
    sd = post.theta.std(axis=0)
    slope = np.zeros(len(names))
    # one step each: the drift is multilinear (twin.calibration.emulator), so a line through
    # one parameter's step is exact and a central difference would only double the runs
    for i in np.flatnonzero(sd > 0):
        up = centre.copy()
        up[i] += sd[i]
        slope[i] = (run(_values(names, up)) - base) / sd[i]
    model = base + (post.theta - centre) @ slope
    y = model + sigma * rng.standard_normal(model.size)
    lo, med, hi = np.percentile(y, [5, 50, 95])
    entry = {
        "name": cand.name,
        "scenario": f"scenarios/calibration/{cand.key}.toml",
        "reads": cand.reads,
        "windows_h": {"before": list(cand.before_h), "after": list(cand.after_h)},
        "source": cand.source,
        "at_posterior_mean_mm": base,
        "predicted_mm": {
            "median": float(med),
            "interval_90": [float(lo), float(hi)],
            "sd_twin": float(np.std(model)),
        },
        "noise_mm": sigma,
        "information_all_nats": float(0.5 * np.log1p(np.var(model) / sigma**2)),
        "slope_mm_per_unit": {n: float(s) for n, s in zip(names, slope, strict=True) if s},
    }
    return entry, y


def separated(if_alone: Mapping[str, float], correlation: Mapping[str, Mapping[str, float]]) -> list[str]:
    """The two explanations the outcome reads apart: of the pairs whose outcomes alone lie
    within 10 % of the farthest apart, the one the record trades off most (the most negative
    posterior correlation of their contributions); in the leading explanations' order."""
    labels = list(if_alone)
    pairs = [(a, b) for i, a in enumerate(labels) for b in labels[i + 1 :]]
    gap = {p: abs(if_alone[p[0]] - if_alone[p[1]]) for p in pairs}
    far = [p for p in pairs if gap[p] >= 0.9 * max(gap.values())]
    return list(min(far, key=lambda p: correlation[p[0]][p[1]]))


def _leading(post: Posterior) -> list[dict[str, Any]]:
    corr = np.corrcoef(post.contrib, rowvar=False)
    out = []
    for k, e in enumerate(post.leading):
        c = post.contrib[:, k]
        lo, hi = np.percentile(c, [5, 95])
        out.append(
            {
                "label": e.label,
                "prior_mean_mm": float(post.prior_contrib[:, k].mean()),
                "posterior_mean_mm": float(c.mean()),
                "posterior_sd_mm": float(c.std(ddof=1)),
                "interval_90_mm": [float(lo), float(hi)],
                "correlation": {o.label: float(corr[k, j]) for j, o in enumerate(post.leading) if j != k},
            }
        )
    return out


def report_line(found: Mapping[str, Any]) -> str:
    """The terminal's line: the experiment, what it separates, its predicted outcome."""
    best = found["best"]
    p = best["predicted_mm"]
    a, b = best["separates"]
    alone_text = "; ".join(f"if {k}: {best['if_alone_mm'][k] * 1e3:+.1f} um" for k in (a, b))
    return (
        f"next experiment: {best['name']} (separates {a} from {b}; {best['reads']}): predicted "
        f"{p['median'] * 1e3:+.1f} um, 90 % [{p['interval_90'][0] * 1e3:+.1f}, {p['interval_90'][1] * 1e3:+.1f}] um "
        f"({alone_text})"
    )
