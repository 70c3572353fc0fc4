"""Testers as built and room curves, drawn deterministically from a seed.

The spreads are a sweep file's ``[spread]`` table (:mod:`twin.sweep.spec`), resolved around a
base scenario's values; one file, ``scenarios/validation/testers-as-built.toml``, names every
FMU parameter a tester as built varies, so no parameter name lives in the code.

Tester ``i`` is drawn from ``SeedSequence(seed, spawn_key=(2, i))`` alone: the same tester
whatever the number of testers, workers or the order they finish in. Its values map through
SALib's :func:`~SALib.util.scale_samples`, so a spread means what it means to ``twin sweep``.

Room curves (facts.md section 6: the room's shape is unknown, plus a slow drift of up to 1 K
over a run) are written as a ``table`` profile: the room of a scenario sampled every
:data:`ROOM_STEP_S` (and at its own table's corners), plus the drift.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from twin.config.spec import NS_PER_S, Scenario
from twin.errors import ConfigError
from twin.seeds import Key, generator
from twin.sweep.spec import Spec, spec_from_data, toml_value

#: the room table's sampling interval, s (a day's sine between samples is off by < 0.001 K)
ROOM_STEP_S = 300.0
#: room shapes of an unknown rise (x = t / rise time, from 0 to 1)
ROOM_SHAPES = ("exponential", "ramp", "s-curve")


def instance_of(key: str) -> str | None:
    """The FMU instance an ``fmu.<instance>.parameters.<name>`` key sets (None otherwise)."""
    parts = key.split(".")
    return parts[1] if len(parts) >= 2 and parts[0] == "fmu" else None


def load_testers(path: Path, base: Path | None = None, instances: Sequence[str] | None = None) -> Spec:
    """The spreads file as a checked sweep spec, around ``base`` (default: its own base).

    With ``instances``, spreads of FMU instances the base does not have are left out (the
    paper replay has no loader and no drive).
    """
    from twin.sweep.spec import _read

    raw = copy.deepcopy(_read(path))
    if instances is not None and isinstance(raw.get("spread"), dict):
        raw["spread"] = {
            k: v for k, v in raw["spread"].items() if instance_of(k) is None or instance_of(k) in instances
        }
    return spec_from_data(raw, path, base)


@dataclass(frozen=True)
class Testers:
    """Draws testers as built from a spreads spec."""

    spec: Spec
    seed: int

    @property
    def names(self) -> list[str]:
        """The varied keys, in the file's order."""
        return self.spec.names

    def draw(self, index: int) -> dict[str, float]:
        """Tester ``index``'s values by key."""
        from SALib.util import scale_samples

        problem = {k: list(v) if isinstance(v, list) else v for k, v in self.spec.problem.items()}
        rng = generator(self.seed, Key.TESTER, index)
        unit = rng.random((1, len(self.names)))
        row = scale_samples(unit, problem)[0]
        return {n: float(v) for n, v in zip(self.names, row, strict=True)}


def overrides_for(values: Mapping[str, float], data: Mapping[str, Any]) -> list[str]:
    """The ``--set`` strings of ``values`` that apply to a scenario's data: an FMU parameter
    only where the scenario has that instance."""
    fmus = data.get("fmu", {})
    return [f"{k}={toml_value(v)}" for k, v in values.items() if instance_of(k) in (None, *fmus)]


# ----------------------------------------------------------------------------- room curves


def smooth_drift(rng: np.random.Generator, max_amplitude: float) -> Callable[[np.ndarray], np.ndarray]:
    """A slow random drift over a run, zero at its start and end: three half-waves with
    normal weights (falling as 1/k), scaled so its largest excursion is uniform in
    [0, max_amplitude]. Argument x = t / run length."""
    weights = rng.normal(size=3) / np.arange(1, 4)
    amplitude = float(rng.uniform(0.0, max_amplitude))
    grid = np.linspace(0.0, 1.0, 401)
    peak = float(np.max(np.abs(sum(w * np.sin((k + 1) * np.pi * grid) for k, w in enumerate(weights)))))
    scale = amplitude / peak if peak > 0 else 0.0

    def drift(x: np.ndarray) -> np.ndarray:
        x = np.clip(x, 0.0, 1.0)
        return scale * sum(w * np.sin((k + 1) * np.pi * x) for k, w in enumerate(weights))

    return drift


def shape(name: str, x: np.ndarray, tau_ratio: float) -> np.ndarray:
    """A room rise's shape from 0 at x = 0 to 1 at x = 1: a first-order approach with time
    constant ``tau_ratio`` (of the rise time), a linear ramp, or a smooth S-curve
    (3x^2 - 2x^3: slow start, fastest at mid-run, levelling off)."""
    x = np.clip(x, 0.0, None)
    if name == "exponential":
        return -np.expm1(-x / tau_ratio) / -math.expm1(-1.0 / tau_ratio)
    if name == "ramp":
        return np.minimum(x, 1.0)
    if name == "s-curve":
        y = np.minimum(x, 1.0)
        return 3 * y**2 - 2 * y**3
    raise ConfigError(f"unknown room shape {name!r} (expected one of: {', '.join(ROOM_SHAPES)})")


def room_profile(scenario: Scenario, target: str) -> Any:
    """The scenario's profile driving ``target`` (``instance.variable``)."""
    for p in scenario.profiles:
        if p.target == target:
            return p
    raise ConfigError(f"no profile drives {target}", source=scenario.source_path, key="input")


def sample_times(scenario: Scenario, corners: Sequence[float] = ()) -> np.ndarray:
    """Every :data:`ROOM_STEP_S` over the run, and the given corner times within it."""
    end = scenario.duration_ns / NS_PER_S
    grid = np.arange(0.0, end + ROOM_STEP_S / 2, ROOM_STEP_S)
    grid[-1] = end
    return np.unique(np.concatenate([grid, [c for c in corners if 0.0 <= c <= end]]))


def set_room(data: dict[str, Any], key: str, t: np.ndarray, values: np.ndarray, source: str) -> None:
    """Replace the room input ``key`` (``input.<instance>.<variable>``) of the scenario's data
    by a table of ``values`` at ``t`` (s)."""
    parts = key.split(".")
    if len(parts) != 3 or parts[0] != "input":
        raise ConfigError("expected input.<instance>.<variable>", source=source, key=key)
    points = [[f"{ti!r} s", float(v)] for ti, v in zip(t.tolist(), values.tolist(), strict=True)]
    data.setdefault("input", {}).setdefault(parts[1], {})[parts[2]] = {
        "profile": "table",
        "points": points,
        "source": source,
    }


def with_room_drift(
    data: dict[str, Any], scenario: Scenario, key: str, drift: Callable[[np.ndarray], np.ndarray]
) -> None:
    """The scenario's own room curve plus ``drift`` (of x = t / run length), as a table."""
    from twin.config.profiles import profile_function

    profile = room_profile(scenario, key.split(".", 1)[1])
    t = sample_times(scenario, [a for a, _ in profile.table])
    end = scenario.duration_ns / NS_PER_S
    values = profile_function(profile)(t) + drift(t / end)
    set_room(data, key, t, values, "twin heldout: the scenario's room plus a slow random drift (facts 6)")
