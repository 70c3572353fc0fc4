"""Spreads of a scenario's values as SALib's rows (name, distribution, bounds).

A ``[spread]`` entry names a value a study varies (a key of
:meth:`twin.config.spec.Scenario.with_value`) and its spread around the scenario's own value::

    "fmu.thermal.parameters.g_base_room" = { dist = "lognormal", sigma = 0.3 }
    "fmu.mechanics.parameters.alpha_long_pole" = { dist = "normal", sigma = 0.04, relative = true }
    "fmu.sensors.parameters.probe_zero_drift" = { dist = "normal", mean = 0.0, sigma = 0.5e-6 }
    "fmu.mechanics.parameters.abbe_offset" = { dist = "uniform", half_width = 0.005 }

normal, lognormal, uniform or truncnorm around the base value, with ``sigma`` absolute or,
``relative = true``, a fraction of the base value; a lognormal's ``sigma`` is that of ln (about
the relative spread). Each becomes a row in SALib's own terms (``norm``, ``lognorm``, ``unif``,
``truncnorm`` with SALib's bounds), so a spread means what it means to SALib's samplers. An
entry may also name its input ``group`` and its ``source`` (words the draw does not read: the
prior file's, scenarios/base/priors.toml).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from twin.config.reader import Problems, finite_number
from twin.config.spec import Scenario
from twin.errors import ConfigError

__all__ = [
    "DISTS",
    "Row",
    "calibrated_rows",
    "centre",
    "check_dist",
    "ends",
    "merge_rows",
    "spread_rows",
]

#: SALib's distributions and the number of values each takes in ``bounds`` (SALib's order)
DISTS = {"unif": 2, "logunif": 2, "triang": 3, "norm": 2, "truncnorm": 4, "lognorm": 2}
_SPREAD_KEYS = {"dist", "sigma", "relative", "mean", "median", "half_width", "low", "high", "group", "source"}
#: an entry's words, not numbers: the input group it belongs to and where its spread comes from
_WORDS = {"dist", "relative", "group", "source"}

#: one SALib row: (name, distribution, bounds)
Row = tuple[str, str, list[float]]


def check_dist(dist: Any, bounds: Any) -> str | None:
    """Why ``bounds`` cannot parametrise SALib's ``dist`` (None when they can)."""
    if dist not in DISTS:
        return f"unknown distribution {dist!r} (expected one of: {', '.join(DISTS)})"
    n = DISTS[dist]
    if not isinstance(bounds, list) or len(bounds) != n or not all(finite_number(b) for b in bounds):
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
    return None if test() else f"impossible {dist} {bounds}: {why}"


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
    a point there must be a valid scenario too, or a study would fail at its points."""
    return [bounds[0], bounds[1]] if dist in ("unif", "logunif", "triang", "truncnorm") else []


def _row(p: Problems, key: str, raw: Any, nominal: float | None) -> Row | None:
    """One ``[spread]`` entry as a SALib row (see the module)."""
    where = f'spread."{key}"'
    if not isinstance(raw, dict):
        p.add(where, "expected a table { dist = ..., sigma = ... }")
        return None
    p.unknown_keys(raw, _SPREAD_KEYS, where + ".")
    bad = [k for k in sorted(_SPREAD_KEYS - _WORDS) if k in raw and not finite_number(raw[k])]
    if bad:
        p.add(f"{where}.{bad[0]}", f"expected a finite number, got {raw[bad[0]]!r}")
        return None
    words = [k for k in ("group", "source") if k in raw and not isinstance(raw[k], str)]
    if words:
        p.add(f"{where}.{words[0]}", f"expected a string, got {raw[words[0]]!r}")
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
    row = _bounds(raw, base, scale)
    if isinstance(row, str):
        p.add(where, row)
        return None
    why = check_dist(row[0], row[1])
    if why:
        p.add(where, why)
        return None
    return key, row[0], row[1]


def _bounds(raw: Mapping[str, Any], base: float | None, scale: float) -> tuple[str, list[float]] | str:
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


def spread_rows(p: Problems, spread: Mapping[str, Any], scenario: Scenario) -> list[Row]:
    """The rows of a ``[spread]`` table around ``scenario``'s values (problems go to ``p``)."""
    rows = []
    for key, entry in spread.items():
        nominal = scenario.nominal(str(key))
        if nominal is None and (missing := _names_nothing(scenario, str(key))):
            p.add(f'spread."{key}"', missing)  # not "give 'mean'": there is nothing to vary
            continue
        row = _row(p, str(key), entry, nominal)
        if row is not None:
            rows.append(row)
    return rows


def _names_nothing(scenario: Scenario, key: str) -> str | None:
    """Why ``key`` names nothing the scenario could vary (an unknown instance, parameter or
    profile parameter), or None when it names something."""
    try:
        scenario.with_value(key, 1.0)
    except ConfigError as exc:
        return exc.message
    return None


def calibrated_rows(scenario: Scenario) -> list[Row]:
    """A lognormal row (ln of the value, the relative standard error) for every parameter the
    scenario's parameter files give a standard error (a calibrated value: ``std_error``)."""
    rows = []
    for spec in scenario.fmus:
        for name, param in spec.parameters.items():
            value = param.value
            if (
                param.std_error
                and isinstance(value, int | float)
                and not isinstance(value, bool)
                and value > 0
            ):
                rows.append(
                    (
                        f"fmu.{spec.name}.parameters.{name}",
                        "lognorm",
                        [math.log(value), param.std_error / value],
                    )
                )
    return rows


def merge_rows(rows: list[Row], replacing: list[Row]) -> list[Row]:
    """``rows`` with each of ``replacing`` in place of the row of the same name (added where
    there is none)."""
    by_name = {r[0]: r for r in replacing}
    out = [by_name.pop(r[0], r) for r in rows]
    return out + [r for r in replacing if r[0] in by_name]


def problem(rows: list[Row], groups: list[str] | None = None) -> dict[str, Any]:
    """SALib's problem dict of ``rows``."""
    out: dict[str, Any] = {
        "num_vars": len(rows),
        "names": [r[0] for r in rows],
        "bounds": [r[2] for r in rows],
        "dists": [r[1] for r in rows],
    }
    if groups is not None:
        out["groups"] = groups
    return out
