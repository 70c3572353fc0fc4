"""An emulator of the twin's probe drift over the tester-as-built parameters, derived from
twin runs and verified against them (for ``twin update``, whose sampler needs ~1e5 forward
evaluations where a twin run takes ~0.1 s).

Why it can be exact: in a thermal-only replay nothing mechanical feeds back into the thermal
network, so at a fixed thermal network and room the node temperatures are fixed, and each
part's growth is its length times its expansion coefficient times its rise factor times its
node's rise. The drift is then a sum over the lengths of ``c_j x alpha_p(j) x f_p(j) x L_j``
(relative to the nominal values) plus terms linear in the probe's own drifts. Nothing of that
is copied from the FMUs' C code: the structure is a hypothesis stated in the prior file's
groups (``lengths`` carry, ``alphas`` and ``point-vs-mean`` multiply, the rest adds), and
:func:`derive` reads every coefficient and every length's partners off twin runs:

- the nominal run, then each parameter moved by +-2 prior sigma: its slope within the prior;
  a length whose effect is below 5 nm there acts alone (its line through that step), the
  others are doubled for their coefficient (a large, clean signal);
- two pattern runs per multiplier group (each multiplier scaled by its own factor 1.1 ... 2.0)
  with each length moved again: the ratio of a length's effect under the pattern names its one
  partner in the group; a ratio that matches no factor refuses the hypothesis (RunError);
- a multiplier's own main effect must equal the sum of its lengths' (else something else
  grows with it: refused).

:func:`verify` then runs the full twin at random prior draws and reports the largest
difference: the emulator is only used with that figure beside it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from twin.config.spec import Scenario
from twin.errors import RunError

__all__ = ["Emulator", "derive", "twin_drift", "verify"]

#: a length whose effect over its prior scale is below this (mm) has no partner worth finding:
#: it acts alone (a seat radius known to microns moves the drift by 1e-4 um)
_TINY_MM = 5e-6
#: the pattern factors must be matched within this (relative): quantisation of the probe's
#: reading moves a ratio by far less
_MATCH = 0.02


@dataclass(frozen=True)
class Emulator:
    """The drift (mm) as ``base + sum_t c_t (prod_i x_i - prod_i x0_i)``, with ``x_i`` a
    parameter over its step (the nominal value, or a prior sigma where the nominal is 0)."""

    names: tuple[str, ...]
    nominal: np.ndarray
    step: np.ndarray
    base: float
    terms: tuple[tuple[float, tuple[int, ...]], ...]

    def drift(self, theta: np.ndarray) -> np.ndarray:
        """The drift (mm) at each row of ``theta`` (parameters in :attr:`names` order)."""
        x = np.atleast_2d(theta) / self.step
        x0 = self.nominal / self.step
        out = np.full(x.shape[0], self.base)
        for c, idx in self.terms:
            out += c * (np.prod(x[:, idx], axis=1) - np.prod(x0[list(idx)]))
        return out

    def describe(self) -> list[dict[str, object]]:
        """The terms by name (for summary.json): what each coefficient multiplies."""
        return [{"mm_at_nominal": c, "product_of": [self.names[i] for i in idx]} for c, idx in self.terms]


def twin_drift(scenario: Scenario) -> Callable[..., float]:
    """The twin's probe drift (mm, ``drift_mm.probe``) of ``scenario`` with some values
    changed (or of another scenario of the same FMUs, ``other``): a full run of its FMUs in
    process, the instances pooled."""
    from twin.errormodel.config import evaluation_config
    from twin.fmu.pool import SlotPool
    from twin.pipeline.prepare import prepare_scenario
    from twin.pipeline.stages import run_point
    from twin.uncertainty.testers import apply

    # the drift is all a forward run reports: the credibility indexes (their Frechet recursion
    # is half of an evaluation) would be computed and dropped in each of the update's runs
    evaluation = dataclasses.replace(evaluation_config(scenario), credibility=False)
    pool = SlotPool()

    def run(values: Mapping[str, float], other: Scenario | None = None) -> float:
        changed = apply(scenario if other is None else other, values)
        summary = run_point(prepare_scenario(changed, evaluation), pool=pool)
        if summary.status != "completed":
            raise RunError(f"a forward run of the update failed: {summary.error}")
        return float(summary.figures()["drift_mm.probe"])

    return run


def derive(
    run: Callable[[Mapping[str, float]], float],
    nominal: Mapping[str, float],
    scales: Mapping[str, float],
    roles: Mapping[str, str],
) -> Emulator:
    """The emulator of ``run`` around ``nominal``; ``scales`` gives each parameter's prior
    scale (one sigma), ``roles`` maps it to ``carrier``, a multiplier group's name, or
    ``additive`` (see the module)."""
    names = tuple(nominal)
    index = {n: i for i, n in enumerate(names)}
    step = np.array([abs(nominal[n]) or scales[n] for n in names], dtype=float)
    base = run({})
    # each parameter's slope over +-2 prior sigma (central: the reading's 0.1 um quantisation
    # jitters a drift by ~0.02 um, which a one-sigma step of a small effect does not beat),
    # per step: which carriers matter within the prior, and the line of those acting alone
    local = {n: _slope(run, n, nominal[n], 2.0 * scales[n]) * step[index[n]] for n in names}
    doubled = {n: nominal[n] + step[index[n]] for n in names}
    carriers = [
        n for n in names if roles[n] == "carrier" and abs(local[n]) * scales[n] / step[index[n]] > _TINY_MM
    ]
    effect = {n: run({n: doubled[n]}) - base for n in carriers}
    groups = sorted({r for r in roles.values() if r not in ("carrier", "additive")})
    partners: dict[str, list[str]] = {n: [] for n in carriers}
    for group in groups:
        members = [n for n in names if roles[n] == group]
        for carrier, partner in _partners(run, (nominal, doubled), carriers, members).items():
            partners[carrier].append(partner)
        linked = [m for m in members if any(m in ps for ps in partners.values())]
        _check_sums({m: run({m: doubled[m]}) - base for m in linked} | effect, partners, linked)
    terms = [(effect[n], tuple(sorted(index[m] for m in (n, *partners[n])))) for n in carriers]
    linked_all = {m for ps in partners.values() for m in ps} | set(carriers)
    # the rest act alone within the prior (a probe drift, a seat radius known to microns):
    # a straight line through the prior-scale step
    terms += [(local[n], (index[n],)) for n in names if n not in linked_all and local[n] != 0.0]
    return Emulator(names, np.array([nominal[n] for n in names], dtype=float), step, base, tuple(terms))


def _slope(run: Callable[[Mapping[str, float]], float], name: str, value: float, h: float) -> float:
    """The drift's central-difference slope in ``name`` at ``value`` (mm per unit)."""
    return (run({name: value + h}) - run({name: value - h})) / (2.0 * h)


