"""Testers as built: drawn from the prior file, one tester per index, and a scenario changed
to one of them.

The prior file (``scenarios/base/priors.toml``) is the one file that names what is not known of
the tester as built: its ``[spread]`` tables (each with its ``group`` and ``source``), the room's
curve (``[room]``: shapes and slow drift) and the shares that are the rest of others (``[rest]``).
A spreads file in a sweep file's format (``[sweep] base`` and ``[spread]``) is read too.
Its spreads are resolved around a base scenario's values (:mod:`twin.uncertainty.spreads`);
tester ``i`` is drawn from :func:`twin.seeds.generator` with key ``(TESTER, i)`` alone: the
same tester whatever the number of testers, workers or the order they finish in. Its values
map through the inverse CDFs of SALib's :func:`~SALib.util.scale_samples` (:func:`scale`: the
same numbers, within 1e-14 relative), so a spread means what it means to
``twin sweep``.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from statistics import NormalDist
from typing import Any

import numpy as np

from twin.config.load import load_scenario
from twin.config.reader import Problems, read_toml
from twin.config.spec import Scenario
from twin.errors import ConfigError
from twin.seeds import Key, generator
from twin.uncertainty.spreads import Row, problem, spread_rows

__all__ = [
    "Prior",
    "Room",
    "Testers",
    "apply",
    "instance_of",
    "key_parts",
    "load_prior",
    "load_room",
    "load_testers",
    "normal_quantile",
    "scale",
    "with_rests",
]

_TOP = {"priors", "room", "rest", "spread", "sweep", "problem"}
#: the room of a file that does not say (the paper replay's shapes, a drift of up to 1 K)
_ROOM = {"shapes": ["exponential", "ramp", "s-curve"], "drift_K": 1.0}


def instance_of(key: str) -> str | None:
    """The FMU instance an ``fmu.<instance>.parameters.<name>`` key sets (None otherwise)."""
    parts = key.split(".")
    return parts[1] if len(parts) >= 2 and parts[0] == "fmu" else None


@dataclass(frozen=True)
class Testers:
    """Draws testers as built from spreads (SALib rows)."""

    rows: tuple[Row, ...]
    seed: int

    @property
    def names(self) -> list[str]:
        """The varied keys, in the file's order."""
        return [r[0] for r in self.rows]

    def draw(self, index: int) -> dict[str, float]:
        """Tester ``index``'s values by key."""
        return self.draw_many([index])[0]

    def draw_many(self, indices: Sequence[int]) -> list[dict[str, float]]:
        """Testers ``indices``' values by key, each from its own stream as :meth:`draw` (the
        same numbers): scaled in one call, as a column's inverse CDF per tester was most of a
        Monte Carlo sample's making."""
        if not len(indices):
            return []
        unit = np.vstack([generator(self.seed, Key.TESTER, i).random((1, len(self.rows))) for i in indices])
        rows = scale(unit, self.rows)
        names = self.names
        return [{n: float(v) for n, v in zip(names, row, strict=True)} for row in rows]


#: the distributions :func:`scale` maps itself, as SALib does (every one of the prior file's)
_OWN = {"norm", "lognorm", "unif"}


