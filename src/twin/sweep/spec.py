"""A sweep file (TOML): a base scenario and a design over keys that ``--set`` accepts.

::

    [sweep]
    base = "../sine-load.toml"          # relative to this file
    design = "saltelli"                 # grid | random | montecarlo | lhs | sobol-sequence | saltelli | morris
    samples = 64                        # N (points: N, or N(D+2) saltelli, N(D+1) morris)
    seed = 7                            # design and per-point seeds derive from it
    set = ['scenario.duration = "1 h"'] # fixed overrides of every point (applied first)
    outputs = ["compensation.residual_rms_um.before"]   # summary figures kept (default: all)

    [problem]                           # SALib's problem dict, one to one
    names = ["input.thermal.t_room.amplitude", "fmu.hydraulic.parameters.load_amplitude"]
    bounds = [[0.0, 3.0], [0.0, 50e3]]
    dists = ["unif", "unif"]            # unif logunif triang norm truncnorm lognorm (SALib's meaning)

    [spread]                            # spreads around the base scenario's values -> more [problem] rows
    "fmu.thermal.parameters.g_base_room" = { dist = "lognormal", sigma = 0.3 }

    [grid]                              # design = "grid": every combination of the levels
    "input.thermal.t_room.amplitude" = [0.0, 1.5, 3.0]

Every problem is reported at once, one line each, ``file: key: what`` (:class:`ConfigErrors`).
Keys are checked against the base scenario before anything runs: each design key is set to
its distribution's centre (every level, for a grid) and the scenario and its error-model
configuration are loaded, so an unknown key or a value no point could take is exit-2 material.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from twin.config.load import apply_overrides, load_scenario_data, read_scenario_data
from twin.config.reader import toml_copy, unsafe_name
from twin.config.spec import Scenario
from twin.errors import ConfigError, ConfigErrors

DESIGNS = ("grid", "random", "montecarlo", "lhs", "sobol-sequence", "saltelli", "morris")
#: SALib's distributions and the number of values each takes in ``bounds`` (SALib's order)
DISTS = {"unif": 2, "logunif": 2, "triang": 3, "norm": 2, "truncnorm": 4, "lognorm": 2}
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
}
_TOP_KEYS = {"sweep", "problem", "spread", "grid"}
_PROBLEM_KEYS = {"names", "bounds", "dists", "groups", "num_vars"}
_SPREAD_KEYS = {"dist", "sigma", "relative", "mean", "median", "half_width", "low", "high"}
#: designs whose sample size must be a power of two (a Sobol' sequence is balanced only then)
_POWER_OF_TWO = {"sobol-sequence", "saltelli"}


@dataclass(frozen=True)
class Spec:
    """A checked sweep file."""

    path: Path
    name: str
    base: Path
    design: str
    samples: int
    seed: int
    fixed: tuple[str, ...]
    #: SALib's problem dict (``num_vars``, ``names``, ``bounds``, ``dists``, maybe ``groups``);
    #: for a grid ``names`` and ``num_vars`` only
    problem: Mapping[str, Any]
    levels: tuple[tuple[Any, ...], ...] = ()
    outputs: tuple[str, ...] = ()
    main: str | None = None
    second_order: bool = False
    morris_levels: int = 4
    vary_seed: bool = True
    run_folders: bool = False
    #: the base scenario's data with the fixed overrides applied (read once, copied per point)
    base_data: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def names(self) -> list[str]:
        """The design's keys, in column order."""
        return list(self.problem["names"])


