"""Room curves: the shapes of a rise the paper gives only the size of, and a slow random drift.

The paper gives the room's rise over the experiment (8.9 K in 480 min), not its shape; a run's
Monte Carlo and the thermal calibration try each of :data:`ROOM_SHAPES` (a first-order
approach, a linear ramp, an S-curve) with the same start, rise and rise time. Facts 6 adds a
slow random drift of up to 1 K over a run (:func:`smooth_drift`). Each curve becomes a ``table``
profile sampled every :data:`ROOM_STEP_S` (and at the scenario's own corners), which
:meth:`~twin.config.spec.Scenario.with_input` puts in place of the room's profile.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from twin.config.profiles import profile_function
from twin.config.spec import NS_PER_S, Profile, Scenario
from twin.errors import ConfigError

__all__ = [
    "ROOM_SHAPES",
    "ROOM_STEP_S",
    "Rise",
    "ShapedCurve",
    "SmoothDrift",
    "drifted",
    "rise_of",
    "sample_times",
    "shape",
    "shaped",
    "shaped_curve",
    "smooth_drift",
]

#: the room table's sampling interval, s (a day's sine between samples is off by < 0.001 K)
ROOM_STEP_S = 300.0
#: room shapes of an unknown rise (x = t / rise time, from 0 to 1)
ROOM_SHAPES = ("exponential", "ramp", "s-curve")

Drift = Callable[[np.ndarray], np.ndarray]


#: the points a drift's peak and mean are taken over (x from 0 to 1), and its three
#: half-waves there: the same for every drift, worked out once (a Monte Carlo draws hundreds)
_GRID = np.linspace(0.0, 1.0, 401)
_GRID_WAVES = tuple(np.sin((k + 1) * np.pi * _GRID) for k in range(3))


@dataclass(frozen=True, eq=False)
class SmoothDrift:
    """A slow random drift over a run (:func:`smooth_drift`): ``scale`` times the half-waves
    ``sin(k pi x)`` weighted by ``weights``. Called with x = t / run length."""

    weights: np.ndarray
    scale: float

    def __call__(self, x: np.ndarray) -> np.ndarray:
        x = np.clip(x, 0.0, 1.0)
        return self.scale * sum(w * np.sin((k + 1) * np.pi * x) for k, w in enumerate(self.weights))

    def grid_mean(self) -> float:
        """Its mean over 401 points from x = 0 to 1: ``np.mean(self(np.linspace(0, 1, 401)))``,
        the same double, from the half-waves there worked out once."""
        return float(
            np.mean(self.scale * sum(w * wave for w, wave in zip(self.weights, _GRID_WAVES, strict=True)))
        )


def smooth_drift(rng: np.random.Generator, max_amplitude: float) -> SmoothDrift:
    """A slow random drift over a run, zero at its start and end: three half-waves with
    normal weights (falling as 1/k), scaled so its largest excursion is uniform in
    [0, max_amplitude]. Argument x = t / run length."""
    weights = rng.normal(size=3) / np.arange(1, 4)
    amplitude = float(rng.uniform(0.0, max_amplitude))
    peak = float(np.max(np.abs(sum(w * wave for w, wave in zip(weights, _GRID_WAVES, strict=True)))))
    return SmoothDrift(weights, amplitude / peak if peak > 0 else 0.0)


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


def sample_times(scenario: Scenario, corners: Sequence[float] = ()) -> np.ndarray:
    """Every :data:`ROOM_STEP_S` over the run, and the given corner times within it."""
    end = scenario.duration_ns / NS_PER_S
    grid = np.arange(0.0, end + ROOM_STEP_S / 2, ROOM_STEP_S)
    # the last point is the run's end; a run shorter than half a step keeps its start too (the
    # grid's one point was moved to the end, and a table of one point drives nothing)
    grid = np.append(grid[:-1], end) if len(grid) > 1 else np.array([0.0, end])
    return np.unique(np.concatenate([grid, [c for c in corners if 0.0 <= c <= end]]))


@dataclass(frozen=True)
class Rise:
    """A room's rise (an ``exponential`` profile): where it starts, by how much it rises and
    when it has risen that much; ``tau_ratio`` is its time constant over that time."""

    start: float
    rise: float
    rise_at: float
    tau_ratio: float


def rise_of(profile: Profile, end_s: float) -> Rise | None:
    """The rise an ``exponential`` room profile describes; None for any other profile (a
    day's sine, a lab's table: a curve of its own, not a rise of unknown shape)."""
    if profile.kind != "exponential":
        return None
    f = profile_function(profile)
    rise_at = float(profile.params.get("rise_at", end_s))
    start = float(f(np.array([0.0]))[0])
    rise = float(f(np.array([rise_at]))[0]) - start
    tau_ratio = float(profile.params.get("time_constant", rise_at / 4.0)) / rise_at
    return Rise(start, rise, rise_at, tau_ratio)


def shaped(
    scenario: Scenario, target: str, name: str, drift: Drift | None = None, source: str = ""
) -> Profile:
    """The room ``target``'s rise in the shape ``name`` (same start, rise and rise time as its
    own exponential profile), plus ``drift`` (of x = t / run length) when given."""
    return shaped_curve(scenario, target, name).profile(drift, source)


@dataclass(frozen=True, eq=False)
class ShapedCurve:
    """A room's rise in one shape (:func:`shaped_curve`), sampled at ``times`` (s) over a run
    of ``end`` s, before any drift is added: the same for every sample that draws that shape."""

    target: str
    name: str
    times: np.ndarray
    values: np.ndarray
    end: float

    def profile(self, drift: Drift | None = None, source: str = "") -> Profile:
        """The curve plus ``drift`` (of x = t / run length) when given, as a table profile."""
        values = self.values if drift is None else self.values + drift(self.times / self.end)
        return Profile.of_table(self.target, self.times, values, source or f"room shape {self.name}")


def shaped_curve(scenario: Scenario, target: str, name: str) -> ShapedCurve:
    """The room ``target``'s rise in the shape ``name``, before a drift (:func:`shaped`)."""
    end = scenario.duration_ns / NS_PER_S
    rise = rise_of(scenario.profile(target), end)
    if rise is None:
        raise ConfigError(
            "a room of another shape needs an 'exponential' rise to reshape",
            source=scenario.source_path,
            key=f"input.{target}",
        )
    t = sample_times(scenario, [rise.rise_at])
    values = rise.start + rise.rise * shape(name, t / rise.rise_at, rise.tau_ratio)
    return ShapedCurve(target, name, t, values, end)


def drifted(scenario: Scenario, target: str, drift: Drift, source: str = "") -> Profile:
    """The room ``target``'s own curve plus ``drift`` (of x = t / run length), as a table."""
    profile = scenario.profile(target)
    t = sample_times(scenario, [a for a, _ in profile.table])
    end = scenario.duration_ns / NS_PER_S
    values = profile_function(profile)(t) + drift(t / end)
    return Profile.of_table(
        target, t, values, source or "the scenario's room plus a slow random drift (facts 6)"
    )