def scale(unit: np.ndarray, rows: Sequence[Row]) -> np.ndarray:
    """The unit draws ``unit`` (one column per row) mapped through each row's inverse CDF: SALib's
    :func:`~SALib.util.scale_samples` maps, each value within 1e-14 of SALib's, relative
    (tests/uncertainty/test_scale.py).

    SALib's module imports pandas and all of scipy.stats (about half a second and a hundred MB,
    a third of a default run's) for three one-line maps: a normal's quantile is
    ``ndtri(q) * sigma + mean`` in scipy.stats, a lognormal's its exponential, a uniform's
    ``q * (high - low) + low``. Those three are computed here with the same arithmetic, the
    standard normal's quantile by the standard library's (:func:`normal_quantile`): scipy's
    ``ndtri`` alone cost a default run a fifth of a CPU second to import (scipy.special loads
    its own BLAS and starts its thread). A uniform's values are SALib's to the last bit. A row
    of any other distribution (triangular, log-uniform, truncated normal: no prior file uses
    them yet) sends the whole draw to SALib."""
    if any(r[1] not in _OWN for r in rows):
        from SALib.util import scale_samples

        return np.asarray(scale_samples(unit, problem(list(rows))))
    out = np.empty_like(unit)
    for i, (_, dist, bounds) in enumerate(rows):
        b1, b2 = bounds[0], bounds[1]
        if dist == "unif":
            out[:, i] = unit[:, i] * (b2 - b1) + b1
        elif dist == "norm":
            out[:, i] = normal_quantile(unit[:, i]) * b2 + b1
        else:
            out[:, i] = np.exp(normal_quantile(unit[:, i]) * b2 + b1)
    return out


def normal_quantile(q: np.ndarray) -> np.ndarray:
    """The standard normal's quantile of each ``q``, as scipy's ``ndtri`` gives it (within a few
    units in the last place: Wichura's AS 241, :meth:`statistics.NormalDist.inv_cdf`): minus
    infinity at 0 and below, infinity at 1 and above, NaN for NaN (a unit draw is in [0, 1))."""
    inv_cdf = NormalDist().inv_cdf

    def one(p: float) -> float:
        if math.isnan(p):
            return p
        if p <= 0.0:
            return -math.inf
        return math.inf if p >= 1.0 else inv_cdf(p)

    return np.array([one(p) for p in q.tolist()], dtype=float)


@dataclass(frozen=True)
class Room:
    """The room curve's prior: the shapes a rise of unknown shape takes, the slow drift's
    largest excursion (K)."""

    shapes: tuple[str, ...]
    drift_K: float


@dataclass(frozen=True)
class Prior:
    """A prior file read around a scenario: SALib rows, each row's input group, the room, and
    the shares kept as the rest of others (key -> the prefix of the keys it is the rest of)."""

    rows: tuple[Row, ...]
    groups: Mapping[str, str]
    room: Room
    rests: Mapping[str, str]


def load_prior(path: Path, scenario: Scenario | None = None) -> Prior:
    """The prior file's rows around ``scenario``'s values (default: the file's own base
    scenario, ``[priors] base`` or a sweep file's ``[sweep] base``); spreads of FMU instances the
    scenario does not have are left out (the paper replay has no loader and no drive). Every
    problem at once, one line each."""
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, _TOP, "")
    spread = p.table(raw, "spread")
    room = _room(p, p.table(raw, "room") if "room" in raw else {})
    rests = _rests(p, p.table(raw, "rest") if "rest" in raw else {})
    if scenario is None:
        where = "priors" if "priors" in raw else "sweep"
        base = p.table(raw, where).get("base")
        if not isinstance(base, str):
            p.add(f"{where}.base", "expected the base scenario's file name (relative to this file)")
            p.check()
        scenario = _base(path, str(base), where)
    instances = {f.name for f in scenario.fmus}
    spread = {k: v for k, v in spread.items() if instance_of(str(k)) in (None, *instances)}
    rows = spread_rows(p, spread, scenario)
    if not rows and not p.items:
        p.add("spread", "no spread: nothing to draw")
    p.check()
    groups = {str(k): str(v.get("group", "other")) for k, v in spread.items() if isinstance(v, dict)}
    return Prior(tuple(rows), groups, room, rests)


def load_room(path: Path) -> Room:
    """The prior file's room curve (``[room]``; the paper replay's shapes and a 1 K drift when
    the file has none)."""
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    room = _room(p, p.table(raw, "room") if "room" in raw else {})
    p.check()
    return room