def _partners(
    run: Callable[[Mapping[str, float]], float],
    points: tuple[Mapping[str, float], Mapping[str, float]],
    carriers: Sequence[str],
    members: Sequence[str],
) -> dict[str, str]:
    """Each carrier's one partner among ``members``: the member whose pattern factor its
    effect grows by when every member is scaled by its own factor."""
    nominal, moved = points
    factors = {m: 1.0 + 0.1 * (k + 1) for k, m in enumerate(members)}
    pattern = {m: nominal[m] * f for m, f in factors.items()}
    base = run(pattern)
    out = {}
    for n in carriers:
        plain = run({n: moved[n]}) - run({})
        ratio = (run(pattern | {n: moved[n]}) - base) / plain
        best = min(factors, key=lambda m: abs(factors[m] - ratio))
        if abs(factors[best] - ratio) > _MATCH * factors[best]:
            raise RunError(
                f"the drift is not multilinear as the emulator assumes: {n}'s effect grows by "
                f"{ratio:.4f} under the pattern, no single partner's factor"
            )
        out[n] = best
    return out


def _check_sums(
    effect: Mapping[str, float], partners: Mapping[str, list[str]], members: Sequence[str]
) -> None:
    """A multiplier's main effect is the sum of its carriers' (nothing else grows with it)."""
    for m in members:
        carried = sum(effect[n] for n, ps in partners.items() if m in ps)
        if abs(effect[m] - carried) > max(1e-5, 0.02 * abs(effect[m])):
            raise RunError(
                f"the drift is not multilinear as the emulator assumes: {m} moves it by "
                f"{effect[m]:+.6f} mm, its lengths by {carried:+.6f} mm"
            )


def verify(
    emulator: Emulator,
    run: Callable[[Mapping[str, float]], float],
    draws: np.ndarray,
) -> dict[str, float]:
    """The emulator against full twin runs at ``draws`` (rows of parameters): the largest and
    the RMS difference, um."""
    diffs = []
    for row in draws:
        values = {n: float(v) for n, v in zip(emulator.names, row, strict=True)}
        diffs.append(emulator.drift(row[None, :])[0] - run(values))
    d = np.abs(np.array(diffs)) * 1e3
    return {"runs": len(d), "max_um": float(d.max()), "rms_um": float(np.sqrt(np.mean(d**2)))}
