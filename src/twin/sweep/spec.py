"""A sweep file (TOML): a base scenario and a design over the values a study varies.

::

    [sweep]
    base = "../sine-load.toml"          # relative to this file
    design = "saltelli"                 # grid | random | montecarlo | lhs | sobol-sequence | saltelli | morris
    samples = 64                        # N (points: N, or N(D+2) saltelli, N(D+1) morris)
    seed = 7                            # design and per-point seeds derive from it
    set = ['scenario.duration = "1 h"'] # fixed overrides of the base (--set syntax, applied first)
    outputs = ["compensation.residual_rms_um.before"]   # summary figures kept (default: all)
    vary_seed = false                   # one seed for every point (default for saltelli, morris)
    priors = "../base/priors.toml"      # the prior file's spreads -> more rows ([spread] overrides them)

    [problem]                           # SALib's problem dict, one to one
    names = ["input.thermal.t_room.amplitude", "fmu.hydraulic.parameters.load_amplitude"]
    bounds = [[0.0, 3.0], [0.0, 50e3]]
    dists = ["unif", "unif"]            # unif logunif triang norm truncnorm lognorm (SALib's meaning)

    [spread]                            # spreads around the base scenario's values -> more [problem] rows
    "fmu.thermal.parameters.g_base_room" = { dist = "lognormal", sigma = 0.3 }

    [grid]                              # design = "grid": every combination of the levels
    "input.thermal.t_room.amplitude" = [0.0, 1.5, 3.0]

The design's keys are what :meth:`twin.config.spec.Scenario.with_value` sets: an FMU
parameter (``fmu.<instance>.parameters.<name>``), a parameter of an input's profile
(``input.<instance>.<variable>.<parameter>``) or ``scenario.seed``. Every problem is reported
at once, one line each, ``file: key: what`` (:class:`ConfigErrors`). Each key is set on the base
scenario at its distribution's centre and ends (every level, for a grid) before anything runs,
so an unknown key or a value no point could take is bad input, named by its key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.config.load import load_scenario
from twin.config.reader import Problems, read_toml, unsafe_name
from twin.config.spec import Scenario
from twin.errors import ConfigError, ConfigErrors
from twin.uncertainty.spreads import Row, centre, check_dist, ends, merge_rows, problem, spread_rows

__all__ = ["DESIGNS", "MAX_POINTS", "Spec", "load_spec", "point_count"]

DESIGNS = ("grid", "random", "montecarlo", "lhs", "sobol-sequence", "saltelli", "morris")
_SWEEP_KEYS = {
    "base",
    "name",
    "design",
    "samples",
    "seed",
    "set",
    "outputs",
    "main",
    "second_order",
    "levels",
    "vary_seed",
    "run_folders",
    "priors",
}
#: designs whose indices compare points: their points share the base's seed by default
_SENSITIVITY = ("saltelli", "morris")
_TOP_KEYS = {"sweep", "problem", "spread", "grid"}
_PROBLEM_KEYS = {"names", "bounds", "dists", "groups", "num_vars"}
#: designs whose sample size must be a power of two (a Sobol' sequence is balanced only then)
_POWER_OF_TWO = {"sobol-sequence", "saltelli"}
#: the most points a sweep may have: its design matrix and its results table are held in
#: memory, and a few lines (eight keys of twenty levels, a Saltelli design of 2^23 samples)
#: otherwise ask for 10^8 to 10^10 points and fill it before the first point runs. A million
#: points of the paper replay are about five hours on a two-core machine.
MAX_POINTS = 1_000_000


@dataclass(frozen=True)
class Spec:
    """A checked sweep file; ``scenario`` is its base scenario with the fixed overrides."""

    path: Path
    name: str
    scenario: Scenario
    design: str
    samples: int
    seed: int
    #: SALib's problem dict (``num_vars``, ``names``, ``bounds``, ``dists``, maybe ``groups``);
    #: for a grid ``names`` and ``num_vars`` only
    problem: Mapping[str, Any]
    levels: tuple[tuple[Any, ...], ...] = ()
    outputs: tuple[str, ...] = ()
    main: str | None = None
    second_order: bool = False
    morris_levels: int = 4
    vary_seed: bool = False
    run_folders: bool = False
    #: the fixed overrides (``set``) already applied to ``scenario``, as written
    fixed: tuple[str, ...] = ()

    @property
    def names(self) -> list[str]:
        """The design's keys, in column order."""
        return list(self.problem["names"])