class _Problems:
    """Collects problems of one file, so all of them are reported at once."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.items: list[ConfigError] = []

    def add(self, key: str, message: str) -> None:
        self.items.append(ConfigError(message, source=self.source, key=key))

    def unknown(self, table: Mapping[str, Any], allowed: set[str], prefix: str) -> None:
        for k in table:
            if k not in allowed:
                self.add(f"{prefix}{k}", f"unknown key (expected one of: {', '.join(sorted(allowed))})")

    def check(self) -> None:
        if self.items:
            raise self.items[0] if len(self.items) == 1 else ConfigErrors(self.items)


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _read(path: Path) -> dict[str, Any]:
    from twin.config.reader import read_toml  # the loader's one reader of TOML files

    return read_toml(path, str(path))


def _table(p: _Problems, data: Mapping[str, Any], key: str) -> dict[str, Any]:
    v = data.get(key, {})
    if not isinstance(v, dict):
        p.add(key, f"expected a table, got {type(v).__name__}")
        return {}
    return v


def _string_list(p: _Problems, table: Mapping[str, Any], key: str, where: str) -> tuple[str, ...]:
    v = table.get(key, [])
    if not isinstance(v, list) or not all(isinstance(s, str) for s in v):
        p.add(where, "expected a list of strings")
        return ()
    return tuple(v)


def _int(p: _Problems, table: Mapping[str, Any], key: str, default: int, lo: int, hi: int) -> int:
    v = table.get(key, default)
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        p.add(f"sweep.{key}", f"expected an integer in [{lo}, {hi}], got {v!r}")
        return default
    return v


def _bool(p: _Problems, table: Mapping[str, Any], key: str, default: bool) -> bool:
    v = table.get(key, default)
    if not isinstance(v, bool):
        p.add(f"sweep.{key}", f"expected true or false, got {v!r}")
        return default
    return v


# ----------------------------------------------------------------------------- [problem]


def check_dist(dist: Any, bounds: Any) -> str | None:
    """Why ``bounds`` cannot parametrise SALib's ``dist`` (None when they can)."""
    if dist not in DISTS:
        return f"unknown distribution {dist!r} (expected one of: {', '.join(DISTS)})"
    n = DISTS[dist]
    if not isinstance(bounds, list) or len(bounds) != n or not all(_is_number(b) for b in bounds):
        return f"{dist} takes {n} finite numbers"
    b = [float(x) for x in bounds]
    rules = {
        "unif": (lambda: b[0] < b[1], "lower bound must be below the upper bound"),
        "logunif": (lambda: 0 < b[0] < b[1], "needs 0 < lower < upper"),
        "triang": (
            lambda: b[0] < b[1] and 0 <= b[2] <= 1,
            "needs lower < upper and a peak fraction in [0, 1]",
        ),
        "norm": (lambda: b[1] > 0, "standard deviation must be positive"),
        "lognorm": (lambda: b[1] > 0, "standard deviation (of ln) must be positive"),
        "truncnorm": (
            lambda: b[0] < b[1] and b[3] > 0,
            "needs lower < upper and a positive standard deviation",
        ),
    }
    test, why = rules[dist]
    ok = test()
    return None if ok else f"impossible {dist} {bounds}: {why}"


def centre(dist: str, bounds: list[float]) -> float:
    """A value every distribution of this kind can take: its median (the peak of a triangle)."""
    b = bounds
    return {
        "unif": lambda: b[0] / 2 + b[1] / 2,  # not (b0 + b1) / 2: that overflows near 1.8e308
        "logunif": lambda: math.sqrt(b[0] * b[1]),
        "triang": lambda: b[0] + b[2] * (b[1] - b[0]),
        "norm": lambda: b[0],
        "lognorm": lambda: math.exp(b[0]),
        "truncnorm": lambda: min(max(b[2], b[0]), b[1]),
    }[dist]()


def ends(dist: str, bounds: list[float]) -> list[float]:
    """The lowest and highest value a bounded distribution takes (none for an unbounded one):
    a point there must load too, or the sweep would fail at its points, not before."""
    return [bounds[0], bounds[1]] if dist in ("unif", "logunif", "triang", "truncnorm") else []


def _problem_rows(p: _Problems, raw: Mapping[str, Any]) -> list[tuple[str, str, list[float]]]:
    """(name, dist, bounds) of the ``[problem]`` table, SALib's meaning."""
    p.unknown(raw, _PROBLEM_KEYS, "problem.")
    names = _string_list(p, raw, "names", "problem.names")
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