def load_testers(path: Path, scenario: Scenario | None = None) -> list[Row]:
    """The prior file's SALib rows (:func:`load_prior`)."""
    return list(load_prior(path, scenario).rows)


def _room(p: Problems, table: Mapping[str, Any]) -> Room:
    from twin.uncertainty.rooms import ROOM_SHAPES

    p.unknown_keys(table, {"shapes", "drift_K", "source"}, "room.")
    shapes = table.get("shapes", _ROOM["shapes"])
    if not isinstance(shapes, list) or not shapes or not set(shapes) <= set(ROOM_SHAPES):
        p.add("room.shapes", f"expected a list from {list(ROOM_SHAPES)}")
        shapes = list(ROOM_SHAPES)
    drift = p.number(_ROOM | dict(table), "drift_K", "room.", lo=0.0)
    return Room(tuple(shapes), float(drift or 0.0))


def _rests(p: Problems, table: Mapping[str, Any]) -> dict[str, str]:
    out = {}
    for key, entry in table.items():
        if not isinstance(entry, dict) or not isinstance(entry.get("of"), str):
            p.add(f'rest."{key}"', "expected a table { of = the prefix of the keys it is the rest of }")
            continue
        p.unknown_keys(entry, {"of", "source"}, f'rest."{key}".')
        out[str(key)] = entry["of"]
    return out


def with_rests(scenario: Scenario, values: Mapping[str, float], rests: Mapping[str, str]) -> dict[str, float]:
    """``values`` with each rest (a share kept as 1 minus the others of its prefix, drawn or the
    scenario's), where a value of its prefix was drawn: drawn shares still sum to 1."""
    out = dict(values)
    for key, prefix in rests.items():
        instance = instance_of(key)
        if not any(k.startswith(prefix) and k != key for k in values) or instance not in {
            f.name for f in scenario.fmus
        }:
            continue
        spec = scenario.fmu(instance)
        others = [
            values.get(f"fmu.{instance}.parameters.{name}", param.value)
            for name, param in spec.parameters.items()
            if f"fmu.{instance}.parameters.{name}".startswith(prefix)
            and f"fmu.{instance}.parameters.{name}" != key
        ]
        out[key] = 1.0 - float(sum(others))
    return out


def _base(path: Path, base: str, where: str = "sweep") -> Scenario:
    base_path = (path.resolve().parent / base).resolve()
    try:
        return load_scenario(base_path)
    except ConfigError as exc:
        if exc.source != str(base_path) or exc.key is not None:
            raise
        raise ConfigError(f"{base}: {exc.message}", source=str(path), key=f"{where}.base") from None


@functools.lru_cache(maxsize=4096)
def key_parts(key: str) -> tuple[str | None, str | None]:
    """The instance a key sets (:func:`instance_of`) and, for an ``fmu.<instance>.parameters.
    <name>`` key, the parameter's name (else None): a Monte Carlo's samples set the same keys,
    each split once."""
    parts = key.split(".")
    parameter = parts[3] if len(parts) == 4 and parts[0] == "fmu" and parts[2] == "parameters" else None
    return instance_of(key), parameter


def apply(scenario: Scenario, values: Mapping[str, Any]) -> Scenario:
    """``scenario`` as the tester of ``values`` (keys of
    :meth:`~twin.config.spec.Scenario.with_value`): each value whose instance the scenario has."""
    instances = {f.name for f in scenario.fmus}
    # an instance's parameters set in one copy: a tester draws about ninety, and a copy of the
    # scenario per value was most of a Monte Carlo sample's making
    grouped: dict[str, dict[str, Any]] = {}
    for key, value in values.items():
        instance, parameter = key_parts(key)
        if instance in instances and parameter is not None:
            grouped.setdefault(instance, {})[parameter] = value
        elif instance in (None, *instances):
            scenario = scenario.with_value(key, value)
    for instance, params in grouped.items():
        scenario = scenario.with_parameters(instance, params)
    return scenario