def _sweep_table(p: Problems, raw: Mapping[str, Any], path: Path) -> dict[str, Any]:
    sw = p.table(raw, "sweep")
    p.unknown_keys(sw, _SWEEP_KEYS, "sweep.")
    design = sw.get("design")
    if design not in DESIGNS:
        p.add("sweep.design", f"expected one of: {', '.join(DESIGNS)}, got {design!r}")
    if not isinstance(sw.get("base"), str):
        p.add("sweep.base", "expected the base scenario's file name (relative to this file)")
    name = sw.get("name", path.stem)
    why = unsafe_name(name)
    if why is not None:  # the name becomes the sweep's folder: sweeps/<name>
        p.add("sweep.name", why)
        name = "sweep"
    samples = p.integer(sw, "samples", "sweep.", default=0 if design == "grid" else 1, lo=0, hi=10**7)
    if design != "grid" and samples == 0:
        p.add("sweep.samples", "empty design: at least one sample")
    if design in _POWER_OF_TWO and samples & (samples - 1):
        p.add("sweep.samples", f"{design} needs a power of two (its Sobol' sequence is balanced only then)")
    outputs = p.strings(sw, "outputs", "sweep.")
    main = sw.get("main")
    if main is not None and (not isinstance(main, str) or (outputs and main not in outputs)):
        p.add("sweep.main", "expected one of the outputs" if outputs else "expected an output name")
    return {
        "name": name,
        "design": design,
        "samples": samples,
        "seed": p.integer(sw, "seed", "sweep.", default=0, lo=0, hi=2**32 - 1),
        "fixed": p.strings(sw, "set", "sweep."),
        "outputs": outputs,
        "main": main,
        "second_order": p.boolean(sw, "second_order", "sweep.", default=False),
        "morris_levels": p.integer(sw, "levels", "sweep.", default=4, lo=2, hi=100),
        # a sensitivity design compares points that differ in one key: a seed of their own
        # would add its noise to every difference (common random numbers, unless asked)
        "vary_seed": p.boolean(sw, "vary_seed", "sweep.", default=design not in _SENSITIVITY),
        "run_folders": p.boolean(sw, "run_folders", "sweep.", default=False),
    }


def _problem_rows(p: Problems, raw: Mapping[str, Any]) -> list[Row]:
    """(name, dist, bounds) of the ``[problem]`` table, SALib's meaning."""
    p.unknown_keys(raw, _PROBLEM_KEYS, "problem.")
    names = p.strings(raw, "names", "problem.")
    bounds = raw.get("bounds", [])
    dists = raw.get("dists", ["unif"] * len(names))
    if not isinstance(bounds, list) or len(bounds) != len(names):
        p.add("problem.bounds", f"expected one entry per name ({len(names)})")
        return []
    if not isinstance(dists, list) or len(dists) != len(names):
        p.add("problem.dists", f"expected one entry per name ({len(names)})")
        return []
    if "num_vars" in raw and raw["num_vars"] != len(names):
        p.add("problem.num_vars", f"is {raw['num_vars']!r} but {len(names)} names are given")
    rows = []
    for i, (name, dist, b) in enumerate(zip(names, dists, bounds, strict=True)):
        why = check_dist(dist, b)
        if why:
            p.add(f"problem.bounds[{i}] ({name})", why)
        else:
            rows.append((name, dist, [float(x) for x in b]))
    return rows


def _grid(p: Problems, raw: Mapping[str, Any]) -> tuple[list[str], tuple[tuple[Any, ...], ...]]:
    names, levels = [], []
    for key, values in raw.items():
        where = f'grid."{key}"'
        scalar = isinstance(values, list) and all(isinstance(v, int | float | str | bool) for v in values)
        if not scalar or not values:
            p.add(where, "empty design: expected a non-empty list of values" if scalar else "expected a list")
            continue
        kinds = {
            "number" if isinstance(v, int | float) and not isinstance(v, bool) else type(v) for v in values
        }
        if len(kinds) > 1:
            p.add(where, "levels must be all numbers, all strings or all booleans")
            continue
        if any(isinstance(v, float) and not math.isfinite(v) for v in values):
            p.add(where, "levels must be finite")
            continue
        names.append(key)
        levels.append(tuple(values))
    if not names and not p.items:
        p.add("grid", "empty design: no key to vary")
    return names, tuple(levels)


def _rows(p: Problems, raw: Mapping[str, Any], scenario: Scenario, path: Path) -> list[Row]:
    rows = _problem_rows(p, p.table(raw, "problem")) if "problem" in raw else []
    own = (
        spread_rows(p, p.table(raw, "spread"), scenario)
        if "spread" in raw or "priors" not in raw["sweep"]
        else []
    )
    rows += merge_rows(_prior_rows(p, raw["sweep"].get("priors"), scenario, path), own)
    names = [r[0] for r in rows]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        p.add("problem.names", f"{dupes[0]!r} is varied twice")
    if not rows and not p.items:
        p.add("problem", "empty design: no [problem] names and no [spread]")
    return rows


def _prior_rows(p: Problems, priors: Any, scenario: Scenario, path: Path) -> list[Row]:
    """The prior file's rows (``[sweep] priors``, relative to the sweep file) around the base
    scenario: a sweep over the testers as built draws what ``twin run``'s Monte Carlo draws."""
    from twin.uncertainty.testers import load_testers

    if priors is None:
        return []
    file = (path.resolve().parent / str(priors)).resolve()
    if not isinstance(priors, str) or not file.is_file():
        p.add("sweep.priors", f"expected the prior file's name (relative to this file), no such file {file}")
        return []
    return load_testers(file, scenario)