# ----------------------------------------------------------------------------- [spread]


def _spread_row(
    p: _Problems, key: str, raw: Any, nominal: float | None
) -> tuple[str, str, list[float]] | None:
    """One ``[spread]`` entry as a SALib row: normal, lognormal, uniform or truncnorm around
    the base value (``nominal``), with ``sigma`` absolute or, ``relative = true``, a fraction
    of the base value; a lognormal's ``sigma`` is that of ln (about the relative spread)."""
    where = f'spread."{key}"'
    if not isinstance(raw, dict):
        p.add(where, "expected a table { dist = ..., sigma = ... }")
        return None
    p.unknown(raw, _SPREAD_KEYS, where + ".")
    bad = [k for k in _SPREAD_KEYS - {"dist", "relative"} if k in raw and not _is_number(raw[k])]
    if bad:
        p.add(f"{where}.{bad[0]}", f"expected a finite number, got {raw[bad[0]]!r}")
        return None
    if not isinstance(raw.get("relative", False), bool):
        p.add(f"{where}.relative", "expected true or false")
        return None
    for k in ("sigma", "half_width"):
        if k in raw and raw[k] < 0:
            p.add(f"{where}.{k}", f"negative spread {raw[k]!r}")
            return None
    centre_key = "median" if raw.get("dist") == "lognormal" else "mean"
    base = raw.get(centre_key, nominal)
    if base is None and not {"low", "high"} <= set(raw):
        p.add(where, f"the base scenario has no numeric value here: give '{centre_key}'")
        return None
    scale = abs(base) if raw.get("relative", False) and base is not None else 1.0
    row = _spread_bounds(raw, base, scale)
    if isinstance(row, str):
        p.add(where, row)
        return None
    why = check_dist(row[0], row[1])
    if why:
        p.add(where, why)
        return None
    return key, row[0], row[1]


def _spread_bounds(raw: Mapping[str, Any], base: float | None, scale: float) -> tuple[str, list[float]] | str:
    dist, sigma = raw.get("dist"), raw.get("sigma")
    if dist == "normal":
        return ("norm", [base, sigma * scale]) if sigma is not None else "normal needs 'sigma'"
    if dist == "lognormal":
        if sigma is None or base is None or base <= 0:
            return f"lognormal needs 'sigma' and a positive median, got median {base!r}"
        return "lognorm", [math.log(base), sigma]
    if dist == "uniform":
        if "half_width" in raw and base is not None:
            w = raw["half_width"] * scale
            return "unif", [base - w, base + w]
        return "unif", [raw.get("low", math.nan), raw.get("high", math.nan)]
    if dist == "truncnorm":
        if sigma is None or "low" not in raw or "high" not in raw:
            return "truncnorm needs 'sigma', 'low' and 'high'"
        return "truncnorm", [raw["low"], raw["high"], base, sigma * scale]
    return f"unknown spread {dist!r} (expected normal, lognormal, uniform or truncnorm)"


# ----------------------------------------------------------------------------- base values


def nominal_value(scenario: Scenario, data: Mapping[str, Any], key: str) -> float | None:
    """The value ``key`` has in the base scenario (its file, its parameter files, or the
    FMU's declared start value; not the error model's identified coefficients)."""
    from twin.config.overrides import split_key  # the loader's own key syntax
    from twin.fmu.catalog import variables as model_variables

    parts = split_key(key)
    node: Any = data
    for part in parts:
        node = node.get(part) if isinstance(node, dict) else None
    if isinstance(node, dict):
        node = node.get("value")
    if _is_number(node):
        return float(node)
    if len(parts) == 4 and parts[0] == "fmu" and parts[2] == "parameters":
        try:
            spec = scenario.fmu(parts[1])
        except KeyError:
            return None
        if parts[3] in spec.parameters:
            return float(spec.parameters[parts[3]].value)
        var = model_variables(spec.model).get(parts[3])
        return float(var.start) if var is not None and var.start is not None else None
    return None


