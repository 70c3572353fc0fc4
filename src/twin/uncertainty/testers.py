"""Testers as built: drawn from a spreads file, one tester per index, and a scenario changed
to one of them.

The spreads file (``scenarios/validation/testers-as-built.toml``) is the one file that names
the FMU parameters a tester as built varies (a sweep file: ``[sweep] base`` and ``[spread]``).
Its spreads are resolved around a base scenario's values (:mod:`twin.uncertainty.spreads`);
tester ``i`` is drawn from :func:`twin.seeds.generator` with key ``(TESTER, i)`` alone: the
same tester whatever the number of testers, workers or the order they finish in. Its values
map through SALib's :func:`~SALib.util.scale_samples`, so a spread means what it means to
``twin sweep``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from twin.config.load import load_scenario
from twin.config.reader import Problems, read_toml
from twin.config.spec import Scenario
from twin.errors import ConfigError
from twin.seeds import Key, generator
from twin.uncertainty.spreads import Row, problem, spread_rows

__all__ = ["Testers", "apply", "instance_of", "load_testers"]


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
        from SALib.util import scale_samples

        rng = generator(self.seed, Key.TESTER, index)
        unit = rng.random((1, len(self.rows)))
        row = scale_samples(unit, problem(list(self.rows)))[0]
        return {n: float(v) for n, v in zip(self.names, row, strict=True)}


def load_testers(path: Path, scenario: Scenario | None = None) -> list[Row]:
    """The spreads file's rows around ``scenario``'s values (default: the file's own base
    scenario); spreads of FMU instances the scenario does not have are left out (the paper
    replay has no loader and no drive). Every problem at once, one line each."""
    raw = read_toml(path, str(path))
    p = Problems(str(path))
    p.unknown_keys(raw, {"sweep", "spread", "problem"}, "")
    spread = p.table(raw, "spread")
    if scenario is None:
        base = p.table(raw, "sweep").get("base")
        if not isinstance(base, str):
            p.add("sweep.base", "expected the base scenario's file name (relative to this file)")
            p.check()
        scenario = _base(path, str(base))
    instances = {f.name for f in scenario.fmus}
    spread = {k: v for k, v in spread.items() if instance_of(str(k)) in (None, *instances)}
    rows = spread_rows(p, spread, scenario)
    if not rows and not p.items:
        p.add("spread", "no spread: nothing to draw")
    p.check()
    return rows


def _base(path: Path, base: str) -> Scenario:
    base_path = (path.resolve().parent / base).resolve()
    try:
        return load_scenario(base_path)
    except ConfigError as exc:
        if exc.source != str(base_path) or exc.key is not None:
            raise
        raise ConfigError(f"{base}: {exc.message}", source=str(path), key="sweep.base") from None


def apply(scenario: Scenario, values: Mapping[str, Any]) -> Scenario:
    """``scenario`` as the tester of ``values`` (keys of
    :meth:`~twin.config.spec.Scenario.with_value`): each value whose instance the scenario has."""
    instances = {f.name for f in scenario.fmus}
    for key, value in values.items():
        if instance_of(key) in (None, *instances):
            scenario = scenario.with_value(key, value)
    return scenario