def _groups(p: Problems, raw: Mapping[str, Any], n: int) -> list[str] | None:
    groups = raw.get("problem", {}).get("groups") if isinstance(raw.get("problem"), dict) else None
    if groups is None:
        return None
    if not isinstance(groups, list) or len(groups) != n or not all(isinstance(g, str) for g in groups):
        p.add("problem.groups", f"expected one group name per varied key ({n})")
        return None
    return groups


def _check_keys(
    p: Problems, scenario: Scenario, names: Sequence[str], values: Sequence[Sequence[Any]]
) -> None:
    """Set each design key on the base scenario at each of ``values`` (the others at their
    first): an unknown key, or a value no point could take, is a problem named by its key."""
    for i, name in enumerate(names):
        point = scenario
        try:
            for j, other in enumerate(names):
                if j != i:
                    point = point.with_value(other, values[j][0])
            for v in values[i]:
                point.with_value(name, v)
        except ConfigError as exc:
            p.add(name, exc.message or str(exc))


def point_count(
    design: str, samples: int, problem: Mapping[str, Any], levels: Sequence[Sequence[Any]], second_order: bool
) -> int:
    """How many points a design has, without making it (SALib's sizes: Saltelli N (k + 2), or
    N (2k + 2) with second-order indices, Morris N (k + 1) trajectories' points, with k the
    groups where there are groups, else the keys)."""
    if design == "grid":
        return math.prod(len(lv) for lv in levels)
    k = len(set(problem["groups"])) if problem.get("groups") else int(problem["num_vars"])
    if design == "saltelli":
        return samples * (2 * k + 2 if second_order else k + 2)
    if design == "morris":
        return samples * (k + 1)
    return samples


def _base(path: Path, raw: Mapping[str, Any], fixed: Sequence[str], base: Scenario | None) -> Scenario:
    """The base scenario (the file ``sweep.base`` names, relative to the sweep file) with the
    fixed overrides, or ``base`` when given."""
    if base is not None:
        return base
    base_path = (path.resolve().parent / raw["sweep"]["base"]).resolve()
    try:
        scenario = load_scenario(base_path)
    except ConfigError as exc:
        if exc.source != str(base_path) or exc.key is not None:
            raise
        # the base itself cannot be read (missing, a directory, a device): say so where it is named
        raise ConfigError(
            f"{raw['sweep']['base']}: {exc.message}", source=str(path), key="sweep.base"
        ) from None
    if not fixed:
        return scenario
    try:
        return load_scenario(base_path, fixed)
    except ConfigErrors as exc:  # the base loads alone: each problem is the set's
        raise ConfigErrors([_in_set(e, path) for e in exc.problems]) from None
    except ConfigError as exc:
        raise _in_set(exc, path) from None


def _in_set(exc: ConfigError, path: Path) -> ConfigError:
    """A problem of the base scenario with the sweep's ``set`` applied (the base alone has
    none): named where the override is written, ``sweep.set``."""
    what = f"{exc.key}: {exc.message}" if exc.key else exc.message
    return ConfigError(what, source=str(path), key="sweep.set")


def load_spec(path: str | Path, base: Scenario | None = None) -> Spec:
    """Read and check a sweep file; ``base`` replaces its ``sweep.base`` (the spreads of a
    tester as built, around another scenario's values). Raises :class:`ConfigError` /
    :class:`ConfigErrors` with every problem."""
    path = Path(path)
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP_KEYS, "")
    sw = _sweep_table(p, raw, path)
    p.check()
    sw["fixed"] = tuple(sw["fixed"])
    scenario = _base(path, raw, sw["fixed"], base)
    if sw["design"] == "grid":
        p.unknown_keys(raw, {"sweep", "grid"}, "")
        names, levels = _grid(p, p.table(raw, "grid"))
        prob: dict[str, Any] = {"num_vars": len(names), "names": names}
        values: list[list[Any]] = [list(lv) for lv in levels]
    else:
        if "grid" in raw:
            p.add("grid", f"only design = 'grid' takes a [grid] table (this is {sw['design']!r})")
        rows = _rows(p, raw, scenario, path)
        levels = ()
        prob = problem(rows, _groups(p, raw, len(rows)))
        values = [[centre(r[1], r[2]), *ends(r[1], r[2])] for r in rows]
    p.check()
    points = point_count(sw["design"], sw["samples"], prob, levels, sw["second_order"])
    if points > MAX_POINTS:
        p.add(
            "grid" if sw["design"] == "grid" else "sweep.samples",
            f"{points} points, more than the {MAX_POINTS} a sweep may have: split it, or take fewer "
            + ("levels" if sw["design"] == "grid" else "samples"),
        )
        p.check()
    _check_keys(p, scenario, prob["names"], values)
    p.check()
    return Spec(path=path, scenario=scenario, problem=prob, levels=levels, **sw)