# ----------------------------------------------------------------------------- loading


def toml_value(v: Any) -> str:
    """A Python scalar as the TOML text ``--set`` reads back to the same value (JSON's text of
    a number, a boolean or a string is TOML's too; floats keep their shortest exact form)."""
    if not isinstance(v, bool | int | float | str):
        raise TypeError(f"not a TOML scalar: {v!r}")
    return json.dumps(v)


def load_base(spec_path: Path, base: Path, fixed: tuple[str, ...]) -> tuple[dict[str, Any], Scenario]:
    """The base scenario's data with the fixed overrides, and the checked scenario."""
    data = read_scenario_data(base)
    apply_overrides(data, fixed, f"{spec_path}: sweep.set")
    return data, build_scenario(data, base, ())


def build_scenario(data: Mapping[str, Any], base: Path, overrides: tuple[str, ...] | list[str]) -> Scenario:
    """One point's scenario: the base data with ``overrides`` applied, checked (the loader's
    and the error model's checks), named by the base file's name only (no client paths)."""
    from twin.errormodel.config import evaluation_config

    point = toml_copy(dict(data))  # every point changes its own copy
    apply_overrides(point, overrides, f"{base.name}: point")
    scenario = load_scenario_data(point, base.name, base.resolve().parent)
    evaluation_config(scenario)
    return scenario


def _sweep_table(p: _Problems, raw: Mapping[str, Any], path: Path) -> dict[str, Any]:
    sw = _table(p, raw, "sweep")
    p.unknown(sw, _SWEEP_KEYS, "sweep.")
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
    samples = _int(p, sw, "samples", 0 if design == "grid" else 1, 0, 10**7)  # points: MAX_POINTS
    if design != "grid" and samples == 0:
        p.add("sweep.samples", "empty design: at least one sample")
    if design in _POWER_OF_TWO and samples & (samples - 1):
        p.add("sweep.samples", f"{design} needs a power of two (its Sobol' sequence is balanced only then)")
    outputs = _string_list(p, sw, "outputs", "sweep.outputs")
    main = sw.get("main")
    if main is not None and (not isinstance(main, str) or (outputs and main not in outputs)):
        p.add("sweep.main", "expected one of the outputs" if outputs else "expected an output name")
    return {
        "name": name,
        "design": design,
        "samples": samples,
        "seed": _int(p, sw, "seed", 0, 0, 2**32 - 1),
        "fixed": _string_list(p, sw, "set", "sweep.set"),
        "outputs": outputs,
        "main": main,
        "second_order": _bool(p, sw, "second_order", False),
        "morris_levels": _int(p, sw, "levels", 4, 2, 100),
        "vary_seed": _bool(p, sw, "vary_seed", True),
        "run_folders": _bool(p, sw, "run_folders", False),
    }


def _grid(p: _Problems, raw: Mapping[str, Any]) -> tuple[list[str], tuple[tuple[Any, ...], ...]]:
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


def _rows(
    p: _Problems, raw: Mapping[str, Any], scenario: Scenario, data: Mapping[str, Any]
) -> list[tuple[str, str, list[float]]]:
    rows = _problem_rows(p, _table(p, raw, "problem")) if "problem" in raw else []
    for key, entry in _table(p, raw, "spread").items():
        row = _spread_row(p, key, entry, nominal_value(scenario, data, key))
        if row is not None:
            rows.append(row)
    names = [r[0] for r in rows]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        p.add("problem.names", f"{dupes[0]!r} is varied twice")
    if not rows and not p.items:
        p.add("problem", "empty design: no [problem] names and no [spread]")
    return rows


def _groups(p: _Problems, raw: Mapping[str, Any], n: int) -> list[str] | None:
    groups = raw.get("problem", {}).get("groups") if isinstance(raw.get("problem"), dict) else None
    if groups is None:
        return None
    if not isinstance(groups, list) or len(groups) != n or not all(isinstance(g, str) for g in groups):
        p.add("problem.groups", f"expected one group name per varied key ({n})")
        return None
    return groups


