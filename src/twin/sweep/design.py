"""The points of a sweep: the design matrix and each point's overrides and seed.

Everything is drawn on the client from the sweep's seed before any point runs, so a sweep is
the same whatever the number of workers or the order results come back in:

- the design's random numbers come from ``SeedSequence(seed, spawn_key=(0,))``;
- point ``i`` runs with ``scenario.seed`` from ``SeedSequence(seed, spawn_key=(1, i))``
  (unless the design varies ``scenario.seed`` itself, or ``vary_seed = false`` keeps the
  base scenario's seed for every point: common random numbers, the default of Saltelli and
  Morris designs, whose indices compare points and would otherwise measure seed noise).

Random, Latin hypercube and Sobol'-sequence designs draw points in the unit cube
(:mod:`scipy.stats.qmc`) and map them through SALib's own :func:`SALib.util.scale_samples`,
so ``bounds`` and ``dists`` mean exactly what they mean to SALib; the Saltelli and Morris
designs are SALib's samplers.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

import numpy as np

from twin import seeds
from twin.config.spec import SEED_KEY, Scenario
from twin.seeds import Key, scenario_seed
from twin.sweep.spec import Spec


def point_seed(sweep_seed: int, index: int) -> int:
    """The scenario seed of point ``index`` (in [0, 2^31), what a scenario accepts)."""
    return scenario_seed(sweep_seed, Key.POINT, index)


@dataclass(frozen=True)
class Design:
    """The design matrix (one row per point, in the spec's key order) and the point seeds."""

    names: list[str]
    rows: list[tuple[Any, ...]]
    seeds: list[int]

    def __len__(self) -> int:
        return len(self.rows)

    def values(self, index: int) -> dict[str, Any]:
        """What point ``index`` sets, by key (its seed last, unless the design varies it)."""
        out = dict(zip(self.names, self.rows[index], strict=True))
        if SEED_KEY not in self.names:
            out[SEED_KEY] = self.seeds[index]
        return out

    def point(self, base: Scenario, index: int) -> Scenario:
        """The scenario of point ``index``: ``base`` with its values set."""
        scenario = base
        for key, value in self.values(index).items():
            scenario = scenario.with_value(key, int(value) if key == SEED_KEY else value)
        return scenario


def _unit_samples(spec: Spec, rng: np.random.Generator) -> np.ndarray:
    from scipy.stats import qmc

    d, n = spec.problem["num_vars"], spec.samples
    if spec.design == "lhs":
        return qmc.LatinHypercube(d=d, rng=rng).random(n)
    if spec.design == "sobol-sequence":
        return qmc.Sobol(d=d, scramble=True, rng=rng).random(n)
    return rng.random((n, d))  # random, montecarlo


def matrix(spec: Spec) -> np.ndarray:
    """The design matrix of a sampled (not grid) design: points x keys."""
    from SALib.sample import morris
    from SALib.sample import sobol as saltelli
    from SALib.util import scale_samples

    problem = {k: list(v) if isinstance(v, list) else v for k, v in spec.problem.items()}
    sequence = seeds.sequence(spec.seed, Key.DESIGN)
    if spec.design == "saltelli":
        seed = int(sequence.generate_state(1)[0])
        return saltelli.sample(problem, spec.samples, calc_second_order=spec.second_order, seed=seed)
    if spec.design == "morris":
        seed = int(sequence.generate_state(1)[0])
        return morris.sample(problem, spec.samples, num_levels=spec.morris_levels, seed=seed)
    unit = _unit_samples(spec, np.random.default_rng(sequence))
    return scale_samples(unit, problem)


def make_design(spec: Spec) -> Design:
    """Every point of the sweep, in index order."""
    if spec.design == "grid":
        rows = list(itertools.product(*spec.levels))
    else:
        rows = [tuple(float(x) for x in row) for row in matrix(spec)]
    names = spec.names
    if SEED_KEY in names:
        seeds = [int(r[names.index(SEED_KEY)]) for r in rows]
    elif spec.vary_seed:
        seeds = [point_seed(spec.seed, i) for i in range(len(rows))]
    else:
        seeds = [spec.scenario.seed] * len(rows)
    return Design(names, rows, seeds)


def fingerprint(design: Design) -> str:
    """A hash of every point's values: a resumed sweep must be the very same design."""
    import hashlib

    h = hashlib.sha256()
    for i in range(len(design)):
        h.update(repr(sorted(design.values(i).items())).encode() + b"\n")
    return h.hexdigest()[:16]