def _check_keys(p: _Problems, spec: Spec, values: list[list[Any]]) -> None:
    """Load the base with each design key at the given values: unknown keys, values out of a
    variable's range and keys the error model refuses surface here, named by their key."""
    names = spec.names
    for i, options in enumerate(values):
        for v in options:
            overrides = [f"{n}={toml_value(values[j][0] if j != i else v)}" for j, n in enumerate(names)]
            try:
                build_scenario(spec.base_data, spec.base, overrides)
            except ConfigError as exc:
                for e in getattr(exc, "problems", [exc]):
                    _blame(p, e, names)
                return


def _blame(p: _Problems, e: ConfigError, names: list[str]) -> None:
    key = e.key or ""
    hit = next((n for n in names if key and (n.startswith(key) or key.startswith(n))), None)
    if hit is None:
        p.items.append(e)
    else:
        p.add(hit, e.message or str(e))


#: the most points a sweep may have: its design matrix and its results table are held in
#: memory, and a few lines (eight keys of twenty levels, a Saltelli design of 2^23 samples)
#: otherwise ask for 10^8 to 10^10 points and fill it before the first point runs. A million
#: points of the paper replay are about five hours on a two-core machine.
MAX_POINTS = 1_000_000


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


def load_spec(path: str | Path) -> Spec:
    """Read and check a sweep file; raises :class:`ConfigError` / :class:`ConfigErrors`."""
    path = Path(path)
    return spec_from_data(_read(path), path)


def spec_from_data(raw: Mapping[str, Any], path: Path, base: Path | None = None) -> Spec:
    """Check a sweep file's data read from ``path``; ``base`` replaces its ``sweep.base`` (the
    spreads of one tester as built, resolved around another scenario's values)."""
    p = _Problems(str(path))
    p.unknown(raw, _TOP_KEYS, "")
    sw = _sweep_table(p, raw, path)
    p.check()
    base = base or (path.resolve().parent / raw["sweep"]["base"]).resolve()
    try:
        data, scenario = load_base(path, base, sw["fixed"])
    except ConfigError as exc:
        if exc.source != str(base) or exc.key is not None:
            raise
        # the base itself cannot be read (missing, a directory, a device): say so where it is named
        raise ConfigError(
            f"{raw['sweep']['base']}: {exc.message}", source=str(path), key="sweep.base"
        ) from None
    if sw["design"] == "grid":
        p.unknown(raw, {"sweep", "grid"}, "")
        names, levels = _grid(p, _table(p, raw, "grid"))
        problem: dict[str, Any] = {"num_vars": len(names), "names": names}
        centres: list[list[Any]] = [list(lv) for lv in levels]
    else:
        if "grid" in raw:
            p.add("grid", f"only design = 'grid' takes a [grid] table (this is {sw['design']!r})")
        rows = _rows(p, raw, scenario, data)
        levels = ()
        problem = {
            "num_vars": len(rows),
            "names": [r[0] for r in rows],
            "bounds": [r[2] for r in rows],
            "dists": [r[1] for r in rows],
        }
        groups = _groups(p, raw, len(rows))
        if groups is not None:
            problem["groups"] = groups
        centres = [[centre(r[1], r[2]), *ends(r[1], r[2])] for r in rows]
    p.check()
    points = point_count(sw["design"], sw["samples"], problem, levels, sw["second_order"])
    if points > MAX_POINTS:
        p.add(
            "grid" if sw["design"] == "grid" else "sweep.samples",
            f"{points} points, more than the {MAX_POINTS} a sweep may have: split it, or take fewer "
            + ("levels" if sw["design"] == "grid" else "samples"),
        )
        p.check()
    spec = Spec(path=path, base=base, problem=problem, levels=levels, base_data=data, **sw)
    _check_keys(p, spec, centres)
    p.check()
    return spec
